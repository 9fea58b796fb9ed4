"""The Fig. 7 picture of a case the Fig. 7 search found (:func:`plot_fig7`).

Three panels: the unmodulated run looping ``a -> b -> a ...`` until its budget, its last steps
zoomed on the loop at the soup's surface, and LTL-DS with the cut it added; the unperturbed run
from the same start is dashed grey. The case comes from
:func:`tli_verify.experiments.fig7.fig7_search`.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2, Fig. 7.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from tli_verify.errors import TliError
from tli_verify.experiments.fig7 import b_to_a_failures
from tli_verify.experiments.scoop_task import scoop_setup
from tli_verify.runtime.episodes import run_variant
from tli_verify.tasks.task import Task
from tli_verify.viz.episodes import plot_episodes

__all__ = [
    "plot_fig7",
]


def plot_fig7(task: Task, search: Mapping[str, Any],
              path: str | os.PathLike[str]) -> None:
    """Fig. 7-style picture of a case :func:`~tli_verify.experiments.fig7.fig7_search` found
    (PNG, atomic).

    Three panels (:func:`tli_verify.viz.episodes.plot_episodes`): the unmodulated run looping
    until its budget, its last 400 steps zoomed on the loop at the soup's surface, and LTL-DS
    with the cut it added (blue); the unperturbed run from the same start is dashed grey.

    Raises
    ------
    TliError
        The search found no case.
    """
    f = search["found"]
    if f is None:
        raise TliError("no Fig. 7 case to draw (the search found none)")
    p, r = f["no_modulation"], f["ltl_ds"]
    nominal = None
    if f["perturbations"]:
        nominal = run_variant(scoop_setup(lag=search["lag"]), "no-modulation", f["start"],
                              {}, steps=p.steps)
    plot_episodes(task, [("no modulation", p), ("LTL-DS", r)], path, nominal=nominal,
                  zoom_first=True, goal_label="d",
                  title=f"Fig. 7: without modulation a -> b -> a ... until the budget "
                        f"({b_to_a_failures(p)} b -> a failures in {p.steps} steps); LTL-DS "
                        "cuts the first b -> a failure (blue) and reaches d")
