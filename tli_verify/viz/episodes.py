"""Pictures of closed-loop episodes (paper Fig. 7 style) in any dimension ``n >= 1``.

Every panel shows the true regions (:mod:`tli_verify.viz.regions`: the exact partition in
2-D, shadows in n-D), the trajectory with perturbation jumps in red (dashed), the nominal
(unperturbed) run in grey (dashed), the learned cuts in blue, each invariance failure's last
in-mode state (gold circle) and failure state (red cross).

* ``n = 2``: one panel per episode, in a row (as the scoop experiment's ``plot_episode``), the
  trajectory in black;
* ``n >= 3``: per episode, a grid of panels (at most 3 columns), one per coordinate pair
  (:func:`~tli_verify.viz.regions.pairs_for`), and under it the *mode strip* (the running mode
  over the steps, pushes, cuts and failures marked). The trajectory is coloured by its mode in
  every panel (:func:`mode_colors`); a cut is drawn, like the regions, as its shadow
  (:func:`~tli_verify.viz.regions.cut_face_shadow`: the projection of its face, the part of
  its plane that bounds the mode's region; a line or a polygon's outline), and the legend says
  so;
* ``n = 1``: one panel per episode, the state along ``x1`` against the step (upwards).

:func:`animate_episode` animates one episode; in n-D its frames show several planes (three
coordinate pairs by default) and the mode strip with a cursor.

The goal wording of the titles is a parameter (``goal_label``); nothing here names a bundled
task.
"""

from __future__ import annotations

import functools
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_bytes
from tli_verify.plotting import save_figure
from tli_verify.rotations import rotate
from tli_verify.runtime.events import CutAdded, InvarianceFailure, Perturbation, mode_sequence
from tli_verify.viz.regions import (
    DEFAULT_SAMPLES,
    Pair,
    Picture,
    TaskLike,
    _Background,
    _background,
    _grid_shape,
    check_task,
    cut_face_shadow,
    cut_trace,
    pairs_for,
    pose_pairs,
)

if TYPE_CHECKING:
    from tli_verify.runtime.loop import EpisodeResult

__all__ = [
    "ZOOM_STEPS",
    "animate_episode",
    "episode_title",
    "mode_colors",
    "mode_sequence",
    "plot_episodes",
    "zoom_colors",
]

FloatArray = npt.NDArray[np.float64]
Others = tuple[tuple[FloatArray, FloatArray], ...]

ZOOM_STEPS = 400
"""States of the zoom panel (the end of the first episode)."""
_ZOOM_PALETTE: tuple[tuple[str, str], ...] = (
    ("k", "black"), ("tab:orange", "orange"), ("tab:green", "green"),
    ("tab:purple", "purple"), ("tab:brown", "brown"), ("tab:pink", "pink"),
    ("tab:olive", "olive"), ("tab:cyan", "cyan"),
)
_MODE_PALETTE: tuple[str, ...] = (
    "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan",
    "tab:gray", "gold", "darkslateblue",
)
"""The n-D pictures' mode colours, in order of first appearance (no black: the axes; no red or
blue: pushes, failures and cuts)."""
_PANEL_SIDE = 3.6
"""Side of an n-D panel (inches; 360 px at the pictures' 100 dpi)."""
_STRIP_HEIGHT = 0.8
_ND_DPI = 100
_FACE_EDGE = (0.12, 0.47, 0.71, 0.75)


# ----------------------------------------------------------------------------- titles
def episode_title(res: EpisodeResult, *, label: str = "", goal_label: str = "the goal") -> str:
    """``"<label>: <modes> (reaches <goal>, <k> cuts)"`` or ``"... (does not reach <goal> in N
    steps, <k> cuts)"`` (the mode sequence truncated to 12
    characters + ``"..."`` past 14)."""
    seq = mode_sequence(res.modes)
    if len(seq) > 14:
        seq = seq[:12] + "..."
    verdict = (f"reaches {goal_label}" if res.success
               else f"does not reach {goal_label} in {res.steps} steps")
    cuts = f"{res.cuts_added} cut{'' if res.cuts_added == 1 else 's'}"
    return f"{label + ': ' if label else ''}{seq} ({verdict}, {cuts})"


def zoom_colors(modes: Sequence[str], mode_colors: Mapping[str, Any] | None = None
                ) -> dict[str, tuple[Any, str]]:
    """Colours of the modes in the zoom panel: ``{mode: (colour, name for the title)}``.

    Modes are coloured in order of first appearance (black, orange, green, ...) unless
    ``mode_colors`` gives their colour.
    """
    out: dict[str, tuple[Any, str]] = {}
    given = dict(mode_colors or {})
    k = 0
    for m in modes:
        if m in out:
            continue
        if m in given:
            out[m] = (given[m], str(given[m]))
        else:
            out[m] = _ZOOM_PALETTE[k % len(_ZOOM_PALETTE)]
            k += 1
    return out


def mode_colors(modes: Sequence[str], given: Mapping[str, Any] | None = None
                ) -> dict[str, str]:
    """The colour of each mode in the n-D pictures (path, zoom panel, mode strip).

    Modes take :data:`_MODE_PALETTE` in order of first appearance (orange, green, purple, ...;
    cycling past ten modes) unless ``given`` names their colour.

    Parameters
    ----------
    modes : sequence of str
        Modes in the order they are first met (repeats allowed).
    given : mapping of str to colour, optional

    Returns
    -------
    dict of str to colour
    """
    out: dict[str, str] = {}
    chosen = dict(given or {})
    k = 0
    for m in modes:
        if m in out:
            continue
        if m in chosen:
            out[m] = chosen[m]
        else:
            out[m] = _MODE_PALETTE[k % len(_MODE_PALETTE)]
            k += 1
    return out


# ----------------------------------------------------------------------------- checks
def _check_episode(task: TaskLike, res: EpisodeResult, label: str) -> FloatArray:
    S = np.asarray(res.states, dtype=np.float64)
    what = f"episode {label!r}" if label else "episode"
    if S.ndim != 2 or S.shape[1] != task.dim or len(S) == 0:
        raise TliError(f"{task.name}: cannot draw {what}: states of shape {S.shape}, "
                       f"expected (T + 1, {task.dim})")
    if len(res.modes) != len(S):
        raise TliError(f"{task.name}: cannot draw {what}: {len(res.modes)} modes for "
                       f"{len(S)} states")
    return S


def _final_cuts(res: EpisodeResult) -> list[Any]:
    return [c for cs in _mode_cuts(res).values() for c in cs]


def _mode_cuts(res: EpisodeResult) -> dict[str, list[Any]]:
    """The cuts of each mode's region in the episode's final model."""
    modes = sorted({mm.mode for mm in res.model.modes.values()})
    return {m: list(res.model.region_cuts(m)) for m in modes}


def _faces(cuts: Mapping[str, Sequence[Any]]) -> list[tuple[Any, Others]]:
    """Each cut with the other cuts of its mode (its face: :func:`_draw_cut`)."""
    return [(c, tuple((o.normal, o.point) for q, o in enumerate(cs) if q != k))
            for cs in cuts.values() for k, c in enumerate(cs)]


# ----------------------------------------------------------------------------- drawing
def _xy(S: FloatArray, pair: Pair | None, t0: int = 0) -> tuple[FloatArray, FloatArray]:
    """Panel coordinates of states ``S`` (1-D: the state and the step ``t0 + k``)."""
    if pair is None:
        return S[:, 0], np.arange(t0, t0 + len(S), dtype=np.float64)
    return S[:, pair[0]], S[:, pair[1]]


def _pt(x: npt.ArrayLike, pair: Pair | None, t: int) -> tuple[float, float]:
    v = np.asarray(x, dtype=np.float64)
    if pair is None:
        return float(v[0]), float(t)
    return float(v[pair[0]]), float(v[pair[1]])


def _draw_cut(ax: Any, cut: Any, pair: Pair | None, lo: FloatArray, hi: FloatArray, *,
              others: Others | None = None) -> list[Any]:
    """A learned cut in the panel's plane (blue); nothing in 1-D. Returns the artists drawn.

    ``others`` None (2-D): the cut's line across the workspace. Else (n >= 3), like the
    regions, a shadow: the projection of the cut's *face*, the part of its plane that bounds
    the mode's region (within the workspace, on the inner side of the mode's ``others`` cuts;
    :func:`~tli_verify.viz.regions.cut_face_shadow`), as a line when it projects to one,
    else the outline of its polygon (a face seen nearly face-on covers much of the panel: an
    outline hides nothing); nothing where the face is empty or covers the whole panel.
    """
    if pair is None:
        return []
    if others is None:
        seg = cut_trace(cut.normal, cut.point, pair[0], pair[1], lo, hi)
        return [] if seg is None else ax.plot(seg[:, 0], seg[:, 1], color="tab:blue", lw=1.5)
    poly = _face_shadow(_key(cut.normal), _key(cut.point), pair, _key(lo), _key(hi),
                        tuple((_key(a), _key(q)) for a, q in others))
    if poly is None:
        return []
    if len(poly) == 2:
        return list(ax.plot(poly[:, 0], poly[:, 1], color="tab:blue", lw=1.5, zorder=2.5))
    return list(ax.fill(poly[:, 0], poly[:, 1], fill=False, edgecolor=_FACE_EDGE, lw=1.0,
                        zorder=2.4))


def _key(v: npt.ArrayLike) -> tuple[float, ...]:
    return tuple(float(x) for x in np.asarray(v, dtype=np.float64).ravel())


@functools.lru_cache(maxsize=4096)
def _face_shadow(normal: tuple[float, ...], point: tuple[float, ...], pair: Pair,
                 lo: tuple[float, ...], hi: tuple[float, ...],
                 others: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...]
                 ) -> FloatArray | None:
    """:func:`~tli_verify.viz.regions.cut_face_shadow`, computed once per cut, mode and plane
    (the episodes of one picture and the frames of an animation share their cuts)."""
    return cut_face_shadow(normal, point, pair[0], pair[1], lo, hi,
                           [(np.array(a), np.array(q)) for a, q in others])


def _segments(S: FloatArray, pair: Pair | None, modes: Sequence[str], pushes: set[int],
              t0: int = 0) -> tuple[FloatArray, list[str], FloatArray]:
    """The path of ``S`` (states ``t0 ..``) as segments: the moves (each with the mode of its
    first state; the modes with fewest moves last, drawn on top: a short mode stays visible)
    and the push jumps apart.

    Returns
    -------
    moves : ndarray, shape (m, 2, 2)
    move_modes : list of str, length m
    jumps : ndarray, shape (p, 2, 2)
    """
    u, v = _xy(S, pair, t0)
    P = np.column_stack([u, v])
    if len(P) < 2:
        return np.zeros((0, 2, 2)), [], np.zeros((0, 2, 2))
    seg = np.stack([P[:-1], P[1:]], axis=1)
    is_jump = np.array([t0 + k + 1 in pushes for k in range(len(seg))], dtype=bool)
    moves, move_modes = seg[~is_jump], [m for m, j in zip(modes[:-1], is_jump, strict=False)
                                        if not j]
    count: dict[str, int] = {}
    for m in move_modes:
        count[m] = count.get(m, 0) + 1
    order = sorted(range(len(move_modes)), key=lambda k: -count[move_modes[k]])  # stable
    return moves[order], [move_modes[k] for k in order], seg[is_jump]


def _limits(ax: Any, bg: _Background, pair: Pair | None, steps: int) -> None:
    lo, hi = bg.lo, bg.hi
    if pair is None:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(0, max(steps, 1))
        return
    i, j = pair
    ax.set_xlim(lo[i], hi[i])
    ax.set_ylim(lo[j], hi[j])
    ratio = (hi[j] - lo[j]) / (hi[i] - lo[i])
    ax.set_aspect("equal" if 0.25 <= ratio <= 4.0 else "auto")


def _draw_episode(ax: Any, bg: _Background, res: EpisodeResult, S: FloatArray,
                  pair: Pair | None, nominal: EpisodeResult | None,
                  colors: Mapping[str, Any] | None = None) -> None:
    """One panel of one episode (regions, nominal, trajectory, cuts, failures).

    ``colors`` (n >= 3): the trajectory coloured by mode (:func:`mode_colors`) and the cuts as
    shadows; else the trajectory in black and the cuts as lines.
    """
    steps = len(S) - 1
    if nominal is not None:
        steps = max(steps, len(nominal.states) - 1)
    bg.draw(ax, pair, t_range=(0.0, float(max(steps, 1))))
    if nominal is not None:
        ax.plot(*_xy(np.asarray(nominal.states, dtype=np.float64), pair), color="0.55",
                lw=1.0, ls="--", label="nominal")
    pushes = {e.step for e in res.events if isinstance(e, Perturbation)}
    if colors is not None:
        from matplotlib.collections import LineCollection

        moves, move_modes, jumps = _segments(S, pair, list(res.modes), pushes)
        ax.add_collection(LineCollection(list(moves), colors=[colors[m] for m in move_modes],
                                         linewidths=1.6, zorder=3))
        for seg in jumps:
            ax.plot(seg[:, 0], seg[:, 1], color="tab:red", lw=1.2, ls="--", zorder=3)
        ax.plot(*_pt(S[0], pair, 0), "o", color=colors[res.modes[0]], mec="k", ms=5, zorder=4)
    else:
        start = 0
        for t in sorted(pushes):  # the push lands between states[t-1] and states[t]
            if t <= 0 or t > len(S):
                continue
            ax.plot(*_xy(S[start:t], pair, start), color="k", lw=1.2)
            if t < len(S):
                ax.plot(*_xy(S[t - 1:t + 1], pair, t - 1), color="tab:red", lw=1.2, ls="--")
            start = t
        ax.plot(*_xy(S[start:], pair, start), color="k", lw=1.2)
        ax.plot(*_pt(S[0], pair, 0), "ko", ms=4)
    if colors is None:
        for c in _final_cuts(res):
            _draw_cut(ax, c, pair, bg.lo, bg.hi)
    else:
        for c, others in _faces(_mode_cuts(res)):
            _draw_cut(ax, c, pair, bg.lo, bg.hi, others=others)
    for e in res.events:
        if isinstance(e, InvarianceFailure):
            ax.plot(*_pt(e.last_inside, pair, e.step - 1), "o", mfc="gold", mec="k", ms=6,
                    zorder=5)
            ax.plot(*_pt(e.outside, pair, e.step), "x", color="tab:red", ms=7, mew=2, zorder=5)
    _orientation_glyphs(ax, bg, S, pair)
    _limits(ax, bg, pair, steps)


GLYPHS = 12
"""Orientation glyphs along a pose task's path, per panel of two position coordinates."""


def tool_axis(task: TaskLike) -> FloatArray:
    """The tool axis a pose task's glyphs draw: its first cone's ``axis``, else ``z``."""
    partition = getattr(task, "partition", None)
    named_regions = () if partition is None else (*partition.cells, *partition.layers)
    for named in named_regions:
        for leaf in named.region.leaves():
            if hasattr(leaf, "toward") and hasattr(leaf, "axis"):
                return np.asarray(leaf.axis, dtype=np.float64)
    return np.array([0.0, 0.0, 1.0])


def _orientation_glyphs(ax: Any, bg: _Background, S: FloatArray, pair: Pair | None) -> None:
    """On a panel of two position coordinates of a pose task: the tool axis, turned by the
    state's orientation (:meth:`~tli_verify.tasks.orientation.OrientationChart.quaternions`),
    as short arrows at :data:`GLYPHS` states along the path (the k-th position coordinate of
    the state is the world's k-th axis)."""
    chart = getattr(bg.task, "orientation", None)
    if chart is None or pair is None or len(S) < 2:
        return
    cols = range(chart.start, chart.start + 3)
    pos = [i for i in range(bg.task.dim) if i not in cols][:3]
    if pair[0] not in pos or pair[1] not in pos:
        return
    idx = np.unique(np.linspace(0, len(S) - 1, GLYPHS).round().astype(int))
    d = rotate(chart.quaternions(S[idx]), tool_axis(bg.task))  # (k, 3), world frame
    i, j = pair
    span = 0.07 * float(min(bg.hi[i] - bg.lo[i], bg.hi[j] - bg.lo[j]))
    ax.quiver(S[idx, i], S[idx, j], span * d[:, pos.index(i)], span * d[:, pos.index(j)],
              angles="xy", scale_units="xy", scale=1.0, width=0.006, color="0.25", zorder=4)


def _mode_runs(modes: Sequence[str]) -> list[tuple[str, int, int]]:
    """``[(mode, first step, last step + 1), ...]`` of a mode trace."""
    runs: list[tuple[str, int, int]] = []
    for t, m in enumerate(modes):
        if runs and runs[-1][0] == m:
            runs[-1] = (m, runs[-1][1], t + 1)
        else:
            runs.append((m, t, t + 1))
    return runs


def _mode_strip(ax: Any, res: EpisodeResult, colors: Mapping[str, Any]) -> None:
    """The mode over time: one bar per run of a mode (labelled where it is wide enough), the
    pushes (red dashed), the cuts learned (blue ticks) and the invariance failures (red
    crosses) at their steps."""
    steps = max(len(res.modes) - 1, 1)
    for m, a, b in _mode_runs(res.modes):
        ax.broken_barh([(a, b - a)], (0.15, 0.6), facecolors=colors[m], edgecolors="none")
        if (b - a) / steps >= 0.03:
            ax.text(0.5 * (a + b), 0.45, m, ha="center", va="center", fontsize=8,
                    color="white", fontweight="bold", clip_on=True)
    for e in res.events:
        if isinstance(e, Perturbation):
            ax.axvline(e.step, color="tab:red", ls="--", lw=1.0)
        elif isinstance(e, CutAdded):
            ax.plot([e.step, e.step], [0.78, 1.0], color="tab:blue", lw=2.0)
        elif isinstance(e, InvarianceFailure):
            ax.plot(e.step, 0.07, "x", color="tab:red", ms=5, mew=1.5)
    ax.set_xlim(0, steps)
    ax.set_ylim(0.0, 1.0)
    ax.set_yticks([])
    ax.set_ylabel("mode", fontsize=8)
    ax.set_xlabel("step", fontsize=8)
    ax.tick_params(labelsize=7)


def _zoom_panel(ax: Any, bg: _Background, res: EpisodeResult, S_all: FloatArray,
                pair: Pair | None, mode_colors: Mapping[str, Any] | None) -> None:
    """A panel around the last :data:`ZOOM_STEPS` states of ``res``, modes coloured, the last
    failure states as red crosses."""
    from matplotlib.collections import LineCollection

    S = S_all[-ZOOM_STEPS:]
    t0 = len(S_all) - len(S)
    u, v = _xy(S, pair, t0)
    bg.draw(ax, pair, t_range=(0.0, float(max(len(S_all) - 1, 1))))
    modes = list(res.modes[-len(S):])
    colors = zoom_colors(modes, mode_colors)
    if len(S) > 1:
        seg = np.stack([np.column_stack([u[:-1], v[:-1]]), np.column_stack([u[1:], v[1:]])],
                       axis=1)
        ax.add_collection(LineCollection(list(seg), colors=[colors[m][0] for m in modes[:-1]],
                                         linewidths=0.8))
    fails = [e for e in res.events if isinstance(e, InvarianceFailure)][-60:]
    if fails:
        pts = np.array([_pt(e.outside, pair, e.step) for e in fails])
        ax.plot(pts[:, 0], pts[:, 1], "x", color="tab:red", ms=3)
    if pair is None:
        cu = float(u.mean())
        hu = max(0.3, 0.6 * float(u.max() - u.min()))
        ax.set_xlim(cu - hu, cu + hu)
        ax.set_ylim(t0, t0 + max(len(S) - 1, 1))
    else:
        c = np.array([u.mean(), v.mean()])
        half = max(0.3, 0.6 * float(max(u.max() - u.min(), v.max() - v.min())))
        ax.set_xlim(c[0] - half, c[0] + half)
        ax.set_ylim(c[1] - half, c[1] + half)
        ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    legend = ", ".join(f"{m} {name}" for m, (_, name) in colors.items())
    heading = f"zoom: its last {len(S)} steps"
    if len(heading) + len(legend) <= 48:
        ax.set_title(f"{heading} (mode {legend})", fontsize=9)
    else:  # long mode names: the colours in a legend, not a title wider than the panel
        from matplotlib.lines import Line2D

        ax.set_title(heading, fontsize=9)
        ax.legend(handles=[Line2D([], [], color=c, lw=1.2, label=m)
                           for m, (c, _) in colors.items()], fontsize=7, loc="upper right",
                  title="mode", title_fontsize=7, framealpha=0.8)
    _labels(ax, bg.task, pair)


def _labels(ax: Any, task: TaskLike, pair: Pair | None) -> None:
    if pair is None:
        ax.set_xlabel(task.state_names[0], fontsize=8)
        ax.set_ylabel("step", fontsize=8)
    else:
        ax.set_xlabel(task.state_names[pair[0]], fontsize=8)
        ax.set_ylabel(task.state_names[pair[1]], fontsize=8)


def _trajectory_handles(nominal: bool, colors: Mapping[str, Any] | None = None) -> list[Any]:
    """The legend of the trajectories; ``colors`` (n >= 3): one entry per mode, and a cut is
    drawn as the shadow of its face (a line or a polygon's outline), like the regions."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    cut: list[Any]
    if colors is None:
        out = [Line2D([], [], color="k", lw=1.2, label="trajectory")]
        cut = [Line2D([], [], color="tab:blue", lw=1.5, label="cut")]
    else:
        out = [Line2D([], [], color=c, lw=2.0, label=f"path in mode {m}")
               for m, c in colors.items()]
        cut = [Line2D([], [], color="tab:blue", lw=1.5,
                      label="cut: shadow of its face (a line,"),
               Patch(fill=False, edgecolor=_FACE_EDGE, lw=1.0,
                     label="or a polygon's outline), as regions")]
    if nominal:
        out.append(Line2D([], [], color="0.55", lw=1.0, ls="--", label="nominal"))
    return [*out, Line2D([], [], color="tab:red", lw=1.2, ls="--", label="push"), *cut,
            Line2D([], [], ls="none", marker="o", mfc="gold", mec="k", label="last in-mode"),
            Line2D([], [], ls="none", marker="x", color="tab:red", mew=2, label="failure")]


def plot_episodes(task: TaskLike, panels: Sequence[tuple[str, EpisodeResult]],
                  path: str | os.PathLike[str], *, nominal: EpisodeResult | None = None,
                  title: str | None = None, zoom_first: bool = False,
                  goal_label: str = "the goal", mode_colors: Mapping[str, Any] | None = None,
                  pairs: Sequence[Sequence[int]] | None = None,
                  samples: int = DEFAULT_SAMPLES, seed: int = 0) -> Picture:
    """A Fig. 7-style picture of closed-loop episodes, in any dimension, to a PNG.

    Parameters
    ----------
    task : TaskLike
    panels : sequence of (str, EpisodeResult)
        Label and episode; ``states`` of shape (T + 1, n).
    path : path-like
        Output PNG (written atomically).
    nominal : EpisodeResult, optional
        The unperturbed run, dashed grey in every panel.
    title : str, optional
        Figure title.
    zoom_first : bool, optional
        Add a panel zoomed on the last :data:`ZOOM_STEPS` states of the first episode (after
        its first panel in 2-D; in n-D the next cell of its grid, in its first coordinate
        pair), drawn by mode (:func:`zoom_colors`; n-D: :func:`mode_colors`).
    goal_label : str, optional
        The goal in the titles: ``"reaches <goal_label>"`` / ``"does not reach <goal_label> in
        N steps"`` (it reads for a mode name and for a phrase like ``"the goal"``).
    mode_colors : mapping of str to colour, optional
        Mode colours of the zoom panel (n >= 3: also of the path and the mode strip).
    pairs : sequence of (int, int), optional
        The coordinate pairs of each episode's grid (n >= 3;
        :func:`~tli_verify.viz.regions.pairs_for`; at most 3 columns, 3.6 in a side).
    samples, seed : int, optional
        Region samples for the shadows (n >= 3).

    Returns
    -------
    Picture
        ``panels`` counts the drawn axes (zoom included; n >= 3: the mode strips too).

    Raises
    ------
    TliError
        Nothing to draw, or an episode or the task cannot be drawn; nothing is written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_task(task)
    if not panels:
        raise TliError(f"{task.name}: no episode to draw")
    chosen = pairs_for(task.dim, pairs if pairs is not None else pose_pairs(task))
    states = [_check_episode(task, r, label) for label, r in panels]
    if nominal is not None:
        _check_episode(task, nominal, "nominal")
    bg = _background(task, resolution=300, samples=samples, seed=seed)
    flat_row = task.dim <= 2 and len(chosen) <= 1
    if flat_row:
        fig, drawn = _flat_figure(plt, bg, panels, states, chosen[0] if chosen else None,
                                  nominal=nominal, zoom_first=zoom_first,
                                  goal_label=goal_label, mode_colors=mode_colors)
    else:
        fig, drawn = _grid_figure(plt, bg, panels, states, chosen, nominal=nominal,
                                  zoom_first=zoom_first, goal_label=goal_label,
                                  mode_colors=mode_colors)
    try:
        if title:
            fig.suptitle(title, fontsize=10)
        if flat_row:
            fig.tight_layout()
    except BaseException:
        plt.close(fig)
        raise
    save_figure(fig, path, dpi=90 if flat_row else _ND_DPI)
    return Picture(path=Path(path), panels=drawn, pairs=chosen, legend=bg.legend)


def _flat_figure(plt: Any, bg: _Background, panels: Sequence[tuple[str, EpisodeResult]],
                 states: Sequence[FloatArray], pair: Pair | None, *,
                 nominal: EpisodeResult | None, zoom_first: bool, goal_label: str,
                 mode_colors: Mapping[str, Any] | None) -> tuple[Any, int]:
    """One row, one panel per episode (n <= 2; the former ``plot_episode``)."""
    ncols = len(panels) + int(zoom_first)
    width = min(4.2 * ncols, 24.0)
    fig, grid = plt.subplots(1, ncols, figsize=(width, 4.6), squeeze=False)
    try:
        axes = list(grid[0])
        zoom_ax = axes.pop(1) if zoom_first else None
        for ax, (label, r), S in zip(axes, panels, states, strict=True):
            _draw_episode(ax, bg, r, S, pair, nominal)
            ax.set_title(episode_title(r, label=label, goal_label=goal_label), fontsize=9)
            _labels(ax, bg.task, pair)
        if zoom_ax is not None:
            _zoom_panel(zoom_ax, bg, panels[0][1], states[0], pair, mode_colors)
    except BaseException:
        plt.close(fig)
        raise
    return fig, ncols


def _grid_figure(plt: Any, bg: _Background, panels: Sequence[tuple[str, EpisodeResult]],
                 states: Sequence[FloatArray], chosen: Sequence[Pair], *,
                 nominal: EpisodeResult | None, zoom_first: bool, goal_label: str,
                 mode_colors: Mapping[str, Any] | None) -> tuple[Any, int]:
    """Per episode (n >= 3): a grid of panels, one per coordinate pair (at most 3 columns),
    the path coloured by mode, and the mode strip under them (:func:`_mode_strip`)."""
    ncells = len(chosen) + int(zoom_first)
    nrows, ncols = _grid_shape(ncells)
    block = nrows * _PANEL_SIDE + _STRIP_HEIGHT + 0.7
    colors = _colors_of([r for _, r in panels], nominal, mode_colors)
    fig = plt.figure(figsize=(ncols * _PANEL_SIDE + 2.9, len(panels) * block),
                     layout="constrained")
    try:
        subs = fig.subfigures(len(panels), 1, squeeze=False)[:, 0]
        drawn = 0
        for row, (sub, (label, r), S) in enumerate(zip(subs, panels, states, strict=True)):
            grid = sub.add_gridspec(nrows + 1, ncols,
                                    height_ratios=[_PANEL_SIDE] * nrows + [_STRIP_HEIGHT])
            axes = [sub.add_subplot(grid[a, b]) for a in range(nrows) for b in range(ncols)]
            for ax, pair in zip(axes, chosen, strict=False):
                _draw_episode(ax, bg, r, S, pair, nominal, colors)
                _labels(ax, bg.task, pair)
                ax.tick_params(labelsize=7)
                drawn += 1
            extra = axes[len(chosen):]
            if row == 0 and zoom_first:
                _zoom_panel(extra.pop(0), bg, r, S, chosen[0], colors)
                drawn += 1
            for ax in extra:
                ax.axis("off")
            _mode_strip(sub.add_subplot(grid[nrows, :]), r, colors)
            drawn += 1
            sub.suptitle(episode_title(r, label=label, goal_label=goal_label), fontsize=10)
        fig.legend(handles=[*bg.legend_handles(), *_trajectory_handles(nominal is not None,
                                                                     colors)],
                   loc="outside right upper", fontsize=8, frameon=False)
    except BaseException:
        plt.close(fig)
        raise
    return fig, drawn


def _colors_of(results: Sequence[EpisodeResult], nominal: EpisodeResult | None,
               given: Mapping[str, Any] | None) -> dict[str, str]:
    """The mode colours of a picture: every mode of its episodes (and the nominal run), in
    order of first appearance, the modes of the model first met in none of them last."""
    seen: list[str] = [m for r in results for m in r.modes]
    if nominal is not None:
        seen += list(nominal.modes)
    for r in results:
        seen += sorted({mm.mode for mm in r.model.modes.values()})
    return mode_colors(seen, given)


# ----------------------------------------------------------------------------- animation
def animate_episode(task: TaskLike, res: EpisodeResult, path: str | os.PathLike[str], *,
                    frames: int = 120, fps: int = 20, title: str = "",
                    pair: Sequence[int] | None = None,
                    pairs: Sequence[Sequence[int]] | None = None,
                    samples: int = DEFAULT_SAMPLES, seed: int = 0) -> int:
    """An animated GIF of one episode (Fig. 7 style), written atomically.

    Each frame shows the true regions, the path so far (perturbation jumps not joined), the
    current state (red), the cuts learned so far (blue, from each
    :class:`~tli_verify.runtime.events.CutAdded`'s step) and the step and mode in the title.
    In 2-D one panel, the path in black; in 1-D the state along ``x1`` against the step. In
    n-D (n >= 3) several planes side by side (default the first three coordinate pairs of
    :func:`~tli_verify.viz.regions.pairs_for`, which between them show every coordinate of a
    4-D task), the path coloured by mode, the cuts as shadows of their faces (as in
    :func:`plot_episodes`), and under them the mode strip with a cursor at the frame's step.

    Parameters
    ----------
    task : TaskLike
    res : EpisodeResult
        ``states`` of shape (T + 1, n).
    path : path-like
        The GIF file.
    frames : int, optional
        At most this many frames, evenly spaced over the episode's states.
    fps : int, optional
    title : str, optional
        Prefix of every frame's title.
    pair : (int, int), optional
        One coordinate pair to animate (n >= 2); the same as ``pairs=[pair]``.
    pairs : sequence of (int, int), optional
        The coordinate pairs to animate side by side (n >= 2; at most
        :data:`~tli_verify.viz.regions.MAX_PAIRS`).
    samples, seed : int, optional
        Region samples for the shadows (n >= 3).

    Returns
    -------
    int
        Frames written.

    Raises
    ------
    TliError
        The task or episode cannot be drawn, both ``pair`` and ``pairs`` given, or ``frames``
        / ``fps`` below 1; nothing is written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from PIL import Image

    check_task(task)
    if frames < 1 or fps < 1:
        raise TliError(f"{task.name}: cannot animate with frames={frames}, fps={fps} "
                       "(need >= 1)")
    if pair is not None and pairs is not None:
        raise TliError(f"{task.name}: cannot animate: give pair or pairs, not both")
    S = _check_episode(task, res, "")
    if task.dim < 2:
        chosen: tuple[Pair | None, ...] = (None,)
    elif pair is not None or pairs is not None:
        chosen = pairs_for(task.dim, [pair] if pair is not None else pairs)
    else:
        chosen = pairs_for(task.dim)[:3]
    nd = task.dim >= 3
    bg = _background(task, resolution=300, samples=samples, seed=seed)
    pushes = {e.step for e in res.events if isinstance(e, Perturbation)}
    added = sorted((e for e in res.events if isinstance(e, CutAdded)), key=lambda e: e.step)
    online = {(tuple(e.cut.normal.tolist()), tuple(e.cut.point.tolist())) for e in added}
    cuts_now = {m: [c for c in cs
                    if (tuple(c.normal.tolist()), tuple(c.point.tolist())) not in online]
                for m, cs in _mode_cuts(res).items()}
    colors = _colors_of([res], None, None) if nd else None
    shown = np.unique(np.linspace(0, len(S) - 1, max(1, min(frames, len(S)))).astype(int))
    side = 4.0 if len(chosen) == 1 else 3.4
    fig = plt.figure(figsize=(side * len(chosen) + 0.3, side + 0.6 + (0.9 if nd else 0.0)),
                     layout="constrained")
    images = []
    try:
        grid = fig.add_gridspec(2 if nd else 1, len(chosen),
                                height_ratios=[side, 0.65] if nd else [1.0])
        axes = [fig.add_subplot(grid[0, k]) for k in range(len(chosen))]
        cursor = None
        if nd:
            assert colors is not None
            strip = fig.add_subplot(grid[1, :])
            _mode_strip(strip, res, colors)
            cursor = strip.axvline(0, color="k", lw=1.5)
        paths: list[Any] = []
        dots: list[Any] = []
        cut_art: list[list[Any]] = [[] for _ in chosen]
        for ax, the_pair in zip(axes, chosen, strict=True):
            bg.draw(ax, the_pair, t_range=(0.0, float(max(len(S) - 1, 1))))
            _limits(ax, bg, the_pair, len(S) - 1)
            _labels(ax, task, the_pair)
            if nd:
                ax.tick_params(labelsize=7)
            lines = LineCollection([], linewidths=1.6 if nd else 1.2, colors="k", zorder=3)
            ax.add_collection(lines)
            paths.append(lines)
            (dot,) = ax.plot([], [], "o", color="tab:red", ms=6, zorder=4)
            dots.append(dot)

        def draw_cuts() -> None:
            for k, (ax, the_pair) in enumerate(zip(axes, chosen, strict=True)):
                for a in cut_art[k]:
                    a.remove()
                cut_art[k] = [a for c, others in _faces(cuts_now)
                              for a in _draw_cut(ax, c, the_pair, bg.lo, bg.hi,
                                                 others=others if nd else None)]

        draw_cuts()
        learned = 0
        for t in shown:
            for k, the_pair in enumerate(chosen):
                moves, move_modes, _ = _segments(S[: t + 1], the_pair,
                                                 list(res.modes[: t + 1]), pushes)
                paths[k].set_segments(list(moves))
                if colors is not None:
                    paths[k].set_colors([colors[m] for m in move_modes])
                dots[k].set_data(*([v] for v in _pt(S[t], the_pair, int(t))))
            fresh = False
            while learned < len(added) and added[learned].step <= t:
                e = added[learned]
                cuts_now.setdefault(e.mode, []).append(e.cut)
                learned += 1
                fresh = True
            if fresh:
                draw_cuts()
            if cursor is not None:
                cursor.set_xdata([t, t])
            fig.suptitle(f"{title + ': ' if title else ''}step {t}, mode {res.modes[t]}, "
                         f"{learned} cut{'' if learned == 1 else 's'} learned", fontsize=9)
            fig.canvas.draw()
            rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
            images.append(Image.fromarray(rgba[..., :3]).convert(
                "P", palette=Image.Palette.ADAPTIVE))
    finally:
        plt.close(fig)
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:],
                   duration=max(1, round(1000 / fps)), loop=0)
    atomic_write_bytes(path, buffer.getvalue())  # creates the parent folders
    return len(images)
