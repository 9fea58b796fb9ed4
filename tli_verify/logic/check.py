"""Checking a spec end to end: parse, build the game, decide realizability, diagnose.

This is the logic layer's public entry point for the CLI (``tli spec check``), the demo and
the deployment gate (:func:`check_spec_file`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

from tli_verify.errors import UnrealizableError
from tli_verify.logic.automaton import TaskAutomaton, extract_automaton
from tli_verify.logic.diagnose import Diagnosis, diagnose
from tli_verify.logic.gr1 import build_game, solve
from tli_verify.logic.spec import GR1Spec, load_spec

__all__ = ["SpecCheck", "check_spec", "check_spec_file", "synthesize"]


@dataclass(frozen=True, slots=True)
class SpecCheck:
    """The verdict on one spec.

    Attributes
    ----------
    spec : GR1Spec
    realizable : bool
    diagnosis : Diagnosis or None
        Why not, when unrealizable.
    warnings : tuple of str
        Things a realizable verdict should not hide (e.g. vacuous assumptions).
    seconds : float
        Wall time of the check (parse excluded).
    """

    spec: GR1Spec
    realizable: bool
    diagnosis: Diagnosis | None
    warnings: tuple[str, ...]
    seconds: float

    @property
    def expected_realizable(self) -> bool:
        """The verdict the spec file declares (``expect = ...``; realizable by default)."""
        return self.spec.expect_realizable

    def to_json(self) -> dict[str, Any]:
        """The ``tli spec check --json`` record."""
        return {
            "file": self.spec.path,
            "name": self.spec.name,
            "realizable": self.realizable,
            "expected_realizable": self.expected_realizable,
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_json(),
            "warnings": list(self.warnings),
            "seconds": round(self.seconds, 6),
        }


def check_spec(spec: GR1Spec) -> SpecCheck:
    """Decide realizability of ``spec`` and diagnose it when unrealizable."""
    start = time.perf_counter()
    game = build_game(spec)
    solution = solve(game, keep_iterates=False)
    diagnosis = None if solution.realizable else diagnose(game)
    warnings: list[str] = []
    bdd = game.manager
    if game.theta_e == bdd.false:
        warnings.append("the assumptions' initial condition is unsatisfiable: every play "
                        "satisfies the spec vacuously")
    elif bdd.exist(list(game.inputs) + game.inputs_next + list(game.outputs),
                   game.theta_e & game.rho_e) == bdd.false:
        warnings.append("no environment move satisfies the safety assumptions from any "
                        "initial state: the spec holds vacuously")
    return SpecCheck(spec=spec, realizable=solution.realizable, diagnosis=diagnosis,
                     warnings=tuple(warnings), seconds=time.perf_counter() - start)


def check_spec_file(path: str | os.PathLike[str]) -> SpecCheck:
    """Load and check a spec file (raises :class:`~tli_verify.errors.SpecError` on bad input)."""
    return check_spec(load_spec(path))


def synthesize(spec: GR1Spec) -> TaskAutomaton:
    """The task automaton of a realizable spec.

    Raises
    ------
    UnrealizableError
        With the diagnosis summary, when the spec is unrealizable.
    """
    game = build_game(spec)
    solution = solve(game)
    if not solution.realizable:
        d = diagnose(game)
        raise UnrealizableError(f"{spec.path or spec.name}: unrealizable ({d.kind}): {d.summary}")
    return extract_automaton(solution)
