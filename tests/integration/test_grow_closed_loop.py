"""Closed-loop spec growth (``--learn-transitions``, paper appendix F) on the scoop world.

From the demonstration-only spec (``tli spec infer demos/scoop_*.csv``: mode changes
``a -> b -> c -> d`` only), three perturbed episodes run by the executive with the shipped
certified model grow the automaton to exactly paper Fig. 3(a), the automaton of
``specs/scoop.toml``. Each missing transition is driven by one explicit push (:data:`PUSHES`)
computed from the task's true regions (``tasks/scoop.toml``), not found by a lucky
seed: whichever state of its source region the push meets, it lands where the world reads the
missing edge (:func:`test_each_push_lands_where_the_world_reads_its_edge`), and the episodes
check that the push meets the run in that region and mode.
"""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from tests.support.omega_oracle import omega_realizable
from tli_verify.cli import main
from tli_verify.demos import load_demos
from tli_verify.experiments.scoop_task import scoop_setup
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.logic.check import check_spec_file, synthesize
from tli_verify.logic.infer import infer_spec, load_labels
from tli_verify.logic.spec import GR1Spec, load_spec
from tli_verify.runtime.coverage import check_coverage
from tli_verify.runtime.episodes import pusher, run_variant
from tli_verify.runtime.events import (
    AssumptionViolationEvent,
    CutAdded,
    InvarianceFailure,
    Perturbation,
    TransitionLearned,
    TransitionRefused,
)
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.loop import EpisodeResult
from tli_verify.tasks.registry import find_task
from tli_verify.tasks.task import Task

START = (-6.0, 0.0)
"""The start of every episode here (white, left of the soup; ``tli run --start=-6,0``).
Unperturbed, the bundled model runs ``a`` (steps 0-252), ``b`` (253-431, the scoop, x2 down
to -6.8), ``c`` (432-886, up the pink column: x2 <= 2 until about step 600), ``d``."""


@dataclass(frozen=True, slots=True)
class Push:
    """One explicit perturbation (``tli run --perturb STEP:DX,DY``) that shows a missing edge.

    Attributes
    ----------
    step : int
        The step it is applied before (1-based, as ``--perturb``).
    shift : tuple of float
        The displacement ``(DX, DY)``; the state is then clipped to the workspace
        ``[-8, 8]^2``, as every push is.
    edge : tuple of str
        The mode change the world reads: ``(mode before, mode after)``.
    source : tuple of float
        ``(x1_lo, x1_hi, x2_lo, x2_hi)``: the box, intersected with the region of ``edge[0]``,
        from which the push lands in the region of ``edge[1]``, whatever the point.
    """

    step: int
    shift: tuple[float, float]
    edge: tuple[str, str]
    source: tuple[float, float, float, float]

    @property
    def flag(self) -> str:
        """The ``--perturb`` value."""
        return f"{self.step}:{self.shift[0]:g},{self.shift[1]:g}"


PUSHES = (
    # b -> a, out of the soup: yellow is x2 <= -4 outside the pink column; straight up by 8
    # keeps x1 outside the column and puts x2 in [0, 4]: white. Step 340 is mid-scoop.
    Push(340, (0.0, 8.0), ("b", "a"), (-8.0, 8.0, -8.0, -4.0)),
    # c -> a, a spill: pink is 2 <= x1 <= 6, x2 <= 6; left by 8 leaves the column (x1 in
    # [-6, -2]), up by 6 puts x2 at -2 or above (> -4): white, and the soup is lost.
    Push(540, (-8.0, 6.0), ("c", "a"), (2.0, 6.0, -8.0, 6.0)),
    # c -> b, back into the soup: left by 8 leaves the column, down by 6 puts x2 <= -4 from
    # any pink state with x2 <= 2 (the first ~170 steps of c; step 540 is at x2 = -0.6).
    Push(540, (-8.0, -6.0), ("c", "b"), (2.0, 6.0, -8.0, 2.0)),
)
"""The walkthrough's three pushes, in order: episode ``i`` (from :data:`START`) gets
``PUSHES[i]`` and grows the spec by ``PUSHES[i].edge``."""

LOOP_PUSH = (340, (0.5, 2.5))
"""``--perturb 340:0.5,2.5``: a push that stays in the soup (yellow to yellow: no new edge), to
just under its surface left of pink, where the bundled model's scooping DS rises out of the
soup by itself (Fig. 7's loop). From step 340's state (-0.38, -6.84) it lands at
(0.12, -4.34), inside :data:`LOOP_BAND`."""

LOOP_BAND = (-0.5, 1.5, -4.5, -4.05)
"""``(x1_lo, x1_hi, x2_lo, x2_hi)``: the landing points from which the DS of ``b`` leaves the
soup into white (every point of a 0.5 x 0.25 grid over it does, on the bundled model; x2 = -5
does not). A property of the learned DS, not of the world's geometry."""

REGION_OF_MODE = {"a": "white", "b": "yellow", "c": "pink", "d": "green"}
"""Mode -> name of its region (of ``Task.region_names``); pink reads ``c`` only with soup on
the spoon, which a run entering pink from yellow has."""


def _scoop() -> Task:
    """The bundled scoop task (``tasks/scoop.toml``)."""
    return find_task("scoop")


def _region_of(task: Task, mode: str) -> int:
    """The index (in ``task.region_names``) of the region where ``mode`` is read."""
    return task.region_names.index(REGION_OF_MODE[mode])


def _edges(aut: TaskAutomaton) -> set[tuple[Any, ...]]:
    """The automaton's edges, independent of state numbering: (source, reading cube, target),
    a state described by its mode, reading, outputs and goal memory."""

    def desc(sid: int) -> tuple[Any, ...]:
        s = aut.states[sid]
        return (s.mode, s.inputs, s.outputs, s.goal)

    return {(desc(t.source), t.sensors, t.off, desc(t.target)) for t in aut.transitions}


def _pushed(world: Task, push: Push, x: Any) -> np.ndarray:
    """The state ``push`` moves ``x`` to, with the pusher the episodes use."""
    out = pusher(world, {push.step: push.shift})(push.step, np.asarray(x, dtype=np.float64))
    assert out is not None
    return out


def _check_meets(world: Task, res: EpisodeResult, push: Push) -> None:
    """The push met the run in mode ``edge[0]``, inside its source box, and moved it into the
    region of ``edge[1]``."""
    before = res.states[push.step - 1]  # the state the push is applied to
    x1_lo, x1_hi, x2_lo, x2_hi = push.source
    assert res.modes[push.step - 1] == push.edge[0], "re-time the push: the run has moved on"
    assert world.region_one(before) == _region_of(world, push.edge[0])
    assert x1_lo <= before[0] <= x1_hi and x2_lo <= before[1] <= x2_hi, before
    assert world.region_one(_pushed(world, push, before)) == _region_of(world, push.edge[1])


@st.composite
def _in_source(draw: st.DrawFn, push: Push) -> tuple[float, float]:
    x1_lo, x1_hi, x2_lo, x2_hi = push.source
    x = (draw(st.floats(x1_lo, x1_hi)), draw(st.floats(x2_lo, x2_hi)))
    task = _scoop()
    assume(task.region_one(x) == _region_of(task, push.edge[0]))
    return x


@pytest.mark.parametrize("push", PUSHES, ids=lambda p: "".join(p.edge))
@given(data=st.data())
def test_each_push_lands_where_the_world_reads_its_edge(push: Push, data: st.DataObject
                                                        ) -> None:
    """Geometry only: from every state of its source (region of ``edge[0]`` within the box)
    the push lands in the region of ``edge[1]`` -- which is what makes the episodes below
    independent of where exactly the push meets the run."""
    world = _scoop()
    x = data.draw(_in_source(push))
    assert world.region_one(_pushed(world, push, x)) == _region_of(world, push.edge[1])


@pytest.fixture(scope="module")
def inferred(repo: Path) -> GR1Spec:
    demos = load_demos(sorted((repo / "demos").glob("scoop_*.csv")))
    labels = load_labels(repo / "specs" / "scoop.toml", demos[0].sensor_names)
    return infer_spec(demos, labels, name="scoop-inferred")


def _demo_only_policy(inferred: GR1Spec) -> tuple[Any, LTLDSPolicy]:
    setup = replace(scoop_setup(), automaton=synthesize(inferred))
    return setup, LTLDSPolicy(setup.automaton, setup.model, setup.certificate, spec=inferred,
                              learn_transitions=True)


@pytest.fixture(scope="module")
def grown(inferred: GR1Spec) -> tuple[LTLDSPolicy, list[EpisodeResult]]:
    """The executive after the three pushed episodes (one policy: what it learns carries
    over), and their results."""
    setup, pol = _demo_only_policy(inferred)
    results = [run_variant(setup, "LTL-DS", np.array(START), {p.step: p.shift}, policy=pol)
               for p in PUSHES]
    return pol, results


def test_perturbed_episodes_grow_the_demo_spec_to_fig_5a(
        inferred: GR1Spec, grown: tuple[LTLDSPolicy, list[EpisodeResult]], specs_dir: Path,
        tmp_path: Path) -> None:
    demo_only = synthesize(inferred)
    paper = synthesize(load_spec(specs_dir / "scoop.toml"))
    assert _edges(demo_only) < _edges(paper)  # starts strictly smaller than Fig. 3(a)
    pol, results = grown
    world = _scoop()
    assert all(r.success for r in results)
    for push, r in zip(PUSHES, results, strict=True):
        _check_meets(world, r, push)
        # each episode learns exactly its push's edge, at the push, as a push (replanned,
        # never cut)
        ev = [e for e in r.events if isinstance(e, TransitionLearned)]
        assert [(e.step, e.from_mode, e.to_mode, e.perturbed) for e in ev] \
            == [(push.step, *push.edge, True)]
        at = {type(o) for o in r.events if o.step == push.step}
        assert Perturbation in at and InvarianceFailure not in at and CutAdded not in at
    assert list(pol.learned) == [p.edge for p in PUSHES]
    ev = [e for r in results for e in r.events if isinstance(e, TransitionLearned)]
    assert [e.mode_edges for e in ev] == [4, 5, 6]  # each adds exactly its own edge
    assert ev[-1].states == len(pol.automaton.states)
    # no reading was left unexplained once the spec had grown
    assert not any(isinstance(e, (AssumptionViolationEvent, TransitionRefused))
                   for r in results for e in r.events)
    # the grown automaton is Fig. 3(a): same edges, same mode graph
    assert _edges(pol.automaton) == _edges(paper)
    assert pol.automaton.mode_transitions() == paper.mode_transitions()
    # the grown spec, written as TOML, is accepted by `tli spec check` and gives that automaton
    assert pol.spec_toml is not None
    out = tmp_path / "grown.toml"
    out.write_text(pol.spec_toml)
    result = check_spec_file(out)
    assert result.realizable and result.well_separated
    assert _edges(synthesize(result.spec)) == _edges(paper)
    # the certified model still names (and its certificate still binds) the original spec
    assert pol.model.spec_path is not None and pol.model.spec_path.name == "scoop.toml"
    check_coverage(pol.model, pol.certificate)


def test_the_ds_leaving_the_soup_by_itself_is_learned_and_cut(inferred: GR1Spec) -> None:
    """The other way an edge shows: no push across regions; the DS of ``b`` leaves the soup
    itself (an invariance failure): the edge is learned *and* the exit is cut, same step."""
    setup, pol = _demo_only_policy(inferred)
    world = _scoop()
    step, shift = LOOP_PUSH
    r = run_variant(setup, "LTL-DS", np.array(START), {step: shift}, policy=pol)
    assert r.success
    # the push meets the scoop (mode b) and keeps it in the soup, inside the band: b -> b
    assert r.modes[step - 1] == "b"
    landed = _pushed(world, Push(step, shift, ("b", "b"), LOOP_BAND), r.states[step - 1])
    assert world.region_one(landed) == _region_of(world, "b")
    x1_lo, x1_hi, x2_lo, x2_hi = LOOP_BAND
    assert x1_lo <= landed[0] <= x1_hi and x2_lo <= landed[1] <= x2_hi, landed
    ev = [e for e in r.events if isinstance(e, TransitionLearned)]
    assert [(e.from_mode, e.to_mode, e.perturbed) for e in ev] == [("b", "a", False)]
    assert ev[0].step > step and ev[0].mode_edges == 4
    at = {type(o) for o in r.events if o.step == ev[0].step}
    assert {InvarianceFailure, CutAdded} <= at and Perturbation not in at
    # the state read at that step is out of the soup, in white
    assert world.region_one(r.states[ev[0].step - 1]) == _region_of(world, "a")
    assert r.cuts_added >= 1 and pol.learned == (("b", "a"),)


def test_grown_spec_cross_checked_by_spot_and_omega(
        inferred: GR1Spec, grown: tuple[LTLDSPolicy, list[Any]], specs_dir: Path) -> None:
    import spot

    spec = grown[0].spec
    assert spec is not None
    with contextlib.redirect_stdout(io.StringIO()):  # omega prints its reasons on stdout
        assert omega_realizable(spec)
    paper = load_spec(specs_dir / "scoop.toml")

    def phi_ts(s: GR1Spec) -> Any:
        """The conjunction of the file's system safety formulas (phi_t^s and the marker)."""
        return spot.formula.And([f.ltl for f in s.guarantee.safety if f.origin == "file"])

    # Spot: the grown phi_t^s is equivalent to the one of the paper's spec (Fig. 3(a))
    assert spot.are_equivalent(phi_ts(spec), phi_ts(paper))
    assert not spot.are_equivalent(phi_ts(inferred), phi_ts(paper))


def test_cli_grows_across_episodes_and_writes_the_spec(
        inferred: GR1Spec, specs_dir: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    from tli_verify.logic.infer import spec_to_toml

    spec = tmp_path / "g0.toml"
    spec.write_text(spec_to_toml(inferred))
    per_episode = []
    for i, push in enumerate(PUSHES, start=1):  # the commands of docs/howto/grow-spec.md
        nxt = tmp_path / f"g{i}.toml"
        code = main(["run", "--task", "scoop", f"--start={START[0]:g},{START[1]:g}",
                     "--perturb", push.flag, "--spec", str(spec), "--learn-transitions",
                     "--grown-spec", str(nxt), "--out", str(tmp_path / f"run{i}"), "--json"])
        rec = json.loads(capsys.readouterr().out)
        assert code == 0 and rec["success"]
        assert rec["grown_spec"] == str(nxt) and rec["spec"] == str(spec)
        learned = [e for e in rec["events"] if e["event"] == "TransitionLearned"]
        assert len(learned) == len(rec["learned_transitions"])
        per_episode.append((rec["learned_transitions"], [e["step"] for e in learned],
                            rec["mode_sequence"]))
        spec = nxt
    # the growth docs/howto/grow-spec.md prints: one edge per episode, at its push
    assert per_episode == [([["b", "a"]], [340], "ababcd"),
                           ([["c", "a"]], [540], "abcabcd"),
                           ([["c", "b"]], [540], "abcbcd")]
    paper = synthesize(load_spec(specs_dir / "scoop.toml"))
    assert _edges(synthesize(load_spec(spec))) == _edges(paper)
    assert main(["spec", "check", str(spec)]) == 0
    capsys.readouterr()


def test_cli_growth_usage_errors(tmp_path: Path, specs_dir: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--task", "scoop", "--grown-spec", str(tmp_path / "g.toml"),
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "--learn-transitions" in err
    assert err.count("\n") == 1
    # a spec whose mode labels differ from those the model's DS were learned on is refused
    other = tmp_path / "other.toml"
    other.write_text((specs_dir / "scoop.toml").read_text().replace(
        'b = "r & !s & !t"', 'b = "r & !t"'))
    code = main(["run", "--task", "scoop", "--spec", str(other), "--learn-transitions",
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"error: --spec {other}") and "[modes]" in err
    assert err.count("\n") == 1
    # without --learn-transitions the model's own spec is still required (the model named
    # explicitly: by the project layout a spec alone would select models/other.model.json)
    model = specs_dir.parent / "models" / "scoop.model.json"
    code = main(["run", "--task", "scoop", "--model", str(model), "--spec", str(other),
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "not the spec the model names" in err
    # the grown spec may not overwrite an input, nor the spec the model and certificate bind
    named = specs_dir / "scoop.toml"
    before = named.read_bytes()
    code = main(["run", "--task", "scoop", "--learn-transitions", "--grown-spec",
                 str(specs_dir / ".." / "specs" / "scoop.toml"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "grown spec would overwrite" in err
    assert named.read_bytes() == before
    code = main(["run", "--task", "scoop", "--spec", str(other), "--learn-transitions",
                 "--grown-spec", str(other), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "grown spec" in err


def test_batched_episodes_grow_as_single_episodes(inferred: GR1Spec) -> None:
    """``run_episodes`` (the batched fast path) grows each fork's spec as ``run_episode``."""
    from tli_verify.runtime.episodes import run_variant_batch

    setup = replace(scoop_setup(), automaton=synthesize(inferred))
    base = LTLDSPolicy(setup.automaton, setup.model, setup.certificate, spec=inferred,
                       learn_transitions=True)
    # the second start is where the demonstrations start: its run enters c at step 719, so
    # the c -> b push comes 108 steps into c, as PUSHES[2] does from START
    starts = np.array([START, (-5.0, 4.5)])
    pushes = [PUSHES[0], replace(PUSHES[2], step=719 + 108)]
    perts = [{p.step: p.shift} for p in pushes]
    batch = run_variant_batch(setup, "LTL-DS", starts, perts, policy=base)
    assert base.learned == ()  # forks grow their own copies
    for x0, push, got in zip(starts, pushes, batch, strict=True):
        _check_meets(setup.task, got, push)
        one = run_variant(setup, "LTL-DS", x0, {push.step: push.shift}, policy=base.fork())
        learned = [(e.from_mode, e.to_mode) for e in got.events
                   if isinstance(e, TransitionLearned)]
        assert learned == [push.edge] == [(e.from_mode, e.to_mode) for e in one.events
                                          if isinstance(e, TransitionLearned)]
        assert got.modes == one.modes and got.success and one.success
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)
