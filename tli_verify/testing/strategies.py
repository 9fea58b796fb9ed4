"""Hypothesis strategies for the perturbation sequences of any task, in any dimension.

:func:`cases` draws :class:`~tli_verify.verify.strategies.Case` objects (a start and a finite
perturbation sequence) with the defaults of a task -- its nominal start (or random starts in
the regions the spec's initial assumption allows), its perturbation window, count and
magnitude bound -- by :func:`tli_verify.verify.strategies.cases`, so a case shrinks toward
fewer, smaller, later perturbations, as ``tli verify``'s counterexamples do.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from tli_verify.errors import CampaignError
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES
from tli_verify.tasks.registry import find_task
from tli_verify.testing.projects import Project, default_project
from tli_verify.verify.simulate import start_regions
from tli_verify.verify.strategies import LEVELS
from tli_verify.verify.strategies import cases as _cases

if TYPE_CHECKING:  # pragma: no cover - types only
    from hypothesis.strategies import SearchStrategy

    from tli_verify.verify.strategies import Case

__all__ = ["MARK", "cases", "is_tli_strategy"]

MARK = "_tli_verify_cases"
"""The attribute that marks a strategy built by :func:`cases`: the pytest plugin gives the
``@given`` tests that draw from one the settings of a closed-loop test (no deadline,
``--tli-examples``, ``--tli-seed``). An attribute, not a registry: it survives a re-import of
this module (pytest's in-process runs drop the modules they imported)."""


def is_tli_strategy(strategy: object) -> bool:
    """Whether ``strategy`` was built by :func:`cases`."""
    return getattr(strategy, MARK, False) is True


def cases(project_or_task: Project | Any | str | os.PathLike[str] | None = None, *,
          max_pushes: int | None = None, window: int | None = None,
          levels: Sequence[str] = LEVELS, start: Sequence[float] | None = None,
          random_starts: bool | None = None, max_magnitude: float | None = None,
          min_pushes: int = 0) -> SearchStrategy[Case]:
    """Cases of a project's (or a task's) closed loop: a start and finitely many perturbations.

    Parameters
    ----------
    project_or_task : Project, Task, str or path-like, optional
        A :class:`~tli_verify.testing.Project` (its task, and for random starts its spec's
        initial assumption); a task, task name or task file; default: the plugin's project
        (``--tli-project``, else the working directory), resolved when the first case is drawn.
    max_pushes : int, optional
        At most this many perturbations (default: the task's ``perturbations.max_pushes``).
    window : int, optional
        Perturbations happen in steps ``1..window`` (default: the task's); a check's step
        budget covers the last one whatever the window.
    levels : sequence of str, optional
        Perturbation levels, a subset of ``("free", "motion", "task")`` (default: all).
    start : sequence of float, optional
        A fixed start (default: the task's first nominal start).
    random_starts : bool, optional
        Draw the start too (default: when the task has no nominal start and ``start`` is not
        given): in the task's ``starts.region``, else in the regions whose first reading the
        spec allows (a project), else anywhere in the workspace (a task alone).
    max_magnitude : float, optional
        Largest displacement (default: the task's bound, else the workspace size).
    min_pushes : int, optional
        At least this many perturbations.

    Returns
    -------
    SearchStrategy of Case
        Shrinks toward fewer, smaller, later perturbations
        (:mod:`tli_verify.verify.strategies`).

    Raises
    ------
    CampaignError
        (a :class:`ValueError`) A bad option: a level that is not one, a window outside
        ``[1, MAX_CAMPAIGN_STEPS]``, more pushes than ``MAX_PUSHES`` (a saved case must
        replay), a start of the wrong dimension or outside the workspace, a fixed start with
        ``random_starts=True``.

    Examples
    --------
    >>> from hypothesis import given
    >>> from tli_verify.testing import assert_satisfies, cases, project
    >>> drawer = project("path/to/project")                    # doctest: +SKIP
    >>> @given(cases(drawer, max_pushes=2, levels=("task",)))  # doctest: +SKIP
    ... def test_pushes(case):
    ...     assert_satisfies(drawer, case)
    """
    options: dict[str, Any] = {
        "max_pushes": max_pushes, "window": window, "levels": tuple(levels), "start": start,
        "random_starts": random_starts, "max_magnitude": max_magnitude,
        "min_pushes": min_pushes}
    if project_or_task is None:
        from hypothesis import strategies as st

        out: SearchStrategy[Case] = st.deferred(lambda: _build(default_project(), options))
    else:
        out = _build(project_or_task, options)
    setattr(out, MARK, True)
    return out


def _build(source: Any, o: dict[str, Any]) -> SearchStrategy[Case]:
    import numpy as np

    proj = source if isinstance(source, Project) else None
    if proj is not None:
        task = proj.task
    elif isinstance(source, str | os.PathLike):

        task = find_task(source)
    elif hasattr(source, "perturbations") and hasattr(source, "starts"):
        task = source
    else:
        raise CampaignError(f"cases: expected a Project, a task, a task name or a task file, "
                            f"got {type(source).__name__}")
    perturb = task.perturbations
    max_pushes = perturb.max_pushes if o["max_pushes"] is None else o["max_pushes"]
    window = perturb.window if o["window"] is None else o["window"]
    # what a case file can hold (tli replay refuses more): a saved case must replay
    for name, value, lo, hi in (("max_pushes", max_pushes, 0, MAX_PUSHES),
                                ("min_pushes", o["min_pushes"], 0, max_pushes),
                                ("window", window, 1, MAX_CAMPAIGN_STEPS)):
        if not isinstance(value, int) or isinstance(value, bool) or not lo <= value <= hi:
            raise CampaignError(f"cases: {name}: expected an integer in [{lo}, {hi}], got "
                                f"{value!r}")
    levels = o["levels"]
    if not levels or any(lv not in LEVELS for lv in levels) or len(set(levels)) != len(levels):
        raise CampaignError(f"cases: levels: expected a non-empty subset of "
                            f"{', '.join(LEVELS)}, got {list(levels)}")
    start = o["start"]
    random_starts = o["random_starts"]
    if random_starts and start is not None:
        raise CampaignError("cases: a fixed start and random_starts=True: choose one")
    if random_starts is None:
        random_starts = start is None and not task.starts.nominal
    regions: tuple[str, ...] | None = None
    if random_starts:
        if proj is not None:

            regions = start_regions(task, proj.loaded.automaton)
        if task.starts.region is not None:
            regions = (task.starts.region,) if regions is None or \
                task.starts.region in regions else regions
    elif start is None:
        start = task.starts.nominal[0]
    if start is not None:
        if len(start) != task.dim:
            raise CampaignError(f"cases: start: expected {task.dim} coordinates (task "
                                f"{task.name!r}), got {len(start)}")
        start = tuple(float(v) for v in start)
        if not bool(task.in_workspace(np.asarray(start, dtype=np.float64)[None])[0]):
            raise CampaignError(f"cases: start {list(start)}: outside the workspace of task "
                                f"{task.name!r}")
    magnitude = perturb.max_magnitude if o["max_magnitude"] is None else o["max_magnitude"]
    if magnitude is not None and (isinstance(magnitude, bool) or not isinstance(
            magnitude, int | float) or not math.isfinite(magnitude) or magnitude < 0):
        raise CampaignError(f"cases: max_magnitude: expected a finite number >= 0, got "
                            f"{magnitude!r}")
    return _cases(task, start=start, max_pushes=max_pushes, window=window, levels=levels,
                  max_magnitude=magnitude, min_pushes=o["min_pushes"], start_regions=regions)
