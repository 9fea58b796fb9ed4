"""Checking a spec end to end: parse, build the game, decide realizability, diagnose.

This is the logic layer's public entry point for the CLI (``tli spec check``), the demo and
the deployment gate (:func:`check_spec_file`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tli_verify.arguments import check_path
from tli_verify.errors import SpecError, UnrealizableError, bad_type
from tli_verify.logic.automaton import TaskAutomaton, extract_automaton
from tli_verify.logic.diagnose import Diagnosis, diagnose
from tli_verify.logic.foreign import FORMATS, import_spec_file
from tli_verify.logic.gr1 import build_game, solve
from tli_verify.logic.sanity import (
    Core,
    Hint,
    WellSeparation,
    unrealizable_core,
    vacuity_hints,
    well_separation,
)
from tli_verify.logic.spec import GR1Spec, load_spec, parse_spec

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
        Things a realizable verdict should not hide (vacuous assumptions, a spec that is not
        well-separated).
    seconds : float
        Wall time of the check (parse excluded).
    well_separation : WellSeparation
        Whether the system can force a violation of the assumptions (Maoz and Ringert 2016).
    core : Core or None
        A minimal unrealizable set of guarantees (unrealizable specs, when asked for).
    hints : tuple of Hint
        Formulas that do not affect the verdict (when asked for).
    """

    spec: GR1Spec
    realizable: bool
    diagnosis: Diagnosis | None
    warnings: tuple[str, ...]
    seconds: float
    well_separation: WellSeparation
    core: Core | None = None
    hints: tuple[Hint, ...] = ()

    @property
    def as_expected(self) -> bool:
        """The verdict matches the spec's ``expect`` (realizable specs must also be
        well-separated unless they expect ``"not-well-separated"``)."""
        if self.realizable != self.expected_realizable:
            return False
        if self.realizable:
            return self.well_separated == (self.spec.expect != "not-well-separated")
        return True

    @property
    def well_separated(self) -> bool:
        """Shorthand for ``well_separation.well_separated``."""
        return self.well_separation.well_separated

    @property
    def expected_realizable(self) -> bool:
        """The verdict the spec file declares (``expect = ...``; realizable by default)."""
        return self.spec.expect_realizable

    def to_dict(self) -> dict[str, Any]:
        """The ``tli spec check --json`` record."""
        return {
            "file": self.spec.path,
            "name": self.spec.name,
            "realizable": self.realizable,
            "expected_realizable": self.expected_realizable,
            "expect": self.spec.expect,
            "semantics": self.spec.semantics,
            "as_expected": self.as_expected,
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_dict(),
            "warnings": list(self.warnings),
            "seconds": round(self.seconds, 6),
            "well_separated": self.well_separated,
            "well_separation": self.well_separation.to_dict(),
            "core": None if self.core is None else self.core.to_dict(),
            "hints": [h.to_dict() for h in self.hints],
        }


def _spec_arg(spec: Any) -> GR1Spec:
    """The ``spec`` argument of :func:`check_spec` and :func:`synthesize`: a GR1Spec, or a
    spec file (loaded as :func:`check_spec_file` would)."""
    if isinstance(spec, GR1Spec):
        return spec
    if isinstance(spec, str | os.PathLike) and not isinstance(spec, bool):

        path = check_path(spec, "spec", error=SpecError)

        if path.suffix in FORMATS:
            return parse_spec(import_spec_file(path), path=f"{path} (imported)",
                              default_name=path.stem)
        return load_spec(path)
    raise bad_type(SpecError, f"spec: expected a GR1Spec (load_spec) or a spec file, got "
                   f"{type(spec).__name__}")


def check_spec(spec: GR1Spec | str | os.PathLike[str], *, core: bool = False,
               hints: bool = False) -> SpecCheck:
    """Decide realizability of ``spec``, diagnose it when unrealizable, check well-separation.

    Parameters
    ----------
    spec : GR1Spec
    core : bool
        Also compute a minimal unrealizable core of guarantees (unrealizable specs).
    hints : bool
        Also compute vacuity hints (formulas that do not affect the verdict).
    """
    spec = _spec_arg(spec)
    start = time.perf_counter()
    game = build_game(spec)
    solution = solve(game, keep_iterates=False, exact=False)
    diagnosis = None if solution.realizable else diagnose(game)
    warnings: list[str] = []
    bdd = game.manager
    if game.theta_e == bdd.false:
        # theta_e includes the safety assumptions at time 0 (gr1 module docstring).
        warnings.append("no initial sensor reading satisfies the assumptions' initial "
                        "condition and lets their safety formulas hold from time 0 on: every "
                        "play satisfies the spec vacuously")
    separation = well_separation(game)
    if solution.realizable and not separation.well_separated:
        warnings.append(f"not well-separated: the system can force a violation of an "
                        f"environment {separation.kind} assumption, so this realizable verdict "
                        "may be won vacuously")
    the_core = unrealizable_core(spec) if core and not solution.realizable else None
    the_hints = tuple(vacuity_hints(spec, realizable=solution.realizable, core=the_core)) \
        if hints else ()
    return SpecCheck(spec=spec, realizable=solution.realizable, diagnosis=diagnosis,
                     warnings=tuple(warnings), seconds=time.perf_counter() - start,
                     well_separation=separation, core=the_core, hints=the_hints)


def check_spec_file(path: str | os.PathLike[str], *, core: bool = False, hints: bool = False
                    ) -> SpecCheck:
    """Load and check a spec file (raises :class:`~tli_verify.errors.SpecError` on bad input).

    A ``.spectra``, ``.structuredslugs`` or ``.slugsin`` file is read through
    :func:`~tli_verify.logic.foreign.import_spec_file` (in the tool's own, textbook reading
    of safety at time 0), as ``tli spec import`` would translate it."""
    if Path(path).suffix in FORMATS:
        spec = parse_spec(import_spec_file(Path(path)), path=f"{path} (imported)",
                          default_name=Path(path).stem)
        return check_spec(spec, core=core, hints=hints)
    return check_spec(load_spec(path), core=core, hints=hints)


def synthesize(spec: GR1Spec | str | os.PathLike[str]) -> TaskAutomaton:
    """The task automaton of a realizable spec (paper Sec. 4.2, "Task-Level Reactivity in
    LTL": the GR(1) game's winning strategy as a finite-state machine).

    Parameters
    ----------
    spec : GR1Spec
        A spec from :func:`~tli_verify.logic.spec.load_spec` or
        :func:`~tli_verify.logic.spec.parse_spec`.

    Returns
    -------
    TaskAutomaton

    Raises
    ------
    UnrealizableError
        With the diagnosis summary, when the spec is unrealizable.
    """
    spec = _spec_arg(spec)
    game = build_game(spec)
    solution = solve(game)
    if not solution.realizable:
        d = diagnose(game)
        raise UnrealizableError(f"{spec.path or spec.name}: unrealizable ({d.kind}): {d.summary}")
    return extract_automaton(solution)
