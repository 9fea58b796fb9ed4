"""Repeated invariance failures (:mod:`tli_verify.runtime.repeats`) on a task the test writes.

A 3-D toy project: one sensor ``u``; mode ``a`` (``!u``) and the goal mode ``b`` (``u``); a
hand-built certified model (stable linear DS, ``P = I``). The executive is fed states by hand:
the run enters ``b`` and leaves it with no perturbation (an invariance failure of ``b``), twice.
The check must call the second exit a repeat exactly when it crosses the first failure's cut,
with the executive's own cuts and with the cuts replayed for a run that learned none.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tli_verify.certification.certificate import issue_certificate, write_certificate
from tli_verify.errors import TliError
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import parse_spec
from tli_verify.model.serialize import load_model, model_from_dict, save_model
from tli_verify.runtime.events import CutAdded, InvarianceFailure
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.repeats import REPEAT_TOL, check_repeats, replay_cuts

SPEC = '''
name = "two-modes-3d"
inputs = ["u"]
outputs = ["a", "b", "p"]
[modes]
a = "!u"
b = "u"
[assume]
init = "!u"
liveness = ["GF(!a | u)"]
[guarantee]
init = "a & !p"
safety = ["G(a -> X(a | b))", "G(b -> X(a | b))", "G(X p <-> (b & X a))"]
liveness = ["GF(b | p)"]
[goal]
modes = ["b"]
'''

I3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
STABLE = [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
B_STAR = [0.0, 0.0, 1.0]


def _ds(mode: str, nxt: str | None, att: list[float]) -> dict[str, Any]:
    return {"mode": mode, "next_mode": nxt, "attractor": att, "P": I3,
            "components": [{"prior": 1.0, "mean": att, "cov": I3, "A": STABLE}], "cuts": []}


def _policy(root: Path, *, learn_cuts: bool) -> LTLDSPolicy:
    for d in ("specs", "models", "certificates"):
        (root / d).mkdir(parents=True, exist_ok=True)
    (root / "specs" / "toy.toml").write_text(SPEC)
    doc = {"schema_version": 1, "state_names": ["x", "y", "z"], "spec": "../specs/toy.toml",
           "modes": {"a": _ds("a", "b", [-2.0, 0.0, 0.0]), "b": _ds("b", None, B_STAR)}}
    mpath = root / "models" / "toy.model.json"
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = root / "certificates" / "toy.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    spec = parse_spec(SPEC)
    return LTLDSPolicy(synthesize(spec), load_model(mpath), cpath, spec=spec,
                       learn_cuts=learn_cuts, goal_modes=["b"])


def _exit_twice(pol: LTLDSPolicy, second: list[list[float]]) -> None:
    """Enter b at (0, 0, 0), leave it at x = 1 (first failure), come back, then run the
    states ``second`` (entry, last in-mode, failure state) through b."""
    pol.reset(np.array([-2.0, 0.0, 0.0]), {})
    first = [[0.0, 0.0, 0.0], [0.9, 0.0, 0.5], [1.1, 0.0, 0.5]]
    for run in (first, second):
        entry, last, out = (np.array(x) for x in run)
        pol.decide(entry, {"u": True})
        pol.decide(last, {"u": True})
        pol.decide(out, {})  # no perturbation reported: an invariance failure of b
        assert pol.mode == "a"


REPEAT = [[0.0, 0.0, 0.0], [0.88, 0.0, 0.5], [1.15, 0.0, 0.5]]
"""Out again near where the first run left: beyond the first failure's cut."""
ELSEWHERE = [[0.0, 0.0, 0.0], [0.0, 0.9, 0.5], [0.0, 1.1, 0.5]]
"""Out on another side (+y): a new failure."""


@pytest.mark.parametrize(("second", "repeated"), [(REPEAT, True), (ELSEWHERE, False)])
def test_a_second_exit_repeats_iff_it_crosses_the_first_cut(
        tmp_path: Path, second: list[list[float]], repeated: bool) -> None:
    learned = _policy(tmp_path / "ltlds", learn_cuts=True)
    _exit_twice(learned, second)
    cuts = [e.cut for e in learned.events if isinstance(e, CutAdded)]
    assert len(cuts) == 2
    beyond = float(cuts[0].normal @ (np.array(second[2]) - cuts[0].point))
    assert (beyond > REPEAT_TOL) is repeated  # the scenario is what it says
    own = check_repeats(learned.events, "b")
    assert [c.repeats for c in own] == [(), (0,) if repeated else ()]
    assert own[0].cut is cuts[0] and own[1].cut is cuts[1]

    # the same states without cut learning: the cuts are replayed, with the executive's rule
    blind = _policy(tmp_path / "blind", learn_cuts=False)
    start = blind.model
    _exit_twice(blind, second)
    assert not any(isinstance(e, CutAdded) for e in blind.events)
    failures = [e for e in blind.events if isinstance(e, InvarianceFailure)]
    assert [f.mode for f in failures] == ["b", "b"]
    replayed = check_repeats(blind.events, "b", replay_from=start)
    assert [c.repeats for c in replayed] == [c.repeats for c in own]
    # the first replayed cut is the executive's own (the same failure, the same kept states)
    first = replay_cuts(start, failures[:1])[0]
    assert first is not None
    np.testing.assert_allclose(first.normal, cuts[0].normal, atol=1e-9)
    np.testing.assert_allclose(first.point, cuts[0].point, atol=1e-12)


def test_a_failure_without_a_cut_is_no_boundary_and_a_learned_run_is_not_replayed(
        tmp_path: Path) -> None:
    learned = _policy(tmp_path, learn_cuts=True)
    start = learned.model
    _exit_twice(learned, REPEAT)
    events = list(learned.events)
    # drop the first cut, as if its QCQP had failed (CutFailed): nothing to repeat then
    first = next(k for k, e in enumerate(events) if isinstance(e, CutAdded))
    events.pop(first)
    checks = check_repeats(events, "b")
    assert checks[0].cut is None and [c.repeats for c in checks] == [(), ()]
    with pytest.raises(TliError, match="its own"):
        check_repeats(learned.events, "b", replay_from=start)
    assert check_repeats(learned.events, "a") == ()  # no failure of a: nothing to check
