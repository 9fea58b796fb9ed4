"""Closed-loop spec growth (``--learn-transitions``, paper appendix E) on the scoop world.

From the demonstration-only spec (``tli spec infer demos/scoop_*.csv``: mode changes
``a -> b -> c -> d`` only), seeded perturbed episodes run by the executive with the shipped
certified model grow the automaton to exactly paper Fig. 5(a), the automaton of
``specs/scoop.toml``.
"""

from __future__ import annotations

import contextlib
import io
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.omega_oracle import omega_realizable
from tli_verify.cli import main
from tli_verify.demos import load_demos
from tli_verify.experiments.scoop import (
    bundled_setup,
    random_perturbations,
    random_start,
    run_variant,
)
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.logic.check import check_spec_file, synthesize
from tli_verify.logic.infer import infer_spec, load_labels
from tli_verify.logic.spec import GR1Spec, load_spec
from tli_verify.runtime.events import (
    AssumptionViolationEvent,
    CutAdded,
    InvarianceFailure,
    Perturbation,
    TransitionLearned,
    TransitionRefused,
)
from tli_verify.runtime.executive import LTLDSPolicy, check_coverage

SEEDS = (19, 6, 9)
"""The seeded episodes of the README walkthrough (``tli run --seed S --perturb random:3``; with
the scooping demonstrations of issue 11 D, seed 19 is the Fig. 7 loop's b -> a failure)."""


def _edges(aut: TaskAutomaton) -> set[tuple[Any, ...]]:
    """The automaton's edges, independent of state numbering: (source, reading cube, target),
    a state described by its mode, reading, outputs and goal memory."""

    def desc(sid: int) -> tuple[Any, ...]:
        s = aut.states[sid]
        return (s.mode, s.inputs, s.outputs, s.goal)

    return {(desc(t.source), t.sensors, t.off, desc(t.target)) for t in aut.transitions}


@pytest.fixture(scope="module")
def inferred(repo: Path) -> GR1Spec:
    demos = load_demos(sorted((repo / "demos").glob("scoop_*.csv")))
    labels = load_labels(repo / "specs" / "scoop.toml", demos[0].sensor_names)
    return infer_spec(demos, labels, name="scoop-inferred")


@pytest.fixture(scope="module")
def grown(inferred: GR1Spec) -> tuple[LTLDSPolicy, list[Any]]:
    """The executive after the seeded perturbed episodes, and their results."""
    setup = bundled_setup()
    setup = replace(setup, automaton=synthesize(inferred))
    pol = LTLDSPolicy(setup.automaton, setup.model, setup.certificate, spec=inferred,
                      learn_transitions=True)
    results = []
    for seed in SEEDS:  # as `tli run --seed S --perturb random:3` draws them
        x0 = random_start(setup.world, np.random.default_rng([seed, 3]))
        pert = random_perturbations(np.random.default_rng([seed, 11]), 3, setup.world)
        results.append(run_variant(setup, "LTL-DS", x0, pert, policy=pol))
    return pol, results


def test_perturbed_episodes_grow_the_demo_spec_to_fig_5a(
        inferred: GR1Spec, grown: tuple[LTLDSPolicy, list[Any]], specs_dir: Path,
        tmp_path: Path) -> None:
    demo_only = synthesize(inferred)
    paper = synthesize(load_spec(specs_dir / "scoop.toml"))
    assert _edges(demo_only) < _edges(paper)  # starts strictly smaller than Fig. 5(a)
    pol, results = grown
    assert all(r.success for r in results)
    assert sorted(pol.learned) == [("b", "a"), ("c", "a"), ("c", "b")]
    ev = [e for r in results for e in r.events if isinstance(e, TransitionLearned)]
    assert [(e.from_mode, e.to_mode) for e in ev] == list(pol.learned)
    assert [e.mode_edges for e in ev] == [4, 5, 6]  # each adds exactly its own edge
    assert ev[-1].states == len(pol.automaton.states)
    for r in results:
        for e in r.events:
            if not isinstance(e, TransitionLearned):
                continue
            at = {type(o) for o in r.events if o.step == e.step}
            if e.perturbed:  # a push: replanned, never cut
                assert Perturbation in at and InvarianceFailure not in at
            else:  # the DS left the mode itself: the edge is learned *and* the exit is cut
                assert {InvarianceFailure, CutAdded} <= at
    # no reading was left unexplained once the spec had grown
    assert not any(isinstance(e, (AssumptionViolationEvent, TransitionRefused))
                   for r in results for e in r.events)
    # the grown automaton is Fig. 5(a): same edges, same mode graph
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

    # Spot: the grown phi_t^s is equivalent to the one of the paper's spec (Fig. 5(a))
    assert spot.are_equivalent(phi_ts(spec), phi_ts(paper))
    assert not spot.are_equivalent(phi_ts(inferred), phi_ts(paper))


def test_cli_grows_across_episodes_and_writes_the_spec(
        inferred: GR1Spec, specs_dir: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    from tli_verify.logic.infer import spec_to_toml

    spec = tmp_path / "g0.toml"
    spec.write_text(spec_to_toml(inferred))
    per_episode = []
    for i, seed in enumerate(SEEDS):
        nxt = tmp_path / f"g{i + 1}.toml"
        code = main(["run", "--world", "scoop", "--seed", str(seed), "--perturb", "random:3",
                     "--spec", str(spec), "--learn-transitions", "--grown-spec", str(nxt),
                     "--out", str(tmp_path / f"run{seed}"), "--json"])
        rec = json.loads(capsys.readouterr().out)
        assert code == 0 and rec["success"]
        assert rec["grown_spec"] == str(nxt) and rec["spec"] == str(spec)
        assert sum(e["event"] == "TransitionLearned" for e in rec["events"]) \
            == len(rec["learned_transitions"])
        per_episode.append(rec["learned_transitions"])
        spec = nxt
    # the growth the README walkthrough prints (section 7)
    assert per_episode == [[["b", "a"]], [["c", "a"], ["c", "b"]], []]
    paper = synthesize(load_spec(specs_dir / "scoop.toml"))
    assert _edges(synthesize(load_spec(spec))) == _edges(paper)
    assert main(["spec", "check", str(spec)]) == 0
    capsys.readouterr()


def test_cli_growth_usage_errors(tmp_path: Path, specs_dir: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--world", "scoop", "--grown-spec", str(tmp_path / "g.toml"),
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "--learn-transitions" in err
    assert err.count("\n") == 1
    # a spec whose mode labels differ from those the model's DS were learned on is refused
    other = tmp_path / "other.toml"
    other.write_text((specs_dir / "scoop.toml").read_text().replace(
        'b = "r & !s & !t"', 'b = "r & !t"'))
    code = main(["run", "--world", "scoop", "--spec", str(other), "--learn-transitions",
                 "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"error: --spec {other}") and "[modes]" in err
    assert err.count("\n") == 1
    # without --learn-transitions the model's own spec is still required
    code = main(["run", "--world", "scoop", "--spec", str(other), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "not the spec the model names" in err
    # the grown spec may not overwrite an input, nor the spec the model and certificate bind
    named = specs_dir / "scoop.toml"
    before = named.read_bytes()
    code = main(["run", "--world", "scoop", "--learn-transitions", "--grown-spec",
                 str(specs_dir / ".." / "specs" / "scoop.toml"), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "grown spec would overwrite" in err
    assert named.read_bytes() == before
    code = main(["run", "--world", "scoop", "--spec", str(other), "--learn-transitions",
                 "--grown-spec", str(other), "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "grown spec" in err


def test_batched_episodes_grow_as_single_episodes(inferred: GR1Spec) -> None:
    """``run_episodes`` (the batched fast path) grows each fork's spec as ``run_episode``."""
    from tli_verify.experiments.scoop import run_variant_batch

    setup = replace(bundled_setup(), automaton=synthesize(inferred))
    base = LTLDSPolicy(setup.automaton, setup.model, setup.certificate, spec=inferred,
                       learn_transitions=True)
    starts = np.array([random_start(setup.world, np.random.default_rng([s, 3]))
                       for s in SEEDS[:2]])
    perts = [random_perturbations(np.random.default_rng([s, 11]), 3, setup.world)
             for s in SEEDS[:2]]
    batch = run_variant_batch(setup, "LTL-DS", starts, perts, policy=base)
    assert base.learned == ()  # forks grow their own copies
    for x0, pert, got in zip(starts, perts, batch, strict=True):
        one = run_variant(setup, "LTL-DS", x0, pert, policy=base.fork())
        learned = [(e.from_mode, e.to_mode) for e in got.events
                   if isinstance(e, TransitionLearned)]
        assert learned and learned == [(e.from_mode, e.to_mode) for e in one.events
                                       if isinstance(e, TransitionLearned)]
        assert got.modes == one.modes and got.success and one.success
        np.testing.assert_allclose(got.states, one.states, rtol=1e-9, atol=1e-9)
