"""Spec inference from demonstrations and online re-synthesis (tli_verify.logic.infer)."""

from __future__ import annotations

import contextlib
import functools
import io
import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.omega_oracle import omega_realizable
from tli_verify.demos import Demonstration, load_demos
from tli_verify.errors import DemoError, SpecError, UnrealizableError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.infer import (
    add_transition,
    infer_spec,
    infer_spec_text,
    load_labels,
    regrow,
    resume_state,
    spec_to_toml,
)
from tli_verify.logic.spec import GR1Spec, label_holds, load_spec, parse_spec

PERTURBATIONS = (("b", "a"), ("c", "a"), ("c", "b"))
"""The recovery edges perturbations discover on scoop (paper Fig. 3(a), grey edges)."""


def _omega(spec: GR1Spec) -> bool:
    with contextlib.redirect_stdout(io.StringIO()):  # omega prints its reasons on stdout
        return bool(omega_realizable(spec))


@pytest.fixture(scope="module")
def scoop_demos(repo: Path) -> list[Demonstration]:
    return load_demos(sorted((repo / "demos").glob("scoop_*.csv")))


@pytest.fixture(scope="module")
def scoop_labels(repo: Path, scoop_demos: list[Demonstration]) -> dict[str, str]:
    return load_labels(repo / "specs" / "scoop.toml", scoop_demos[0].sensor_names)


@pytest.fixture(scope="module")
def inferred(scoop_demos: list[Demonstration], scoop_labels: dict[str, str]) -> GR1Spec:
    return infer_spec(scoop_demos, scoop_labels, name="scoop-inferred")


def _demo_modes(spec: GR1Spec, demo: Demonstration) -> list[str]:
    modes = []
    for i in range(demo.n_samples):
        holds = [m for m in spec.mode_names if label_holds(spec, m, demo.sensor_reading(i))]
        assert len(holds) == 1
        modes.append(holds[0])
    return modes


def _replay(automaton: TaskAutomaton, spec: GR1Spec, demo: Demonstration) -> None:
    """The automaton follows the demonstration's readings and runs its labelled modes."""
    expected = _demo_modes(spec, demo)
    state = automaton.initial_state(demo.sensor_reading(0))
    assert automaton.states[state].mode == expected[0]
    for i in range(1, demo.n_samples):
        state, mode = automaton.next_mode(state, demo.sensor_reading(i))
        assert mode == expected[i], (demo.path, i)


def test_scoop_inferred_spec_is_realizable_well_separated_and_agrees_with_omega(
        inferred: GR1Spec) -> None:
    result = check_spec(inferred)
    assert result.realizable and result.well_separated and not result.warnings
    assert _omega(inferred)


def test_scoop_inferred_spec_round_trips_through_load_spec(inferred: GR1Spec,
                                                           tmp_path: Path) -> None:
    out = tmp_path / "inferred.toml"
    out.write_text(spec_to_toml(inferred))
    again = load_spec(out)
    assert [f.text for f in again.formulas()] == [f.text for f in inferred.formulas()]
    assert synthesize(again).to_dict() == synthesize(inferred).to_dict()


def test_scoop_demo_only_automaton_has_the_demonstrated_chain(inferred: GR1Spec) -> None:
    pairs = synthesize(inferred).mode_transitions()
    assert [p for p in pairs if p[0] != p[1]] == [["a", "b"], ["b", "c"], ["c", "d"]]


def test_inferred_automaton_reproduces_every_demonstration(
        inferred: GR1Spec, scoop_demos: list[Demonstration]) -> None:
    automaton = synthesize(inferred)
    for demo in scoop_demos:
        _replay(automaton, inferred, demo)
        assert _demo_modes(inferred, demo)[-1] == "d"


def test_perturbations_grow_the_automaton_to_fig_5a(inferred: GR1Spec, specs_dir: Path) -> None:
    grown = inferred
    sizes = []
    for a, b in PERTURBATIONS:
        grown = add_transition(grown, a, b)
        sizes.append(len(synthesize(grown).mode_transitions()))
    assert sizes == [8, 9, 10]  # each perturbation adds exactly its own edge
    paper = synthesize(load_spec(specs_dir / "scoop.toml"))
    ours = synthesize(grown)
    assert ours.mode_transitions() == paper.mode_transitions()
    # Not only the mode graph: the whole automaton is the sound scoop spec's.
    mine, theirs = ours.to_dict(), paper.to_dict()
    mine.pop("name")
    theirs.pop("name")
    assert mine == theirs
    result = check_spec(grown)
    assert result.realizable and result.well_separated
    assert _omega(grown)


def test_grown_spec_round_trips(inferred: GR1Spec, tmp_path: Path) -> None:
    grown = add_transition(add_transition(inferred, "b", "a"), "c", "a")
    out = tmp_path / "grown.toml"
    out.write_text(spec_to_toml(grown))
    again = load_spec(out)
    assert [f.text for f in again.formulas()] == [f.text for f in grown.formulas()]
    assert synthesize(again).to_dict() == synthesize(grown).to_dict()


def test_transition_into_unknown_mode_is_refused(inferred: GR1Spec) -> None:
    with pytest.raises(SpecError, match=r"not a known mode.*Asm\. 3"):
        add_transition(inferred, "b", "z")
    with pytest.raises(SpecError, match="not a known mode"):
        add_transition(inferred, "p", "a")  # the marker is an output, not a mode


def test_unrealizable_growth_is_refused_and_the_old_spec_kept(inferred: GR1Spec) -> None:
    before = synthesize(inferred).to_dict()
    # b -> a as a nominal (unmarked) change: the world may loop a, b, a, b forever while
    # meeting every fairness assumption, and GF d is lost.
    with pytest.raises(UnrealizableError, match=r"b -> a makes the spec unrealizable.*kept"):
        add_transition(inferred, "b", "a", perturbation=False)
    assert synthesize(inferred).to_dict() == before
    # The same edge marked as a perturbation is accepted (the GF(d | p) encoding).
    assert check_spec(add_transition(inferred, "b", "a")).realizable


def test_a_transition_already_allowed_leaves_the_spec_unchanged(specs_dir: Path,
                                                                inferred: GR1Spec) -> None:
    paper = load_spec(specs_dir / "scoop.toml")
    assert add_transition(paper, "c", "b") is paper
    assert add_transition(inferred, "a", "b") is inferred
    assert add_transition(inferred, "b", "a") is not inferred


def test_assumptions_that_cannot_be_relaxed_are_reported(inferred: GR1Spec) -> None:
    text = spec_to_toml(inferred).replace(
        'safety = [\n  "G((!r & !s & !t)', 'safety = [\n  "G(!t | X t)",\n  "G((!r & !s & !t)', 1)
    locked = parse_spec(text)  # sensor t, once on, stays on: d -> a cannot happen
    assert check_spec(locked).realizable
    with pytest.raises(SpecError, match=r"assumptions still rule out the sensor change"):
        add_transition(locked, "d", "a")


def test_resume_state_carries_on_after_the_new_edge(inferred: GR1Spec) -> None:
    old = synthesize(inferred)
    state = old.initial_state({"r": False, "s": False, "t": False})
    for reading in ({"r": True, "s": False, "t": False}, {"r": False, "s": True, "t": False}):
        state, _ = old.next_mode(state, reading)
    assert old.states[state].mode == "c"
    spill = {"r": False, "s": False, "t": False}  # a perturbation spills the soup: c -> a
    with pytest.raises(AssumptionViolation):
        old.next_mode(state, spill)
    grown = regrow(inferred, "c", "a", old.states[state], spill)
    assert grown.automaton.states[grown.state].mode == "a"
    assert "p" in grown.automaton.states[grown.state].outputs  # marked as a perturbation
    # The run carries on: contact, soup, target again reach d.
    s = grown.state
    for reading, mode in (({"r": True, "s": False, "t": False}, "b"),
                          ({"r": False, "s": True, "t": False}, "c"),
                          ({"r": False, "s": False, "t": True}, "d")):
        s, got = grown.automaton.next_mode(s, reading)
        assert got == mode
    # A reading no state carries is reported, not guessed.
    with pytest.raises(AssumptionViolation):
        resume_state(grown.automaton, old.states[state], {"r": True, "s": True, "t": False})


def test_bad_inputs(scoop_demos: list[Demonstration], tmp_path: Path) -> None:
    with pytest.raises(DemoError, match="no demonstrations"):
        infer_spec_text([], {"a": "r"})
    labels = tmp_path / "labels.toml"
    labels.write_text('[modes]\na = "!r & !s & !t"\nb = "q"\n')
    with pytest.raises(SpecError, match=r"labels.toml:3: modes.b: label uses 'q'"):
        load_labels(labels, scoop_demos[0].sensor_names)
    labels.write_text('name = "x"\n')
    with pytest.raises(SpecError, match=r"no \[modes\] table"):
        load_labels(labels, scoop_demos[0].sensor_names)
    with pytest.raises(SpecError, match="cannot read"):
        load_labels(tmp_path / "missing.toml", ("r",))
    # A mode no demonstration visits (paper Asm. 3).
    with pytest.raises(DemoError, match=r"'e'.*visited by no demonstration"):
        infer_spec_text(scoop_demos, {"a": "!r & !s & !t", "b": "r & !s & !t",
                                      "c": "!r & s & !t", "d": "!r & !s & t",
                                      "e": "r & s & t"})


# ------------------------------------------------------------------------------------------
# Random demonstrations: one-hot sensors, mode sequences with returns and shortcuts.


def _synthetic(sequences: list[list[int]], n_modes: int, hold: int = 2
               ) -> tuple[list[Demonstration], dict[str, str]]:
    sensors = tuple(f"s{i}" for i in range(n_modes))
    labels = {f"m{i}": " & ".join(s if j == i else f"!{s}" for j, s in enumerate(sensors))
              for i in range(n_modes)}
    demos = []
    for k, seq in enumerate(sequences):
        rows = [i for i in seq for _ in range(hold)]  # each mode held for `hold` samples
        n = len(rows)
        readings = np.zeros((n, n_modes), dtype=bool)
        readings[np.arange(n), rows] = True
        x = np.linspace(0.0, 1.0, n)[:, None]
        demos.append(Demonstration(path=f"demo{k}.csv", t=np.arange(n, dtype=float), x=x,
                                   dx=np.ones_like(x), sensor_names=sensors,
                                   sensors=readings))
    return demos, labels


@st.composite
def _mode_sequences(draw: st.DrawFn) -> tuple[list[list[int]], int]:
    n_modes = draw(st.integers(2, 4))
    sequences = []
    for _ in range(draw(st.integers(1, 3))):
        walk = draw(st.lists(st.integers(0, n_modes - 1), min_size=1, max_size=6))
        walk = [0, *walk, n_modes - 1]
        sequences.append([m for i, m in enumerate(walk) if i == 0 or m != walk[i - 1]])
    visited = {m for seq in sequences for m in seq}
    missing = [m for m in range(n_modes) if m not in visited]
    if missing:
        sequences.append([m for i, m in enumerate([0, *missing, n_modes - 1])
                          if i == 0 or m != [0, *missing, n_modes - 1][i - 1]])
    return sequences, n_modes


@settings(max_examples=15)
@given(_mode_sequences())
def test_random_demos_give_sound_specs_that_replay_them(
        case: tuple[list[list[int]], int]) -> None:
    sequences, n_modes = case
    demos, labels = _synthetic(sequences, n_modes)
    spec = parse_spec(infer_spec_text(demos, labels, name="random"))
    result = check_spec(spec)
    assert result.realizable and result.well_separated, sequences
    assert _omega(spec)
    automaton = synthesize(spec)
    for demo in demos:
        _replay(automaton, spec, demo)
    # phi_t^s holds exactly the demonstrated mode changes.
    shown = {(f"m{a}", f"m{b}") for seq in sequences for a, b in itertools.pairwise(seq)}
    edges = {(a, b) for a, b in automaton.mode_transitions() if a != b}
    assert edges == shown


def test_inferred_marker_name_avoids_sensors_and_modes() -> None:
    demos, labels = _synthetic([[0, 1]], 2)
    labels = {"p": labels["m0"], "q": labels["m1"]}
    spec = parse_spec(infer_spec_text(demos, labels))
    assert spec.outputs == ("p", "q", "p_")
    assert check_spec(spec).realizable


@functools.lru_cache(maxsize=1)
def _scoop_inferred() -> GR1Spec:
    repo = Path(__file__).resolve().parents[2]
    demos = load_demos(sorted((repo / "demos").glob("scoop_*.csv")))
    return infer_spec(demos, load_labels(repo / "specs" / "scoop.toml", demos[0].sensor_names))


_SCOOP_PAIRS = [(a, b) for a in "abcd" for b in "abcd" if a != b]


@settings(max_examples=6)
@given(st.lists(st.sampled_from(_SCOOP_PAIRS), min_size=1, max_size=4, unique=True))
def test_any_perturbation_growth_stays_sound_and_adds_exactly_its_edges(
        pairs: list[tuple[str, str]]) -> None:
    spec = _scoop_inferred()
    for a, b in pairs:
        spec = add_transition(spec, a, b)
    result = check_spec(spec)
    assert result.realizable and result.well_separated
    assert _omega(spec)
    edges = {(a, b) for a, b in synthesize(spec).mode_transitions() if a != b}
    assert edges == {("a", "b"), ("b", "c"), ("c", "d")} | set(pairs)
    again = parse_spec(spec_to_toml(spec))
    assert synthesize(again).to_dict() == synthesize(spec).to_dict()


def test_a_mode_seen_for_one_sample_is_an_observation() -> None:
    # Sensors that flicker through a mode for one sample (lagged or noisy readings): no DS
    # can be learned from it, but the sensor change it shows is real.
    demos, labels = _synthetic([[0, 1, 2]], 3, hold=1)
    spec = parse_spec(infer_spec_text(demos, labels))
    edges = {(a, b) for a, b in synthesize(spec).mode_transitions() if a != b}
    assert edges == {("m0", "m1"), ("m1", "m2")}


def test_an_unlabelled_reading_names_its_file_and_line(scoop_demos: list[Demonstration]
                                                       ) -> None:
    labels = {"a": "!r & !s & !t", "b": "r & !s & !t", "c": "!r & s & !t"}
    with pytest.raises(DemoError, match=r"scoop_1\.csv.*line \d+.*t=1.*satisfies no mode"):
        infer_spec_text(scoop_demos, labels)
