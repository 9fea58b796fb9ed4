"""Task automata: the paper's Fig. 5(a), determinism, Mealy stepping, file formats."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tli_verify.errors import UnrealizableError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec

BLACK = [["a", "b"], ["b", "c"], ["c", "d"]]  # the demonstrations
GRAY = [["b", "a"], ["c", "a"], ["c", "b"]]  # recoveries the LTL adds
LOOPS = [["a", "a"], ["b", "b"], ["c", "c"], ["d", "d"]]
FIG5A = sorted([*BLACK, *GRAY, *LOOPS])


@pytest.fixture(scope="module")
def scoop(specs_dir: Path) -> TaskAutomaton:
    return synthesize(load_spec(specs_dir / "scoop.toml"))


def test_scoop_automaton_is_paper_fig5a(scoop: TaskAutomaton) -> None:
    assert scoop.mode_transitions() == FIG5A


def test_scoop_replans_after_a_spill(scoop: TaskAutomaton) -> None:
    state = scoop.initial_state({"r": False, "s": False, "t": False})
    modes = []
    for reading in (["r"], ["s"], [], ["r"], ["s"], ["t"], ["t"]):
        state, mode = scoop.next_mode(state, reading)
        modes.append(mode)
    # reach, scoop, transport, spill -> reach again, re-scoop, transport, done, stay done
    assert modes == ["b", "c", "a", "b", "c", "d", "d"]


def test_impossible_sensor_change_is_reported(scoop: TaskAutomaton) -> None:
    state = scoop.initial_state([])
    with pytest.raises(AssumptionViolation, match="violates the environment assumptions"):
        scoop.next_mode(state, ["t"])  # reaching -> at target: physically impossible
    with pytest.raises(AssumptionViolation):
        scoop.initial_state(["r"])


def test_same_spec_same_automaton_byte_for_byte(specs_dir: Path) -> None:
    for name in ("scoop", "cooking-cb", "color-tracing-c"):
        a = synthesize(load_spec(specs_dir / f"{name}.toml"))
        b = synthesize(load_spec(specs_dir / f"{name}.toml"))
        assert json.dumps(a.to_json(), sort_keys=True) == json.dumps(b.to_json(), sort_keys=True)
        assert a.to_dot() == b.to_dot()


def test_json_round_trip(scoop: TaskAutomaton) -> None:
    data = json.loads(json.dumps(scoop.to_json()))
    again = TaskAutomaton.from_json(data)
    assert again.to_json() == scoop.to_json()
    assert set(data) >= {"states", "initial", "transitions", "mode_transitions"}


def test_dot_mentions_every_state_and_edge(scoop: TaskAutomaton) -> None:
    dot = scoop.to_dot()
    assert dot.startswith('digraph "soup-scooping"')
    for s in scoop.states:
        assert f"s{s.id} [label=" in dot
    pairs = {(t.source, t.target) for t in scoop.transitions}
    assert dot.count(" -> s") == len(pairs) + len(scoop.initial)


def test_dot_parses_as_graphviz(scoop: TaskAutomaton) -> None:
    """An independent DOT parser (pydot) reads our output with every state and edge."""
    import warnings

    with warnings.catch_warnings():  # pydot still uses pyparsing's deprecated camelCase API
        warnings.simplefilter("ignore", DeprecationWarning)
        import pydot

        graphs = pydot.graph_from_dot_data(scoop.to_dot())
    assert graphs is not None and len(graphs) == 1
    names = {n.get_name() for n in graphs[0].get_nodes()}
    assert {f"s{s.id}" for s in scoop.states} <= names
    edges = {(e.get_source(), e.get_destination()) for e in graphs[0].get_edges()}
    assert {(f"s{t.source}", f"s{t.target}") for t in scoop.transitions} <= edges


def test_unrealizable_spec_has_no_automaton(specs_dir: Path) -> None:
    with pytest.raises(UnrealizableError, match="unrealizable"):
        synthesize(load_spec(specs_dir / "scoop-unrealizable.toml"))


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("cooking-cc", [["d", "w"], ["w", "y"], ["y", "d"], ["y", "w"]]),
        ("inspection", [["a", "b"], ["b", "a"]]),
        ("color-tracing-a", None),
    ],
)
def test_other_task_automata(specs_dir: Path, name: str, expected: list[list[str]] | None
                             ) -> None:
    aut = synthesize(load_spec(specs_dir / f"{name}.toml"))
    changes = [p for p in aut.mode_transitions() if p[0] != p[1]]
    if expected is not None:
        assert changes == expected
    else:  # (a): every exit into the dark region re-enters at yellow
        assert ["d1", "y"] in changes
        assert all(b == "y" for a, b in changes if a == "d1")
