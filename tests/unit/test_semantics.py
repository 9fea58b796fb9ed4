"""The two readings of safety at time 0 (``semantics = "tli" | "textbook"``,
docs/explanation/logic.md, "Two readings of safety at time 0")."""

from __future__ import annotations

import contextlib
import io

import pytest

from tests.support.omega_oracle import omega_realizable
from tli_verify.errors import SpecError
from tli_verify.logic.check import check_spec
from tli_verify.logic.gr1 import build_game, solve
from tli_verify.logic.infer import spec_to_toml
from tli_verify.logic.spec import parse_spec

SMALLEST = """\
inputs = ["x"]
outputs = ["y"]
[assume]
safety = ["G(!y)"]
[guarantee]
init = "y"
safety = ["G(!y)"]
"""


def _omega(spec: object, semantics: str) -> bool:
    with contextlib.redirect_stdout(io.StringIO()):
        return omega_realizable(spec, semantics=semantics)  # type: ignore[arg-type]


def test_smallest_example_differs_and_each_reading_agrees_with_omega() -> None:
    """The system starts in ``y``, which breaks its own ``G(!y)`` at time 0 and leaves the
    environment no legal move (``G(!y)`` as an assumption). Ours: the guarantee holds at time
    0 too, so no initial state is legal: unrealizable. Textbook: ``G(!y)`` constrains only
    transitions; the environment cannot make the first one, so the system wins."""
    ours = parse_spec(SMALLEST, path="s.toml")
    textbook = parse_spec('semantics = "textbook"\n' + SMALLEST, path="s.toml")
    assert ours.semantics == "tli" and textbook.semantics == "textbook"
    assert check_spec(ours).realizable is False
    assert check_spec(textbook).realizable is True
    assert _omega(ours, "tli") is False
    assert _omega(textbook, "textbook") is True
    # the option of the game construction overrides the spec's own setting
    assert solve(build_game(ours, semantics="textbook")).realizable is True
    assert solve(build_game(textbook, semantics="tli")).realizable is False


def test_semantics_is_validated_and_round_trips() -> None:
    with pytest.raises(SpecError, match=r"s.toml:1: 'semantics' must be one of 'tli', "):
        parse_spec('semantics = "spectra"\n' + SMALLEST, path="s.toml")
    spec = parse_spec('semantics = "textbook"\n' + SMALLEST)
    assert parse_spec(spec_to_toml(spec)).semantics == "textbook"
    assert "semantics" not in spec_to_toml(parse_spec(SMALLEST))
    with pytest.raises(ValueError, match="semantics"):
        build_game(spec, semantics="slugs")


def test_textbook_check_reports_its_reading() -> None:
    result = check_spec(parse_spec('semantics = "textbook"\n' + SMALLEST))
    assert result.to_dict()["semantics"] == "textbook"
