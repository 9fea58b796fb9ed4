"""The LTL-DS executive in closed loop on a small synthetic world (paper eq. 6, Fig. 7).

The world: a 2-D chain of regions read by two sensors, ``u`` (in the strip ``0 <= x0 < 4``
above ``x1 = -2``) and ``v`` (``x0 >= 4``); mode ``a`` (neither) -> ``b`` (u) -> ``c`` (v,
the goal). Mode b's DS is a stable spiral whose attractor lies in c; from some entries it
leaves b through the bottom into a (an invariance failure the spec allows, b -> a), a's DS
brings it back, and without cuts it loops a -> b -> a ... (paper Fig. 7, top row).
"""

from __future__ import annotations

import json
import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.instances import CHAIN_SPEC
from tli_verify.certification.certificate import (
    check_certificate,
    issue_certificate,
    write_certificate,
)
from tli_verify.commands import exit_code
from tli_verify.errors import CertificateError
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import parse_spec
from tli_verify.model.serialize import load_model, model_from_dict, save_model
from tli_verify.model.types import Model
from tli_verify.runtime.events import (
    AssumptionViolationEvent,
    CutAdded,
    InvarianceFailure,
    ModeChange,
    Replan,
    event_to_json,
)
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.loop import run_episode
from tli_verify.runtime.persist import save_certified

SPEC = CHAIN_SPEC

I2 = [[1.0, 0.0], [0.0, 1.0]]


def _ds(mode: str, nxt: str | None, att: list[float], A: list[list[float]]) -> dict[str, Any]:
    return {"mode": mode, "next_mode": nxt, "attractor": att, "P": I2,
            "components": [{"prior": 1.0, "mean": att, "cov": I2, "A": A}], "cuts": []}


class Chain:
    """The sensor model of the chain world."""

    def reset(self, x0: np.ndarray) -> None:
        pass

    def read(self, x: np.ndarray) -> Mapping[str, bool]:
        return {"u": bool(0.0 <= x[0] < 4.0 and x[1] >= -2.0), "v": bool(x[0] >= 4.0)}


SPIRAL = [[-1.0, -1.0], [1.0, -1.0]]


def _project(root: Path, a_attractor: list[float]) -> tuple[TaskAutomaton, Model, Path]:
    """Spec, hand-built model (stable A_k, P = I), certificate at dt = 1/100."""
    for d in ("specs", "models", "certificates"):
        (root / d).mkdir(parents=True, exist_ok=True)
    (root / "specs" / "chain.toml").write_text(SPEC)
    doc = {"schema_version": 1, "state_names": ["x0", "x1"], "spec": "../specs/chain.toml",
           "modes": {"a": _ds("a", "b", a_attractor, [[-1.0, 0.0], [0.0, -1.0]]),
                     "b": _ds("b", "c", [6.0, 0.0], SPIRAL),
                     "c": _ds("c", None, [6.0, 0.0], [[-1.0, 0.0], [0.0, -1.0]])}}
    mpath = root / "models" / "chain.model.json"
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = root / "certificates" / "chain.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    return synthesize(parse_spec(SPEC)), load_model(mpath), cpath


@pytest.fixture
def looping(tmp_path: Path) -> tuple[TaskAutomaton, Model, Path]:
    """A world where mode b's DS leaves b once from the start used below."""
    return _project(tmp_path, [0.5, -1.8])


@pytest.fixture
def nominal(tmp_path: Path) -> tuple[TaskAutomaton, Model, Path]:
    """A world whose DS never leave their modes from the start used below."""
    return _project(tmp_path, [1.0, 3.0])


def _changes(res: Any) -> str:
    return "".join(m for i, m in enumerate(res.modes) if i == 0 or m != res.modes[i - 1])


def test_reaches_the_goal_mode(nominal: tuple[TaskAutomaton, Model, Path]) -> None:
    aut, model, cert = nominal
    pol = LTLDSPolicy(aut, model, cert)
    res = run_episode(pol, Chain(), [-3.0, 4.0], steps=3000, speed_cap=20.0)
    assert res.success and pol.mode == "c"
    assert _changes(res) == "abc"
    assert [e.to_mode for e in res.events if isinstance(e, ModeChange)] == ["b", "c"]
    assert all(e.expected for e in res.events if isinstance(e, ModeChange))
    assert res.cuts_added == 0
    assert res.states.shape == (res.steps + 1, 2) and len(res.modes) == res.steps + 1
    json.dumps([event_to_json(e) for e in res.events])


def test_perturbation_replans_and_still_succeeds(nominal: tuple[TaskAutomaton, Model, Path]
                                                 ) -> None:
    aut, model, cert = nominal
    pushed: list[int] = []

    def push(t: int, x: np.ndarray) -> np.ndarray | None:
        if not pushed and x[0] > 1.5:  # in b: knock it back into a
            pushed.append(t)
            return np.array([-2.0, -1.0])
        return None

    pol = LTLDSPolicy(aut, model, cert)
    res = run_episode(pol, Chain(), [-3.0, 4.0], steps=3000, speed_cap=20.0, perturb=push)
    assert pushed, "the perturbation never fired"
    replans = [e for e in res.events if isinstance(e, Replan)]
    assert [(r.from_mode, r.to_mode, r.cause) for r in replans] == [("b", "a", "perturbation")]
    assert replans[0].planned == "c" and replans[0].new_plan == "b"
    assert not any(isinstance(e, InvarianceFailure) for e in res.events)
    assert res.cuts_added == 0
    assert res.success and _changes(res) == "ababc"


def test_unprovoked_exit_gives_one_cut_and_is_not_repeated(
        looping: tuple[TaskAutomaton, Model, Path]) -> None:
    aut, model, cert = looping
    # without cuts the same exit repeats until the budget runs out (paper Fig. 7, top)
    bare = LTLDSPolicy(aut, model, cert, learn_cuts=False)
    res0 = run_episode(bare, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    fails0 = [e for e in res0.events if isinstance(e, InvarianceFailure)]
    assert not res0.success and len(fails0) > 10
    # LTL-DS: one failure, one cut applied at once, then the goal (Fig. 7, bottom)
    pol = LTLDSPolicy(aut, model, cert)
    res = run_episode(pol, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    fails = [e for e in res.events if isinstance(e, InvarianceFailure)]
    cuts = [e for e in res.events if isinstance(e, CutAdded)]
    assert res.success
    assert len(fails) == 1 and len(cuts) == 1 and res.cuts_added == 1
    f, c = fails[0], cuts[0]
    assert (f.mode, f.to_mode, f.key) == ("b", "a", "b")
    assert c.mode == "b" and c.keys == ("b",) and c.step == f.step
    # the recorded states: entry and last state read in b, failure state read in a
    reader = Chain()
    assert reader.read(f.entry)["u"] and reader.read(f.last_inside)["u"]
    assert not reader.read(f.outside)["u"]
    # the cut separates the failure state from the last in-mode state and x*
    w, p = c.cut.normal, c.cut.point
    assert np.allclose(p, f.last_inside)
    assert w @ (f.outside - p) > 0 and w @ (np.array([6.0, 0.0]) - p) < 0
    assert len(pol.model.modes["b"].cuts) == 1 and len(model.modes["b"].cuts) == 0
    # the cut is kept: a second episode from the same start has no failure at all
    res2 = run_episode(pol, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    assert res2.success and not any(isinstance(e, InvarianceFailure) for e in res2.events)
    assert _changes(res2) == "abc"


def test_impossible_reading_is_reported_and_resynchronized(
        nominal: tuple[TaskAutomaton, Model, Path]) -> None:
    aut, model, cert = nominal
    pol = LTLDSPolicy(aut, model, cert)
    x = np.array([-3.0, 4.0])
    pol.reset(x, {"u": False, "v": False})
    assert pol.mode == "a"
    # a -> c: the assumptions rule it out (not physically possible); a state entered with
    # this reading exists, so the executive follows it
    v = pol.step(x, {"u": False, "v": True})
    ev = [e for e in pol.events if isinstance(e, AssumptionViolationEvent)]
    assert len(ev) == 1 and ev[0].reading == ("v",) and ev[0].resynced is not None
    assert pol.mode == "c" and aut.states[ev[0].resynced].mode == "c"
    replans = [e for e in pol.events if isinstance(e, Replan)]
    assert [(r.from_mode, r.to_mode, r.cause) for r in replans] == [
        ("a", "c", "assumption violation")]
    assert not any(isinstance(e, InvarianceFailure | CutAdded) for e in pol.events)
    assert np.allclose(v, model.velocity(x, "c", dt=pol.dt))
    # no automaton state has both sensors on: report it, hold still, never crash
    v2 = pol.step(x, {"u": True, "v": True})
    ev = [e for e in pol.events if isinstance(e, AssumptionViolationEvent)]
    assert len(ev) == 2 and ev[1].resynced is None and pol.holding
    assert np.array_equal(v2, np.zeros(2))
    # a reading it can follow again ends the hold
    v3 = pol.step(x, {"v": True})
    assert not pol.holding and pol.mode == "c"
    assert np.allclose(v3, model.velocity(x, "c", dt=pol.dt))
    # an initial reading the assumptions rule out
    pol.reset(x, {"u": True})
    first = pol.events[0]
    assert isinstance(first, AssumptionViolationEvent) and pol.mode == "b"


def test_uncertified_or_tampered_model_is_refused(tmp_path: Path) -> None:
    aut, model, cert = _project(tmp_path / "p", [1.0, 3.0])
    LTLDSPolicy(aut, model, cert)  # the genuine pair runs
    # a DS changed in memory, the file untouched: the certificate does not cover it
    fake = model_from_dict(json.loads(Path(model.path or "").read_text()), path=model.path)
    doc = json.loads(Path(model.path or "").read_text())
    doc["modes"]["b"]["components"][0]["A"] = [[-1.0, -3.0], [3.0, -1.0]]
    forged = model_from_dict(doc, path=model.path)
    LTLDSPolicy(aut, fake, cert)
    with pytest.raises(CertificateError, match="differs from the certified file"):
        LTLDSPolicy(aut, forged, cert)
    # a certificate of another model file
    _, other, _ = _project(tmp_path / "q", [0.5, -1.8])
    with pytest.raises(CertificateError, match="refused"):
        LTLDSPolicy(aut, other, cert)
    # a control period longer than the certified one
    with pytest.raises(CertificateError, match="longer than the certified"):
        LTLDSPolicy(aut, model, cert, dt=0.02)
    # the file edited after certification
    mpath = Path(model.path or "")
    mpath.write_text(mpath.read_text().replace("-1.0", "-1.5", 1))
    assert not check_certificate(cert).ok
    with pytest.raises(CertificateError) as info:
        LTLDSPolicy(aut, load_model(mpath), cert)
    assert exit_code(info.value) == 1


def test_policy_pickles_mid_episode(looping: tuple[TaskAutomaton, Model, Path]) -> None:
    aut, model, cert = looping
    pol = LTLDSPolicy(aut, model, cert)
    run_episode(pol, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    copy = pickle.loads(pickle.dumps(pol))
    assert len(copy.model.modes["b"].cuts) == 1 and copy.mode == pol.mode
    rng = np.random.default_rng(0)
    for x in rng.uniform(-3.0, 6.0, (20, 2)):
        reading = Chain().read(x)
        a = pol.step(x, reading, perturbed=True)
        b = copy.step(x, reading, perturbed=True)
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12)
        assert pol.state == copy.state


def test_learned_cuts_saved_as_a_certified_model(looping: tuple[TaskAutomaton, Model, Path],
                                                 tmp_path: Path) -> None:
    aut, model, cert = looping
    pol = LTLDSPolicy(aut, model, cert)
    run_episode(pol, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    out = tmp_path / "models" / "chain.learned.model.json"
    ocert = tmp_path / "certificates" / "chain.learned.cert.json"
    save_certified(pol.model, out, ocert, dt="1/100")
    check = check_certificate(ocert)
    assert check.ok, check.problems
    again = load_model(out)
    assert len(again.modes["b"].cuts) == 1
    pol2 = LTLDSPolicy(aut, again, ocert)  # the new pair is covered; the cut is kept
    res = run_episode(pol2, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    assert res.success and res.cuts_added == 0


def test_batched_episodes_agree_with_single_episodes(
        nominal: tuple[TaskAutomaton, Model, Path]) -> None:
    from tli_verify.runtime.loop import run_episodes

    aut, model, cert = nominal
    starts = np.array([[-3.0, 4.0], [-2.0, 1.0], [-4.0, -1.0], [1.0, 2.0], [5.0, 1.0]])
    base = LTLDSPolicy(aut, model, cert)
    forks = [base.fork() for _ in starts]
    assert len({id(f.model) for f in forks}) == 1 and len({id(f.events) for f in forks}) == 5
    batch = run_episodes(forks,
                         [Chain() for _ in starts], starts, steps=3000, speed_cap=20.0)
    for x0, got in zip(starts, batch, strict=True):
        one = run_episode(pickle.loads(pickle.dumps(base)), Chain(), x0, steps=3000,
                          speed_cap=20.0)
        assert got.success == one.success and got.modes == one.modes
        assert got.steps == one.steps
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)
    assert all(r.success for r in batch)
    assert batch[-1].steps == 0 and batch[-1].modes == ("c",)  # started in the goal mode


def test_per_transition_ds_follow_the_plan_and_share_the_cut(tmp_path: Path) -> None:
    aut, _, _ = _project(tmp_path, [0.5, -1.8])
    mpath = tmp_path / "models" / "chain.model.json"
    doc = json.loads(mpath.read_text())
    b = doc["modes"].pop("b")
    doc["modes"]["b->c"] = {**b, "next_mode": "c"}
    doc["modes"]["b->a"] = {**_ds("b", "a", [-1.0, 3.0], [[-1.0, 0.0], [0.0, -1.0]])}
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = tmp_path / "certificates" / "chain.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    pol = LTLDSPolicy(aut, load_model(mpath), cpath)
    res = run_episode(pol, Chain(), [-3.0, 2.0], steps=1500, speed_cap=20.0)
    # in b the automaton can go to a or c; the plan is c (the goal), so b->c runs
    assert "b" in res.modes
    cuts = [e for e in res.events if isinstance(e, CutAdded)]
    fails = [e for e in res.events if isinstance(e, InvarianceFailure)]
    assert [f.key for f in fails] == ["b->c"]
    assert len(cuts) == 1 and cuts[0].keys == ("b->a", "b->c")
    assert len(pol.model.modes["b->a"].cuts) == 1 and len(pol.model.modes["b->c"].cuts) == 1
    assert res.success
    pol.reset([0.5, 1.0], {"u": True})  # starts in b (reported: not an initial reading)
    assert (pol.mode, pol.planned, pol.key) == ("b", "c", "b->c")


def test_shipped_scoop_pair_runs_and_a_tampered_certificate_is_refused(project: Path) -> None:
    from tli_verify.deploy.gate import run_gate
    from tli_verify.logic.spec import load_spec

    aut = synthesize(load_spec(project / "specs" / "scoop.toml"))
    mpath = project / "models" / "scoop.model.json"
    cert = project / "certificates" / "scoop.cert.json"
    pol = LTLDSPolicy(aut, load_model(mpath), cert)
    assert pol.goal_modes == ("d",) and pol.dt == pytest.approx(1e-2)  # the certified period
    pol.reset(np.full(pol.model.dim, -5.0), {})
    assert (pol.mode, pol.planned, pol.key) == ("a", "b", "a")
    assert run_gate(project, rerun=0).ok  # the gate and the executive agree on the genuine pair
    doc = json.loads(cert.read_text())
    doc["control_period"]["dt"] = "1/10"  # a longer certified period, digest left stale
    cert.write_text(json.dumps(doc))
    assert not run_gate(project, rerun=0).ok
    with pytest.raises(CertificateError, match="does not re-check"):
        LTLDSPolicy(aut, load_model(mpath), cert)


def test_batched_perturbed_episodes_agree_with_single_episodes(
        looping: tuple[TaskAutomaton, Model, Path]) -> None:
    from tli_verify.runtime.loop import run_episodes

    aut, model, cert = looping
    starts = np.array([[-3.0, 2.0], [-3.0, 4.0], [-1.0, 0.0]])
    kicks = {0: (300, [1.0, 4.0]), 1: (50, [2.0, 0.0]), 2: (80, [-4.0, 4.0])}

    def push_batch(i: int, t: int, x: np.ndarray) -> np.ndarray | None:
        return np.array(kicks[i][1]) if t == kicks[i][0] else None

    base = LTLDSPolicy(aut, model, cert)
    batch = run_episodes([base.fork() for _ in starts], [Chain() for _ in starts], starts,
                         steps=1500, speed_cap=20.0, perturb=push_batch)
    for i, (x0, got) in enumerate(zip(starts, batch, strict=True)):
        one = run_episode(base.fork(), Chain(), x0, steps=1500, speed_cap=20.0,
                          perturb={kicks[i][0]: kicks[i][1]})
        assert got.modes == one.modes and got.steps == one.steps and got.success
        assert [type(e).__name__ for e in got.events] == [type(e).__name__ for e in one.events]
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)
    assert any(isinstance(e, CutAdded) for r in batch for e in r.events)
