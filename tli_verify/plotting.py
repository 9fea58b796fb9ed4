"""Pictures for people who would rather look than read: task automata as mode graphs.

Rendering uses matplotlib only (no Graphviz binary needed); ``tli spec automaton -o X.dot``
still writes DOT for those who have Graphviz.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from tli_verify.io import atomic_write_bytes

__all__ = ["draw_mode_graph", "save_figure"]


def save_figure(fig: Any, path: str | os.PathLike[str], *, dpi: int) -> None:
    """Write a matplotlib figure as PNG atomically (parent folders created) and close it.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : path-like
    dpi : int
    """
    import io

    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic_write_bytes(path, buffer.getvalue())


def draw_mode_graph(automaton: Any, path: str | os.PathLike[str], *, title: str | None = None
                    ) -> None:
    """Draw the mode-level graph of a task automaton (like paper Fig. 3(a)) to a PNG.

    Nodes are modes, in spec order around a circle (a row for up to 4 modes); an arrow
    ``m -> n`` means some automaton transition runs ``n`` right after ``m``; a small loop means
    the mode may keep running. Initial modes have a thick border.

    Parameters
    ----------
    automaton : TaskAutomaton
    path : path-like
        Output PNG file (written atomically).
    title : str, optional
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, FancyArrowPatch

    modes = [m for m in automaton.modes
             if any(s.mode == m for s in automaton.states)] or sorted(
        {s.mode for s in automaton.states})
    n = len(modes)
    if n <= 4:
        pos = {m: np.array([2.2 * i, 0.0]) for i, m in enumerate(modes)}
    else:
        radius = max(1.8, 0.55 * n)
        pos = {m: radius * np.array([math.cos(math.pi / 2 - 2 * math.pi * i / n),
                                     math.sin(math.pi / 2 - 2 * math.pi * i / n)])
               for i, m in enumerate(modes)}
    initial = {automaton.states[i].mode for i in automaton.initial}
    pairs = [(a, b) for a, b in automaton.mode_transitions() if a in pos and b in pos]
    pair_set = set(pairs)
    cmap = plt.get_cmap("tab10")
    fig, ax = plt.subplots(figsize=(max(4.0, 1.6 * n), 3.2) if n <= 4 else (6.5, 6.0))
    r_node = 0.42
    for k, m in enumerate(modes):
        ax.add_patch(Circle(tuple(pos[m]), r_node, facecolor=cmap(k % 10), alpha=0.35,
                            edgecolor="black", linewidth=2.5 if m in initial else 1.0, zorder=2))
        ax.text(float(pos[m][0]), float(pos[m][1]), m, ha="center", va="center", fontsize=13,
                zorder=3)
    for a, b in pairs:
        if a == b:
            c = pos[a] + np.array([0.0, r_node + 0.18])
            ax.add_patch(Circle(tuple(c), 0.2, fill=False, edgecolor="0.35", linewidth=1.0,
                                zorder=1))
            continue
        bend = 0.35 if (b, a) in pair_set else 0.15
        forward = modes.index(b) == modes.index(a) + 1
        arrow = FancyArrowPatch(tuple(pos[a]), tuple(pos[b]),
                                connectionstyle=f"arc3,rad={bend}", arrowstyle="-|>",
                                mutation_scale=14, shrinkA=24, shrinkB=24,
                                color="black" if forward else "0.55",
                                linewidth=1.6 if forward else 1.1, zorder=1)
        ax.add_patch(arrow)
    xy = np.array(list(pos.values()))
    pad = 1.0
    ax.set_xlim(xy[:, 0].min() - pad, xy[:, 0].max() + pad)
    ax.set_ylim(xy[:, 1].min() - pad, xy[:, 1].max() + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title or f"{automaton.name}: {len(automaton.states)} automaton states",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
