"""Every number-valued option of ``tli`` has physical bounds, documented and checked when the
command line is parsed, before any work (issue 32, part 4: ``tli learn --control-dt 1e-320``
was accepted).

The options are found by walking the parser (an option whose type takes ``0.5`` and is not a
path), so a new float option without bounds fails here too.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from tli_verify.cli import build_parser

REPO = Path(__file__).resolve().parents[2]
HOSTILE = ["1e-320", "5e-324", "-5e-324", "1e300", "1.8e308", "nan", "inf", "-inf", "-1",
           "1e-30", "0x1p-1074"]


def _commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    yield prefix, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*prefix, name))


def _accepts(kind, text: str) -> bool:
    try:
        kind(text)
    except (argparse.ArgumentTypeError, ValueError, TypeError, ArithmeticError):
        return False
    return True


def _float_options() -> list[tuple[str, argparse.Action]]:
    out = []
    for prefix, parser in _commands(build_parser()):
        for action in parser._actions:
            kind = action.type
            if not action.option_strings or kind is None or kind in (Path, str):
                continue
            if getattr(kind, "__name__", "") in ("output_path",):
                continue
            if _accepts(kind, "0.5") or _accepts(kind, "1.5") or _accepts(kind, "2.5"):
                out.append((" ".join(prefix) + " " + action.option_strings[-1], action))
    return out


FLOAT_OPTIONS = _float_options()
CASES = [(name, action, value) for name, action in FLOAT_OPTIONS for value in HOSTILE]


def test_the_float_options_are_found() -> None:
    names = {n for n, _ in FLOAT_OPTIONS}
    assert {"learn --control-dt", "learn --eps", "learn --rate", "sim franka --duration",
            "evidence --duration", "certify --dt"} <= names, names


@pytest.mark.parametrize(("name", "action", "value"), CASES,
                         ids=[f"{n}={v}" for n, _, v in CASES])
def test_a_hostile_number_is_refused_by_the_parser(name: str, action: argparse.Action,
                                                   value: str) -> None:
    assert not _accepts(action.type, value), f"{name} {value} accepted"


@pytest.mark.parametrize(("name", "action"), FLOAT_OPTIONS, ids=[n for n, _ in FLOAT_OPTIONS])
def test_the_bounds_are_documented(name: str, action: argparse.Action) -> None:
    """The limits page lists the option, and its help states the range."""
    limits = (REPO / "docs" / "reference" / "limits.md").read_text()
    command, option = name.rsplit(" ", 1)
    row = next((line for line in limits.splitlines()
                if line.startswith("| ") and f"`tli {command} {option}`" in line), None)
    assert row is not None, f"docs/reference/limits.md: no row for tli {name}"
    help_text = action.help or ""
    assert re.search(r"\d(e-?\d+)? to \d", help_text) or "up to" in help_text or \
        option == "--dt", f"{name}: the help does not state its range: {help_text!r}"


def test_the_control_period_is_refused_before_any_work(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    """The user's case: exit 2, one line naming the option, no output file, even with a
    demonstration that does not exist (nothing was read)."""
    from tests.support.cli import run

    code, _, err = run(capsys, "learn", str(tmp_path / "missing.csv"), "-o",
                       str(tmp_path / "m.json"), "--control-dt", "1e-320")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("error:") and "--control-dt" in err and "1e-06" in err
    assert not (tmp_path / "m.json").exists()
