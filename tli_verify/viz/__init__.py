"""Pictures of tasks and closed-loop episodes in any dimension ``n >= 1``.

:mod:`.regions` draws a task's true regions (the exact partition in 2-D, a strip in 1-D, one
panel per coordinate pair with the regions' shadows in n-D); :mod:`.episodes` draws Fig.
7-style episode panels and GIF animations. Any object with the :class:`~.regions.TaskLike`
attributes is a task. The submodules are imported on first use (``import tli_verify.viz`` stays
cheap; matplotlib is imported only when a picture is drawn).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tli_verify.viz.episodes import animate_episode, mode_colors, plot_episodes
    from tli_verify.viz.regions import (
        Picture,
        TaskLike,
        as_task,
        check_task,
        cut_face_shadow,
        cut_trace,
        legend_labels,
        pairs_for,
        plot_task,
        region_shadows,
    )

__all__ = [
    "Picture",
    "TaskLike",
    "animate_episode",
    "as_task",
    "check_task",
    "cut_face_shadow",
    "cut_trace",
    "legend_labels",
    "mode_colors",
    "pairs_for",
    "plot_episodes",
    "plot_task",
    "region_shadows",
]

_HOME = {"animate_episode": "episodes", "mode_colors": "episodes", "plot_episodes": "episodes"}


def __getattr__(name: str) -> Any:
    """Import the public names from their submodule on first use."""
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = importlib.import_module(f"{__name__}.{_HOME.get(name, 'regions')}")
    return getattr(module, name)
