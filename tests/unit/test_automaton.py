"""Task automata: the paper's Fig. 3(a), determinism, Mealy stepping, file formats."""

from __future__ import annotations

import itertools
import json
import re
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.cli import main
from tli_verify.errors import SpecError, UnrealizableError
from tli_verify.logic.automaton import MAX_AUTOMATON_EDGES, AssumptionViolation, TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.escape import dot_string, dot_unescape, markdown_text, markdown_url
from tli_verify.logic.spec import load_spec, parse_spec

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
        assert json.dumps(a.to_dict(), sort_keys=True) == json.dumps(b.to_dict(), sort_keys=True)
        assert a.to_dot() == b.to_dot()


def test_json_round_trip(scoop: TaskAutomaton) -> None:
    data = json.loads(json.dumps(scoop.to_dict()))
    again = TaskAutomaton.from_dict(data)
    assert again.to_dict() == scoop.to_dict()
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


# --- hostile specs: many free inputs --------------------------------------------------------------

def _free_spec(n: int, *, name: str = "free") -> str:
    inputs = ", ".join(f'"x{i}"' for i in range(n))
    return (f'name = "{name}"\ninputs = [{inputs}]\noutputs = ["a", "b"]\n'
            '[guarantee]\ninit = "a & !b"\n'
            'safety = ["G(a -> X b)", "G(b -> X a)", "G(!(a & b))"]\nliveness = ["GF a"]\n')


@pytest.mark.parametrize("n", [4, 12, 200])
def test_free_inputs_give_one_cube_per_edge(n: int) -> None:
    """Unconstrained inputs that the strategy never reads multiply neither states nor edges."""
    aut = synthesize(parse_spec(_free_spec(n)))
    assert aut.free_inputs == tuple(f"x{i}" for i in range(n))
    assert len(aut.states) == 2 and len(aut.transitions) == 2
    assert all(t.sensors == () and t.off == () for t in aut.transitions)  # "any reading"
    state = aut.initial_state({f"x{i}": i % 3 == 0 for i in range(n)})
    modes = []
    for k in range(4):
        state, mode = aut.next_mode(state, [f"x{i}" for i in range(k, n, 5)])
        modes.append(mode)
    assert modes == ["b", "a", "b", "a"]
    again = TaskAutomaton.from_dict(json.loads(json.dumps(aut.to_dict())))
    assert again.to_dict() == aut.to_dict()


def test_cubes_agree_with_every_valuation() -> None:
    """A strategy that reads two of six inputs: each valuation matches exactly one cube, and
    the mode follows the spec (b after x0 & !x1, else a)."""
    text = ('inputs = ["x0", "x1", "x2", "x3", "x4", "x5"]\noutputs = ["a", "b"]\n'
            '[guarantee]\nsafety = ["G(X b <-> (X x0 & !X x1))", "G(X a <-> !X b)"]\n')
    aut = synthesize(parse_spec(text))
    assert set(aut.free_inputs) == {"x0", "x1", "x2", "x3", "x4", "x5"}
    for state in range(len(aut.states)):
        for bits in itertools.product([False, True], repeat=6):
            reading = frozenset(f"x{i}" for i in range(6) if bits[i])
            hits = [t for t in aut.transitions if t.source == state and t.matches(reading)]
            assert len(hits) == 1
            want = "b" if bits[0] and not bits[1] else "a"
            assert aut.states[hits[0].target].mode == want
    assert len(aut.transitions) < len(aut.states) * 2 ** 6


def test_too_large_automaton_is_refused_with_the_limit(tmp_path: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    """Parity of 30 next inputs needs 2^29 cubes per edge: refused, naming the limit."""
    n = 30
    parity = " ^ ".join(f"X x{i}" for i in range(n))
    inputs = ", ".join(f'"x{i}"' for i in range(n))
    path = tmp_path / "parity.toml"
    path.write_text(f'inputs = [{inputs}]\noutputs = ["a"]\n[guarantee]\n'
                    f'safety = ["G(X a <-> ({parity}))"]\n')
    assert main(["spec", "automaton", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {path}")
    assert f"more than {MAX_AUTOMATON_EDGES} edges (the limit)" in err


def test_too_many_states_are_refused_with_the_limit() -> None:
    """A strategy that must remember the parity of 12 current inputs: refused, not 90 s."""
    n = 12
    parity = " ^ ".join(f"x{i}" for i in range(n))
    inputs = ", ".join(f'"x{i}"' for i in range(n))
    spec = parse_spec(f'inputs = [{inputs}]\noutputs = ["a"]\n[guarantee]\n'
                      f'safety = ["G(X a <-> ({parity}))"]\n', path="lag.toml")
    with pytest.raises(SpecError, match=r"lag.toml: the task automaton has more than \d+ "):
        synthesize(spec)


def test_old_json_without_cubes_reads_full_readings(scoop: TaskAutomaton) -> None:
    data = scoop.to_dict()
    for t in data["transitions"]:
        del t["off"]
    del data["free_inputs"]
    again = TaskAutomaton.from_dict(data)
    assert again.to_dict() == scoop.to_dict()


# --- hostile specs: output injection --------------------------------------------------------------

NAMES = st.text(st.characters(blacklist_categories=("Cc", "Cs")), min_size=1, max_size=40)


def _parse_dot(text: str) -> Any:
    import warnings

    with warnings.catch_warnings():  # pydot still uses pyparsing's deprecated camelCase API
        warnings.simplefilter("ignore", DeprecationWarning)
        import pydot

        graphs = pydot.graph_from_dot_data(text)
    assert graphs is not None and len(graphs) == 1
    return graphs[0]


@settings(max_examples=60, deadline=None)
@given(name=NAMES | st.sampled_from(['ti"ny"; evil [label=x]', "a\\", '\\"', "}", "\\N"]))
def test_hostile_spec_names_stay_inside_the_dot_string(name: str) -> None:
    toml_name = json.dumps(name, ensure_ascii=False)  # a TOML basic string here
    aut = synthesize(parse_spec(_free_spec(1, name="x").replace('"x"', toml_name, 1)))
    assert aut.name == name
    graph = _parse_dot(aut.to_dot())
    assert dot_unescape(graph.get_name()) == name
    nodes = {n.get_name(): n for n in graph.get_nodes()}
    for s in aut.states:
        label = dot_unescape(nodes[f"s{s.id}"].get_attributes()["label"])
        assert label == f"{s.mode}\n#{s.id} [{','.join(s.inputs) or '-'}]"
    assert len(graph.get_edges()) == len({(t.source, t.target) for t in aut.transitions}) + 1
    assert json.loads(json.dumps(aut.to_dict()))["name"] == name


@settings(max_examples=100, deadline=None)
@given(text=st.text(max_size=40))
def test_dot_string_round_trips_and_is_one_token(text: str) -> None:
    quoted = dot_string(text)
    assert "\n" not in quoted
    printable = "".join(ch for ch in text.replace("\r\n", "\n").replace("\r", "\n")
                        if ch == "\n" or not (ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0))
    assert dot_unescape(quoted) == printable
    graph = _parse_dot(f"digraph {quoted} {{ n [label={quoted}]; }}")
    assert dot_unescape(graph.get_name()) == printable


@settings(max_examples=100, deadline=None)
@given(cells=st.lists(st.text(max_size=20), min_size=1, max_size=4))
def test_markdown_cells_cannot_break_the_table(cells: list[str]) -> None:
    """An escaped cell has no line break and no unescaped ``|``, ``[``, ``<``, ``*`` etc."""
    row = "| " + " | ".join(markdown_text(c) for c in cells) + " |"
    assert "\n" not in row and "\r" not in row
    unescaped = re.sub(r"\\.", "", row)
    assert unescaped.count("|") == len(cells) + 1
    assert not set(unescaped) & set("`*_[]<>&!#~\\")


@settings(max_examples=100, deadline=None)
@given(path=st.text(max_size=30))
def test_markdown_links_cannot_break_out(path: str) -> None:
    """The figure link of the single-mode report: the target has no space, parenthesis or
    bracket left, the alt text no unescaped bracket."""
    link = f"![{markdown_text(path)}]({markdown_url(path)})"
    # the alt text ends at the first unescaped "]" (an escaped one, e.g. "\\](", does not)
    end = re.match(r"(?:\\.|[^\\\]])*", link[2:])
    assert end is not None
    alt, rest = link[2:2 + end.end()], link[2 + end.end():]
    assert rest.startswith("](")
    target = rest[2:]
    assert not set(target[:-1]) & set(" ()[]<>\n\r\"'")
    assert not set(re.sub(r"\\.", "", alt)) & set("[]")
    assert unquote(target[:-1]) == path
