"""The GR(1) solver and the unrealizability diagnosis on games with known answers."""

from __future__ import annotations

from pathlib import Path

import pytest

from tli_verify.logic.check import check_spec, check_spec_file
from tli_verify.logic.gr1 import build_game, solve
from tli_verify.logic.spec import parse_spec


def _spec(body: str) -> str:
    return 'inputs = ["x"]\noutputs = ["y"]\n' + body


@pytest.mark.parametrize(
    ("body", "realizable"),
    [
        # The system copies the input: always possible (Mealy: it sees x' first).
        ('[guarantee]\nsafety = ["G(X y <-> X x)"]\nliveness = ["GF y"]\n'
         '[assume]\nliveness = ["GF x"]', True),
        # Without environment fairness, GF y cannot follow GF x.
        ('[guarantee]\nsafety = ["G(X y <-> X x)"]\nliveness = ["GF y"]', False),
        # Moore-style lag is fine too.
        ('[guarantee]\nsafety = ["G(X y <-> x)"]\nliveness = ["GF y"]\n'
         '[assume]\nliveness = ["GF x"]', True),
        # Contradictory initial condition.
        ('[guarantee]\ninit = "y & !y"', False),
        # Environment safety that cannot be met makes the spec vacuously realizable.
        ('[assume]\nsafety = ["G(X x & X !x)"]\n[guarantee]\nliveness = ["GF(y & !y)"]', True),
        # A system safety that the environment can break.
        ('[guarantee]\nsafety = ["G(X x)"]', False),
        # The same safety, but the environment promised it.
        ('[assume]\nsafety = ["G(X x)"]\n[guarantee]\nsafety = ["G(X x)"]', True),
    ],
)
def test_known_games(body: str, realizable: bool) -> None:
    result = check_spec(parse_spec(_spec(body)))
    assert result.realizable is realizable
    assert (result.diagnosis is None) is realizable


def test_shipped_specs_match_their_expectation(specs_dir: Path) -> None:
    for path in sorted(specs_dir.glob("*.toml")):
        result = check_spec_file(path)
        assert result.as_expected, path


def test_vacuous_environment_is_warned() -> None:
    result = check_spec(parse_spec(_spec('[assume]\ninit = "x & !x"')))
    assert result.realizable
    assert any("vacuously" in w for w in result.warnings)


def test_diagnosis_initial() -> None:
    d = check_spec(parse_spec(_spec('[guarantee]\ninit = "y & !y"'))).diagnosis
    assert d is not None and d.kind == "initial"
    assert any("guarantee.init[0]" in f for f in d.formulas)


def test_diagnosis_safety_on_scoop_as_written(specs_dir: Path) -> None:
    d = check_spec_file(specs_dir / "scoop-unrealizable.toml").diagnosis
    assert d is not None and d.kind == "safety"
    assert any("G(a -> X(a | b))" in f for f in d.formulas)
    # The witness starts in the initial state and ends with a sensor jump the guarantees forbid.
    assert d.witness[0].outputs == ("a",)
    assert d.final_inputs == ("t",)
    assert d.hint is not None and "environment safety assumption" in d.hint


def test_diagnosis_liveness_suggests_fairness(specs_dir: Path) -> None:
    text = (specs_dir / "scoop.toml").read_text()
    for fair in ('"GF(!a | r)",', '"GF(!b | s)",', '"GF(!c | t)",'):
        text = text.replace(fair, "")
    d = check_spec(parse_spec(text, path="scoop-nofair.toml")).diagnosis
    assert d is not None and d.kind == "liveness"
    assert any("GF(d | p)" in f for f in d.formulas)
    assert d.loop_start is not None and d.witness
    # The lasso never meets the goal: d is never the running mode and p never set.
    assert all("d" not in s.outputs and "p" not in s.outputs for s in d.witness[d.loop_start:])
    assert d.hint is not None and "fairness" in d.hint


def test_solution_rings_cover_winning_set(specs_dir: Path) -> None:
    from tli_verify.logic.spec import load_spec

    sol = solve(build_game(load_spec(specs_dir / "scoop.toml")))
    assert sol.realizable
    for rings in sol.rings:
        assert rings[-1] | sol.winning == rings[-1]
