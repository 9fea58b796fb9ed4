"""Pictures of closed-loop episodes (paper Fig. 7 style) in any dimension ``n >= 1``.

Every panel shows the true regions (:mod:`tli_verify.viz.regions`: the exact partition in
2-D, shadows in n-D), the trajectory in black with perturbation jumps in red (dashed), the
nominal (unperturbed) run in grey (dashed), the learned cuts in blue, each invariance
failure's last in-mode state (gold circle) and failure state (red cross).

* ``n = 2``: one panel per episode, in a row (as the scoop experiment's ``plot_episode``);
* ``n >= 3``: one row per episode, one panel per coordinate pair
  (:func:`~tli_verify.viz.regions.pairs_for`); a cut is drawn as its trace in each panel's
  plane through the cut point (:func:`~tli_verify.viz.regions.cut_trace`);
* ``n = 1``: one panel per episode, the state along ``x1`` against the step (upwards).

The goal wording of the titles is a parameter (``goal_label``); nothing here names a bundled
world.
"""

from __future__ import annotations

import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.runtime.events import CutAdded, InvarianceFailure, Perturbation, mode_sequence
from tli_verify.viz.regions import (
    DEFAULT_SAMPLES,
    Pair,
    Picture,
    TaskLike,
    _Background,
    _background,
    check_task,
    cut_trace,
    pairs_for,
)

if TYPE_CHECKING:
    from tli_verify.runtime.loop import EpisodeResult

__all__ = [
    "ZOOM_STEPS",
    "animate_episode",
    "episode_title",
    "mode_sequence",
    "plot_episodes",
    "zoom_colors",
]

FloatArray = npt.NDArray[np.float64]

ZOOM_STEPS = 400
"""States of the zoom panel (the end of the first episode)."""
_ZOOM_PALETTE: tuple[tuple[str, str], ...] = (
    ("k", "black"), ("tab:orange", "orange"), ("tab:green", "green"),
    ("tab:purple", "purple"), ("tab:brown", "brown"), ("tab:pink", "pink"),
    ("tab:olive", "olive"), ("tab:cyan", "cyan"),
)


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
    modes = sorted({mm.mode for mm in res.model.modes.values()})
    return [c for m in modes for c in res.model.region_cuts(m)]


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


def _draw_cut(ax: Any, cut: Any, pair: Pair | None, lo: FloatArray, hi: FloatArray) -> None:
    """A learned cut's trace in the panel's plane (blue); nothing in 1-D."""
    if pair is None:
        return
    seg = cut_trace(cut.normal, cut.point, pair[0], pair[1], lo, hi)
    if seg is not None:
        ax.plot(seg[:, 0], seg[:, 1], color="tab:blue", lw=1.5)


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
                  pair: Pair | None, nominal: EpisodeResult | None) -> None:
    """One panel of one episode (regions, nominal, trajectory, cuts, failures)."""
    steps = len(S) - 1
    if nominal is not None:
        steps = max(steps, len(nominal.states) - 1)
    bg.draw(ax, pair, t_range=(0.0, float(max(steps, 1))))
    if nominal is not None:
        ax.plot(*_xy(np.asarray(nominal.states, dtype=np.float64), pair), color="0.55",
                lw=1.0, ls="--", label="nominal")
    pushes = {e.step for e in res.events if isinstance(e, Perturbation)}
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
    for c in _final_cuts(res):
        _draw_cut(ax, c, pair, bg.lo, bg.hi)
    for e in res.events:
        if isinstance(e, InvarianceFailure):
            ax.plot(*_pt(e.last_inside, pair, e.step - 1), "o", mfc="gold", mec="k", ms=6)
            ax.plot(*_pt(e.outside, pair, e.step), "x", color="tab:red", ms=7, mew=2)
    _limits(ax, bg, pair, steps)


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


def _trajectory_handles(nominal: bool, sliced: bool = False) -> list[Any]:
    """The legend of the trajectories; ``sliced`` (n >= 3): a cut is drawn as its trace in the
    2-D slice through its point, not as a shadow like the regions."""
    from matplotlib.lines import Line2D

    out = [Line2D([], [], color="k", lw=1.2, label="trajectory"),
           Line2D([], [], color="tab:red", lw=1.2, ls="--", label="push"),
           Line2D([], [], color="tab:blue", lw=1.5,
                  label="cut: slice through its point" if sliced else "cut"),
           Line2D([], [], ls="none", marker="o", mfc="gold", mec="k", label="last in-mode"),
           Line2D([], [], ls="none", marker="x", color="tab:red", mew=2, label="failure")]
    if nominal:
        out.insert(1, Line2D([], [], color="0.55", lw=1.0, ls="--", label="nominal"))
    return out


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
        its first panel in 2-D; at the end of its row, in its first coordinate pair, in n-D),
        drawn by mode (:func:`zoom_colors`).
    goal_label : str, optional
        The goal in the titles: ``"reaches <goal_label>"`` / ``"does not reach <goal_label> in
        N steps"`` (it reads for a mode name and for a phrase like ``"the goal"``).
    mode_colors : mapping of str to colour, optional
        Mode colours of the zoom panel.
    pairs : sequence of (int, int), optional
        The coordinate pairs of each row (n >= 3; :func:`~tli_verify.viz.regions.pairs_for`).
    samples, seed : int, optional
        Region samples for the shadows (n >= 3).

    Returns
    -------
    Picture
        ``panels`` counts the drawn axes (zoom included).

    Raises
    ------
    TliError
        Nothing to draw, or an episode or the task cannot be drawn; nothing is written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    check_task(task)
    if not panels:
        raise TliError(f"{task.name}: no episode to draw")
    chosen = pairs_for(task.dim, pairs)
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
        fig, drawn = _row_figure(plt, bg, panels, states, chosen, nominal=nominal,
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
    save_figure(fig, path, dpi=90)
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


def _row_figure(plt: Any, bg: _Background, panels: Sequence[tuple[str, EpisodeResult]],
                states: Sequence[FloatArray], chosen: Sequence[Pair], *,
                nominal: EpisodeResult | None, zoom_first: bool, goal_label: str,
                mode_colors: Mapping[str, Any] | None) -> tuple[Any, int]:
    """One row per episode, one panel per coordinate pair (n >= 3)."""
    ncols = len(chosen) + int(zoom_first)
    nrows = len(panels)
    side = min(3.3, 16.0 / ncols, 20.0 / nrows)
    fig = plt.figure(figsize=(ncols * side + 1.9, nrows * (side + 0.35) + 0.5),
                     layout="constrained")
    try:
        subs = fig.subfigures(nrows, 1, squeeze=False)[:, 0]
        drawn = 0
        for row, (sub, (label, r), S) in enumerate(zip(subs, panels, states, strict=True)):
            axes = sub.subplots(1, ncols, squeeze=False)[0]
            for ax, pair in zip(axes, chosen, strict=False):
                _draw_episode(ax, bg, r, S, pair, nominal)
                _labels(ax, bg.task, pair)
                ax.tick_params(labelsize=7)
                drawn += 1
            extra = list(axes[len(chosen):])
            if row == 0 and zoom_first:
                _zoom_panel(extra.pop(0), bg, r, S, chosen[0], mode_colors)
                drawn += 1
            for ax in extra:
                ax.axis("off")
            sub.suptitle(episode_title(r, label=label, goal_label=goal_label), fontsize=9)
        fig.legend(handles=[*bg.legend_handles(), *_trajectory_handles(nominal is not None,
                                                                     bool(bg.shadows))],
                   loc="outside right upper", fontsize=8, frameon=False)
    except BaseException:
        plt.close(fig)
        raise
    return fig, drawn


# ----------------------------------------------------------------------------- animation
def animate_episode(task: TaskLike, res: EpisodeResult, path: str | os.PathLike[str], *,
                    frames: int = 120, fps: int = 20, title: str = "",
                    pair: Sequence[int] | None = None, samples: int = DEFAULT_SAMPLES,
                    seed: int = 0) -> int:
    """An animated GIF of one episode (Fig. 7 style), written atomically.

    Each frame shows the true regions (n >= 3: shadows in the first coordinate pair, or
    ``pair``), the path so far (black; perturbation jumps are not joined), the current state
    (red), the cuts learned so far (blue, from each
    :class:`~tli_verify.runtime.events.CutAdded`'s step; their traces in n-D) and the step
    and mode in the title. In 1-D the state runs along ``x1`` against the step.

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
        The coordinate pair to animate (n >= 2; default the first of
        :func:`~tli_verify.viz.regions.pairs_for`).
    samples, seed : int, optional
        Region samples for the shadows (n >= 3).

    Returns
    -------
    int
        Frames written.

    Raises
    ------
    TliError
        The task or episode cannot be drawn, or ``frames`` / ``fps`` below 1; nothing is
        written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from tli_verify.io import atomic_write_bytes

    check_task(task)
    if frames < 1 or fps < 1:
        raise TliError(f"{task.name}: cannot animate with frames={frames}, fps={fps} "
                       "(need >= 1)")
    S = _check_episode(task, res, "")
    the_pair: Pair | None = (pairs_for(task.dim, None if pair is None else [pair])[0]
                             if task.dim >= 2 else None)
    bg = _background(task, resolution=300, samples=samples, seed=seed)
    pushes = sorted(e.step for e in res.events if isinstance(e, Perturbation))
    cuts = sorted(((e.step, e.cut) for e in res.events if isinstance(e, CutAdded)),
                  key=lambda sc: sc[0])
    shown = np.unique(np.linspace(0, len(S) - 1, max(1, min(frames, len(S)))).astype(int))
    fig, ax = plt.subplots(figsize=(4.4, 4.6))
    images = []
    try:
        bg.draw(ax, the_pair, t_range=(0.0, float(max(len(S) - 1, 1))))
        _limits(ax, bg, the_pair, len(S) - 1)
        _labels(ax, task, the_pair)
        (path_line,) = ax.plot([], [], color="k", lw=1.2)
        (dot,) = ax.plot([], [], "o", color="tab:red", ms=6)
        drawn = 0
        for t in shown:
            u, v = _xy(S[: t + 1], the_pair)
            breaks = [k for k in pushes if 0 < k <= t]  # a push lands between [k-1] and [k]
            if breaks:
                u, v = np.insert(u, breaks, np.nan), np.insert(v, breaks, np.nan)
            path_line.set_data(u, v)
            px, py = _pt(S[t], the_pair, int(t))
            dot.set_data([px], [py])
            while drawn < len(cuts) and cuts[drawn][0] <= t:
                _draw_cut(ax, cuts[drawn][1], the_pair, bg.lo, bg.hi)
                drawn += 1
            ax.set_title(f"{title + ': ' if title else ''}step {t}, mode {res.modes[t]}, "
                         f"{drawn} cut{'' if drawn == 1 else 's'}", fontsize=9)
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
