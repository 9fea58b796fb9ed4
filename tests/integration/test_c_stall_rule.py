"""The stall rule (``tli_verify.runtime.stall``) in the exported C evaluator: the artifact
carries it (parameters, each DS's level ``lambda_min(P) r^2``, each mode's re-entry DS), the C
executive runs it step for step as the Python executive does (firing when converged and when
blocked, re-entry ended by convergence and by a changed reading, perturbations during it), and
the loader refuses a forged level or re-entry that the artifact's own hash cannot catch."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.cpolicy import (
    F_MODE_CHANGE,
    F_REENTERED,
    F_STALL,
    CError,
    CPolicy,
    build,
    compiler,
    library,
    mask,
    step_both,
)
from tests.support.ndtask import SPEC, write_nd
from tli_verify.deploy.export import build_artifact, write_artifact
from tli_verify.runtime.events import Reentered, Stall
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.stall import StallRule, lyapunov_level, reentry_route

pytestmark = pytest.mark.skipif(compiler() is None, reason="no system C compiler (cc/gcc)")

NO_SOURCES: dict[str, Any] = {k: None for k in ("spec", "model", "certificate", "task",
                                                 "evidence")}
RULE = StallRule(radius=0.5, dwell=0.05, blocked_after=0.3, progress=0.005)
LABELS: tuple[frozenset[str], ...] = (frozenset(), frozenset({"r"}), frozenset({"s"}),
                                     frozenset({"t"}))


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return library(build(tmp_path_factory.mktemp("cbuild")))


def _exported(root: Path, n: int, rule: StallRule | None = RULE, spec_text: str = SPEC) -> Any:
    nd = write_nd(root, n, K=3, seed=n, spec_text=spec_text)
    art = build_artifact(nd.setup, goal_modes=("d",), goal_inputs=(), sources=NO_SOURCES,
                         max_online_cuts=8, stall=rule)
    nd.exported = write_artifact(art, root / "nd.tli.json")
    return nd


def test_the_artifact_records_the_rule_the_executive_runs(tmp_path: Path) -> None:
    nd = _exported(tmp_path, 3)
    art = nd.exported.artifact
    stall = art["stall"]
    assert {k: stall[k] for k in RULE.to_dict()} == RULE.to_dict()
    keys = [d["key"] for d in art["ds"]]
    for key, level in zip(keys, stall["levels"], strict=True):
        assert level == lyapunov_level(nd.model.modes[key].ds.P, RULE.radius)
    # b is re-entered from a, c from b; a (no predecessor) and d (the goal) never
    route = dict(zip(art["automaton"]["modes"], stall["reentry"], strict=True))
    for m, key in route.items():
        want = reentry_route(nd.automaton, nd.model, m)
        assert key == (None if want is None else want[1])
    assert route["a"] is None and route["d"] is None
    assert nd.model.modes[route["b"]].mode == "a" and nd.model.modes[route["c"]].mode == "b"
    # the text form carries the step counts the executive uses
    body = nd.exported.text_path.read_text()
    dwell, window = RULE.periods(art["dt"])
    assert re.search(rf"^stall 1 0\.5 0\.005 {dwell} {window}$", body, re.M)
    assert re.search(rf"^sizes( \d+){{10}} {window}$", body, re.M)
    # no rule: "stall 0", window 0
    off = _exported(tmp_path / "off", 3, rule=None)
    assert off.exported.artifact["stall"] is None
    assert re.search(r"^stall 0$", off.exported.text_path.read_text(), re.M)


@pytest.mark.parametrize("n", [2, 5, 7])
def test_stall_rule_parity_in_closed_loop(lib: Any, tmp_path: Path, n: int) -> None:
    """Closed-loop episodes on the flow, the readings held for long stretches (the
    environment breaking its liveness assumption: the next mode's reading does not come),
    the state sometimes stuck (a wall: the blocked test), pushes and reading changes at
    random: the same states, modes, DS, stall firings and re-entry ends, and bit-equal
    velocities (no cuts: ``learn_cuts=False``)."""
    nd = _exported(tmp_path, n)
    art = nd.exported.artifact
    inputs = art["automaton"]["inputs"]
    keys = [d["key"] for d in art["ds"]]
    rng = np.random.default_rng(100 + n)
    seen = {"converged": 0, "blocked": 0, "back converged": 0, "back by reading": 0,
            "pushed in re-entry": 0}
    for _ in range(8):
        pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01, learn_cuts=False)
        pol.stall_rule = RULE
        c = CPolicy(lib, nd.exported.text_path)
        reading = LABELS[0]
        x = nd.model.modes[keys[0]].ds.attractor + rng.normal(scale=0.3, size=n)
        pol.reset(x, reading)
        c.reset(x, mask(reading, inputs))
        stuck = 0
        for _ in range(2000):
            if rng.random() < 0.002:  # mostly b's and c's readings: modes with a predecessor
                reading = LABELS[rng.choice(len(LABELS), p=[0.1, 0.4, 0.4, 0.1])]
            perturbed = bool(rng.random() < 0.003)
            if perturbed:
                x = x + rng.normal(scale=0.3, size=n)
            in_reentry = pol._reentry is not None
            v_py, info, v_c, new = step_both(pol, c, x, reading, perturbed, art)
            stalls = [e for e in new if isinstance(e, Stall)]
            backs = [e for e in new if isinstance(e, Reentered)]
            assert bool(info.flags & F_STALL) == bool(stalls)
            assert bool(info.flags & F_REENTERED) == bool(backs)
            if stalls or backs:
                assert info.flags & F_MODE_CHANGE
            assert np.array_equal(v_py, v_c)
            for e in stalls:
                level = lyapunov_level(nd.model.modes[e.key].ds.P, RULE.radius)
                seen["converged" if e.value < level else "blocked"] += 1
            for back in backs:
                seen["back converged" if back.converged else "back by reading"] += 1
            seen["pushed in re-entry"] += int(in_reentry and perturbed)
            if stuck:
                stuck -= 1
            elif rng.random() < 0.003:
                stuck = 60  # held against a wall: V does not fall
            else:
                x = x + 0.01 * v_py
    assert all(v > 0 for v in seen.values()), seen


def _rehash(body: str) -> bytes:
    return (body + f"sha256 {hashlib.sha256(body.encode()).hexdigest()}\n").encode()


def _refused(lib: Any, data: bytes, tmp_path: Path) -> CError:
    path = tmp_path / "forged.tli.txt"
    path.write_bytes(data)
    with pytest.raises(CError) as info:
        CPolicy(lib, path)
    return info.value


def test_the_loader_refuses_a_forged_stall_rule(lib: Any, tmp_path: Path) -> None:
    """Forgeries a buggy or hostile exporter could hash correctly: only the loader's own
    checks catch them."""
    nd = _exported(tmp_path, 3)
    text = nd.exported.text_path.read_text()
    body = text[: text.rindex("sha256 ")]
    CPolicy(lib, nd.exported.text_path)  # the genuine one loads
    levels = re.search(r"^levels (.*)$", body, re.M)
    assert levels is not None
    vals = [float(v) for v in levels.group(1).split()]
    # a level above lambda_min(P) r^2 (V below it no longer means "within r of x*")
    forged = " ".join(repr(v * 1.01 if i == 1 else v) for i, v in enumerate(vals))
    err = _refused(lib, _rehash(body.replace(levels.group(0), f"levels {forged}")), tmp_path)
    assert err.code == 6 and "above lambda_min(P) r^2" in err.message
    # ... while one a hair below it loads (the check is not a blanket refusal)
    lower = " ".join(repr(v * (1 - 1e-3)) for v in vals)
    ok = tmp_path / "ok.tli.txt"
    ok.write_bytes(_rehash(body.replace(levels.group(0), f"levels {lower}")))
    CPolicy(lib, ok)
    # a re-entry through a DS that is not planned into the mode (b re-entered by b's own DS)
    reentry = re.search(r"^reentry (.*)$", body, re.M)
    assert reentry is not None
    route = [int(v) for v in reentry.group(1).split()]
    modes = nd.exported.artifact["automaton"]["modes"]
    keys = [d["key"] for d in nd.exported.artifact["ds"]]
    b = modes.index("b")
    own = next(i for i, k in enumerate(keys) if nd.model.modes[k].mode == "b")
    bad = list(route)
    bad[b] = own
    err = _refused(lib, _rehash(body.replace(reentry.group(0), "reentry " + " ".join(
        map(str, bad)))), tmp_path)
    assert err.code == 2 and "re-entry DS" in err.message
    # no re-entry for b although a's DS could re-enter it (the rule silently off there)
    bad = list(route)
    bad[b] = -1
    err = _refused(lib, _rehash(body.replace(reentry.group(0), "reentry " + " ".join(
        map(str, bad)))), tmp_path)
    assert err.code == 2 and "no re-entry DS" in err.message
    # a re-entry into a mode with no way back (d, the goal: d -> c is not a transition)
    bad = list(route)
    bad[modes.index("d")] = next(i for i, k in enumerate(keys)
                                 if nd.model.modes[k].next_mode == "d")
    err = _refused(lib, _rehash(body.replace(reentry.group(0), "reentry " + " ".join(
        map(str, bad)))), tmp_path)
    assert err.code == 2 and "re-entry DS" in err.message
    # the stall line's window against the header's
    stall = re.search(r"^stall 1 (\S+) (\S+) (\d+) (\d+)$", body, re.M)
    assert stall is not None
    err = _refused(lib, _rehash(body.replace(stall.group(0), stall.group(0).rsplit(" ", 1)[0]
                                             + f" {int(stall.group(4)) + 1}")), tmp_path)
    assert err.code == 5 and "stall window" in err.message
    # a rule switched off in the body but not in the header
    err = _refused(lib, _rehash(body.replace(stall.group(0), "stall 0")), tmp_path)
    assert err.code == 2 and "stall 0" in err.message


def _side_by_side(lib: Any, nd: Any, rule: StallRule) -> tuple[LTLDSPolicy, CPolicy, Any]:
    pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01, learn_cuts=False)
    pol.stall_rule = rule
    return pol, CPolicy(lib, nd.exported.text_path), nd.exported.artifact["automaton"]


def test_an_input_the_strategy_never_reads_does_not_end_a_reentry(lib: Any,
                                                                   tmp_path: Path) -> None:
    """A free input (declared, never read by the strategy, so no state records it) read true
    is not a changed reading: the re-entry runs until its DS converges. It used to end every
    re-entry on its first step (the raw reading against the state's recorded inputs)."""
    nd = _exported(tmp_path, 2, spec_text=SPEC.replace('inputs  = ["r", "s", "t"]',
                                                        'inputs  = ["r", "s", "t", "z"]'))
    assert "z" in nd.automaton.free_inputs
    pol, c, aut = _side_by_side(lib, nd, RULE)
    kb = next(k for k, m in nd.model.modes.items() if m.mode == "b")
    ka = next(k for k, m in nd.model.modes.items() if m.mode == "a")
    xb = nd.model.modes[kb].ds.attractor.copy()
    xa = nd.model.modes[ka].ds.attractor.copy()
    pol.reset(xb, {"z"})
    c.reset(xb, mask({"z"}, aut["inputs"]))
    reading = frozenset({"r", "z"})
    x = xb.copy()
    for _ in range(400):  # converged in b: fires; a's DS then runs to a's attractor
        v, _, v_c, _ = step_both(pol, c, x, reading, False, nd.exported.artifact)
        assert np.array_equal(v, v_c)
        x = x + 0.01 * v
        if any(isinstance(e, Reentered) for e in pol.events):
            break
    (back,) = [e for e in pol.events if isinstance(e, Reentered)]
    assert back.converged  # ended by a's DS converging, not by the free input
    assert np.linalg.norm(x - xa) < np.linalg.norm(xb - xa)


def test_a_reentry_ended_by_a_new_reading_lets_the_automaton_take_it(lib: Any,
                                                                      tmp_path: Path) -> None:
    """With a one-step dwell (``dwell=0``), a re-entry ended by the next mode's reading used to
    fire again in the same period, before the automaton saw the reading, and again each time
    (the state held: forever). The period that ends a re-entry runs no stall test, so the
    automaton takes the reading in the next one."""
    nd = _exported(tmp_path, 2, rule=StallRule(radius=0.5, dwell=0.0, blocked_after=0.3,
                                               progress=0.005))
    pol, c, aut = _side_by_side(lib, nd, StallRule(radius=0.5, dwell=0.0, blocked_after=0.3,
                                                   progress=0.005))
    kb = next(k for k, m in nd.model.modes.items() if m.mode == "b")
    xb = nd.model.modes[kb].ds.attractor.copy()
    pol.reset(xb, frozenset())
    c.reset(xb, 0)
    for reading in ({"r"}, {"r"}):  # enter b at its attractor: the rule fires at once
        pol.step(xb, reading)
        c.decide(xb, mask(reading, aut["inputs"]), False)
    assert pol.mode == "a" and any(isinstance(e, Stall) for e in pol.events)
    modes = []
    for _ in range(4):  # c's reading arrives; the state held where b had converged
        pol.step(xb, {"s"})
        info = c.decide(xb, mask({"s"}, aut["inputs"]), False)
        assert aut["modes"][info.mode] == pol.mode
        modes.append(pol.mode)
    assert modes[:2] == ["b", "c"], modes  # back to b, then the automaton takes s
    assert sum(isinstance(e, Stall) for e in pol.events) == 1


def test_export_loads_its_artifact_in_c_before_writing_it(tmp_path: Path) -> None:
    """``tli export`` loads the text form in the C evaluator first: an artifact the loader
    refuses (here a stall level above lambda_min(P) r^2, which no Python check of the JSON
    schema or hash catches) is refused with the loader's own message, nothing written."""
    from tli_verify.deploy.export import c_load_check
    from tli_verify.errors import ExportError

    nd = _exported(tmp_path, 3)
    art = dict(nd.exported.artifact)
    assert c_load_check(art, where="nd") is True
    forged = dict(art, stall=dict(art["stall"], levels=[v * 1.01 for v in art["stall"]["levels"]]))
    with pytest.raises(ExportError, match=r"nd: refused: the C evaluator would not load its "
                                          r"artifact: .*above lambda_min\(P\) r\^2"):
        c_load_check(forged, where="nd")


def test_a_library_that_does_not_load_is_one_export_error(tmp_path: Path) -> None:
    """A shared library the dynamic loader refuses (a foreign compiler's output, a noexec
    directory) is an ExportError naming it -- one gate line or one error line -- not an
    OSError traceback."""
    from tli_verify.deploy.cloop import CEvaluator
    from tli_verify.errors import ExportError

    junk = tmp_path / "libtli_policy.so"
    junk.write_bytes(b"\x7fELF not really")
    with pytest.raises(ExportError, match="the C evaluator's library does not load"):
        CEvaluator(junk, tmp_path / "unused.tli.txt")
