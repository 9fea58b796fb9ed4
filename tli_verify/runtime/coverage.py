"""Coverage: which certified DS the executive may run (paper eq. 6, Thm. 1's premises).

* :func:`check_coverage` -- the certificate re-checks exactly
  (:func:`tli_verify.certification.certificate.check_certificate`), names this model file, and
  the DS in memory are the certified file's; returns the certified control period;
* :func:`plan_states` -- the planner's choice (:meth:`TaskAutomaton.planned_keys`) in every
  automaton state, checked to name a DS the model has (the gate runs the same check).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from fractions import Fraction
from typing import Any

import numpy as np

from tli_verify.defaults import DEFAULT_DT
from tli_verify.errors import CertificateError, ModelError
from tli_verify.io import same_file
from tli_verify.logic.automaton import PlannedStep, TaskAutomaton
from tli_verify.model.serialize import load_model
from tli_verify.model.types import Model

__all__ = [
    "check_coverage",
    "plan_states",
]


def plan_states(automaton: TaskAutomaton, model: Model, goal_modes: Sequence[str] | None,
                where: str) -> dict[int, PlannedStep]:
    """The planner's choice in every state (:meth:`TaskAutomaton.planned_keys`), checked.

    Raises
    ------
    ModelError
        A mode the automaton runs has no DS, or a state has no DS the planner can run (the
        deployment gate's ``modes`` check, with the same planner).
    """
    run_modes = sorted({s.mode for s in automaton.states})
    missing = [m for m in run_modes if not model.keys_of(m)]
    if missing:
        raise ModelError(f"{where}: no DS for mode {missing[0]!r} the automaton "
                         f"{automaton.name!r} runs")
    steps = automaton.planned_keys({k: (mm.mode, mm.next_mode) for k, mm in model.modes.items()},
                                   goal_modes)
    for st in steps:
        if st.key is None:
            towards = ", ".join(st.moves) or "none: it only stays in the mode"
            raise ModelError(f"{where}: no DS to run in automaton state {st.state} (mode "
                             f"{st.mode!r}): no plain DS {st.mode!r} and no per-transition DS "
                             f"towards the modes it can move to ({towards})")
    return {st.state: st for st in steps}


def _same_ds(a: Any, b: Any) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f))
               for f in ("attractor", "priors", "means", "covs", "A", "P"))


def check_coverage(model: Model, certificate: str | os.PathLike[str]) -> Fraction:
    """Check that ``certificate`` covers ``model``, as the gate does; return its ``dt``.

    Parameters
    ----------
    model : Model
        Loaded from a file (``model.path``); cuts added in memory since are allowed.
    certificate : path-like

    Returns
    -------
    Fraction
        The certified control period.

    Raises
    ------
    CertificateError
        (exit 1) The certificate does not re-check, names another model file, or the DS in
        memory differ from the certified file's (a cut of the file missing, other numbers);
        (exit 2) the certificate file cannot be read.
    """
    from tli_verify.certification.certificate import check_certificate

    check = check_certificate(certificate)
    if not check.ok:
        raise CertificateError(f"{certificate}: refused: the certificate does not re-check: "
                               f"{check.problems[0]}")
    if model.path is None or check.model_path is None or \
            not same_file(model.path, check.model_path):
        raise CertificateError(f"{certificate}: refused: it covers {check.model_path}, not the "
                               f"model {model.path or '(not loaded from a file)'}")
    certified = load_model(model.path)
    if set(certified.modes) != set(model.modes):
        raise CertificateError(f"{certificate}: refused: the model in memory has DS "
                               f"{sorted(model.modes)}, the certified file "
                               f"{sorted(certified.modes)}")
    for key, mm in model.modes.items():
        ref = certified.modes[key]
        if not _same_ds(mm.ds, ref.ds):
            raise CertificateError(f"{certificate}: refused: DS {key!r} in memory differs from "
                                   f"the certified file {model.path}")
        have = {(tuple(c.normal.tolist()), tuple(c.point.tolist())) for c in mm.cuts}
        if any((tuple(c.normal.tolist()), tuple(c.point.tolist())) not in have
               for c in ref.cuts):
            raise CertificateError(f"{certificate}: refused: DS {key!r} in memory lacks a cut "
                                   f"of the certified file {model.path}")
    return Fraction(check.dt) if check.dt is not None else DEFAULT_DT
