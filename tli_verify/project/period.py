"""The control period: one rule, one default, one name.

A *control period* ``dt`` (seconds, an exact rational) is the step at which a policy runs,
the step the learner's sampled-data constraint is imposed at, and the step a certificate's
conditions (paper eq. 5, discretised: ``(I + dt A_k)^T P (I + dt A_k) - P < 0``) are proved at.
Every command and API call settles it the same way (:func:`control_period`):

1. the period given explicitly (``--dt``, ``--control-dt``, ``dt=``, ``control_dt=``);
2. else the ``dt`` of the task the spec names (a task file without ``dt`` has
   :data:`~tli_verify.defaults.DEFAULT_DT`);
3. else :data:`~tli_verify.defaults.DEFAULT_DT` (1/100 s).

A certificate at ``dt`` covers every faster loop: with ``M = A^T P + P A`` and
``N = A^T P A`` (positive semidefinite), ``(I + s A)^T P (I + s A) - P = s (M + s N)`` and
``M + s N <= M + dt N < 0`` for ``0 < s <= dt``. So the one default is the slower, stronger
one (a 1 kHz torque loop running a DS certified at 100 Hz is covered).
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

from tli_verify.defaults import DEFAULT_DT
from tli_verify.logic.spec import load_spec
from tli_verify.tasks.project import spec_task

__all__ = ["control_period", "task_period"]


def task_period(spec: str | os.PathLike[str] | None) -> Fraction | None:
    """The control period of the task a spec file names (None: no spec, or it names none).

    Raises
    ------
    SpecError, TaskError
        (exit 2) The spec or its task does not load.
    """
    if spec is None:
        return None

    task = spec_task(load_spec(spec), Path(spec))
    return None if task is None else Fraction(repr(task.dt))


def control_period(explicit: Fraction | float | None,
                   spec: str | os.PathLike[str] | None) -> Fraction:
    """Settle the control period: the explicit one, else the spec's task's, else the default.

    Parameters
    ----------
    explicit : Fraction or float, optional
        A period the user gave (a float is read by its shortest repr: ``0.01`` is 1/100).
    spec : path-like, optional
        The spec whose task may name a period.

    Returns
    -------
    Fraction
        Positive, exact.
    """
    if explicit is not None:
        return explicit if isinstance(explicit, Fraction) else Fraction(repr(float(explicit)))
    named = task_period(spec)
    return named if named is not None else DEFAULT_DT
