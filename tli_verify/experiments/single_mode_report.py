"""The single-mode study's report: statistics, the markdown table and the figures (paper
Figs. 5-6), from the records :func:`tli_verify.experiments.single_mode.run` returns."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.experiments.single_mode import (
    PAPER_TABLE,
    POLICIES,
    SingleModeConfig,
    TrialResult,
)
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.logic.escape import markdown_text, markdown_url
from tli_verify.plotting import save_figure

__all__ = ["markdown", "summarize", "write_outputs"]

FloatArray = npt.NDArray[np.float64]


def _stats(values: Sequence[float]) -> dict[str, float]:
    a = np.asarray(values, dtype=np.float64)
    return {"mean": float(a.mean()), "median": float(np.median(a)),
            "q25": float(np.quantile(a, 0.25)), "q75": float(np.quantile(a, 0.75)),
            "min": float(a.min()), "max": float(a.max())}


def summarize(
    trials: Sequence[TrialResult], config: SingleModeConfig, *, seconds: float | None = None,
    workers: int | None = None,
) -> dict[str, Any]:
    """Aggregate trials: mean and IQR per policy and noise level, cut counts, curves.

    Returns
    -------
    dict
        JSON-ready. ``success[policy][noise]`` is the mean success rate in [0, 1];
        ``cuts[policy][noise]`` holds statistics of the number of cuts.
    """
    noises = [str(p) for p in config.noise_percent]
    success = {p: {k: float(np.mean([t.success[p][k] for t in trials])) for k in noises}
               for p in POLICIES}
    iqr = {p: {k: [_stats([t.success[p][k] for t in trials])["q25"],
                   _stats([t.success[p][k] for t in trials])["q75"]] for k in noises}
           for p in POLICIES}
    heldout = ({p: {k: float(np.mean([t.heldout[p][k] for t in trials])) for k in noises}
                for p in POLICIES} if config.heldout else {})
    cuts: dict[str, dict[str, Any]] = {}
    curves: dict[str, dict[str, Any]] = {}
    for p in ("BC+mod", "DS+mod"):
        cuts[p] = {}
        curves[p] = {}
        for k in noises:
            counts = [t.cuts[p][k] for t in trials]
            st = _stats(counts)
            st["converged"] = float(np.mean([t.converged[p][k] for t in trials]))
            cuts[p][k] = st
            length = max(len(t.curve[p][k]) for t in trials)
            padded = np.array([t.curve[p][k] + [t.curve[p][k][-1]] * (length - len(t.curve[p][k]))
                               for t in trials])
            curves[p][k] = {"mean": padded.mean(axis=0).tolist(),
                            "q25": np.quantile(padded, 0.25, axis=0).tolist(),
                            "q75": np.quantile(padded, 0.75, axis=0).tolist()}
    failures = {p: {k: {"invariance": int(sum(t.invariance_failures[p][k] for t in trials)),
                        "reachability": int(sum(t.reachability_failures[p][k] for t in trials))}
                    for k in noises} for p in POLICIES}
    top = noises[-1]
    shape = {
        "DS+mod is 100% at every noise level": all(success["DS+mod"][k] == 1.0 for k in noises),
        "DS+mod never leaves the mode (0 invariance failures)": all(
            failures["DS+mod"][k]["invariance"] == 0 for k in noises),
        "DS+mod has no invariance failure left after at most 5 cuts": all(
            cuts["DS+mod"][k]["max"] <= 5 and cuts["DS+mod"][k]["converged"] == 1.0
            for k in noises),
        "DS below 100% at the largest noise": success["DS"][top] < 1.0,
        "BC below DS at every noise level": all(success["BC"][k] <= success["DS"][k]
                                                for k in noises),
        "BC+mod below 100% at the largest noise": success["BC+mod"][top] < 1.0,
    }
    return {
        "config": asdict(config),
        "trials_run": len(trials),
        "success": success,
        "success_iqr": iqr,
        "heldout": heldout,
        "cuts": cuts,
        "curve": curves,
        "failures": failures,
        "unsolved_cuts": int(sum(t.unsolved_cuts for t in trials)),
        "expected_shape": shape,
        "paper": PAPER_TABLE,
        "seconds": seconds,
        "workers": workers,
        "per_trial": [asdict(t) for t in trials],
    }


def _pct(x: float) -> str:
    return f"{100.0 * x:.1f}"


def markdown(summary: dict[str, Any], *, figures: Sequence[str] = ()) -> str:
    """The Markdown report: table (mean [IQR]), paper numbers, cuts, held-out, shape checks."""
    cfg = summary["config"]
    noises = [str(p) for p in cfg["noise_percent"]]
    lines = [
        "# Single-mode study (paper Sec. 7.1, Fig. 6)",
        "",
        f"{summary['trials_run']} random convex modes, {cfg['starts']} starts per noise level, "
        f"seed {cfg['seed']}; Euler dt {cfg['dt']}, {cfg['steps']} steps, speed cap "
        f"{cfg['speed_cap']}, goal tolerance {cfg['goal_tolerance']}; cuts keep "
        f"{cfg['cut_constraints']}; DS margin eps {cfg.get('ds_eps', 1e-3):g}; "
        "noise = percent of the "
        f"{cfg['workspace']:g}-unit workspace side. Success rate in % (mean over trials, "
        "[25th-75th percentile]); paper values in parentheses.",
        "",
        "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
        "|---|" + "---|" * len(noises),
    ]
    for p in POLICIES:
        cells = []
        for k in noises:
            q25, q75 = summary["success_iqr"][p][k]
            paper = PAPER_TABLE.get(p, {}).get(k)
            ref = f" ({paper:g})" if paper is not None else ""
            cells.append(f"{_pct(summary['success'][p][k])} [{_pct(q25)}-{_pct(q75)}]{ref}")
        lines.append(f"| {markdown_text(p)} | " + " | ".join(cells) + " |")
    lines += ["", "Cuts learned per mode (mean / max; share of trials with no invariance failure "
              "left):", "", "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
              "|---|" + "---|" * len(noises)]
    for p in ("BC+mod", "DS+mod"):
        cells = [f"{summary['cuts'][p][k]['mean']:.2f} / {summary['cuts'][p][k]['max']:.0f}; "
                 f"{_pct(summary['cuts'][p][k]['converged'])}%" for k in noises]
        lines.append(f"| {p} | " + " | ".join(cells) + " |")
    lines += ["", "Success (mean %) after k cuts (paper Fig. 6 right; a trial that stopped "
              "early keeps its last value):", ""]
    for p in ("DS+mod", "BC+mod"):
        for k in noises:
            mean = summary["curve"][p][k]["mean"][:8]
            lines.append(f"- {p}, noise {k}%: " + ", ".join(_pct(v) for v in mean))
    if summary.get("heldout"):
        lines += ["", "Held-out starts (fresh draws, final cuts):", "",
                  "| Policy | " + " | ".join(f"noise {k}%" for k in noises) + " |",
                  "|---|" + "---|" * len(noises)]
        for p in POLICIES:
            lines.append(f"| {p} | " + " | ".join(_pct(summary["heldout"][p][k])
                                                  for k in noises) + " |")
    lines += ["", "Failures over all trials (invariance = left the mode; reachability = stayed "
              "but missed the goal):", ""]
    for p in POLICIES:
        parts = [f"{k}%: {summary['failures'][p][k]['invariance']} inv / "
                 f"{summary['failures'][p][k]['reachability']} reach" for k in noises]
        lines.append(f"- {p}: " + "; ".join(parts))
    lines += ["", "Expected shape (paper):", ""]
    for name, ok in summary["expected_shape"].items():
        lines.append(f"- [{'x' if ok else ' '}] {name}")
    if summary.get("unsolved_cuts"):
        lines += ["", "Cut attempts that found no separating plane (that failure was skipped): "
                  f"{summary['unsolved_cuts']}"]
    if summary.get("seconds") is not None:
        lines += ["", f"Wall time {summary['seconds']:.1f} s with {summary['workers']} "
                  "worker process(es)."]
    for fig in figures:
        lines += ["", f"![{markdown_text(fig)}]({markdown_url(fig)})"]
    return "\n".join(lines) + "\n"


def _plot_rollouts(record: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    noises = list(record["noise"].keys())
    top = noises[-1]
    ncols = len(noises) + 2
    fig, axes = plt.subplots(2, ncols, figsize=(3.0 * ncols, 6.2), squeeze=False)
    V = record["vertices"]
    goal = record["attractor"]
    W = record["workspace"]
    grid = np.linspace(0.0, W, 40)
    GX, GY = np.meshgrid(grid, grid)
    G = np.column_stack([GX.ravel(), GY.ravel()])
    for r, name in enumerate(("BC", "DS")):
        pol = record["bc"] if name == "BC" else record["ds"]
        for c in range(ncols):
            ax = axes[r, c]
            ax.fill(V[:, 0], V[:, 1], facecolor="0.94", edgecolor="k", linestyle="--", lw=1.0)
            ax.set_xlim(0, W)
            ax.set_ylim(0, W)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
        ax = axes[r, 0]
        U = pol.velocity(G)
        ax.streamplot(GX, GY, U[:, 0].reshape(GX.shape), U[:, 1].reshape(GX.shape),
                      color="0.6", density=0.8, linewidth=0.6, arrowsize=0.6)
        for d in record["demos"]:
            ax.plot(d[:, 0], d[:, 1], "k-", lw=1.8)
        ax.set_title(f"{name}: nominal + demos", fontsize=9)
        panels: list[tuple[str, Any, Any]] = [(f"{name}, noise {k}%", record["noise"][k][name],
                                               None) for k in noises]
        learned = record["noise"][top][f"{name}+mod"]
        panels.append((f"{name}+mod, noise {top}%, {len(learned.cuts)} cuts", learned.final,
                       learned))
        for c, (title, res, learn) in enumerate(panels, start=1):
            ax = axes[r, c]
            P = res.paths
            for j in range(P.shape[1]):
                end = res.exit_step[j] if res.left[j] else P.shape[0] - 1
                color = "tab:blue" if res.success[j] else "tab:red"
                ax.plot(P[: end + 1, j, 0], P[: end + 1, j, 1], color=color, lw=0.6, alpha=0.7)
            if learn is not None:
                for cut in learn.cuts:
                    w, p = cut.normal, cut.point
                    t = np.array([-w[1], w[0]])
                    seg = p + np.outer(np.linspace(-2 * W, 2 * W, 2), t)
                    ax.plot(seg[:, 0], seg[:, 1], color="tab:cyan", lw=1.2)
                for _, last, out in learn.failures:
                    ax.plot(*last, "o", color="gold", mec="k", ms=5, zorder=5)
                    ax.plot(*out, "x", color="tab:red", ms=6, mew=2, zorder=5)
            ax.set_title(f"{title}: {_pct(float(res.success.mean()))}%", fontsize=9)
        for c in range(ncols):
            axes[r, c].plot(*goal, "o", color="tab:orange", mec="k", ms=8, zorder=6)
    fig.suptitle("Single-mode rollouts (cf. paper Fig. 5): blue = success, red = failure; "
                 "cyan = cuts, yellow = last in-mode state, red x = failure state", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def _plot_curve(summary: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    noises = [str(p) for p in summary["config"]["noise_percent"]]
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), sharey=True)
    colors = ["tab:green", "tab:blue", "tab:red", "tab:purple", "tab:brown"]
    for ax, p in zip(axes, ("DS+mod", "BC+mod"), strict=True):
        for k, col in zip(noises, colors, strict=False):
            cur = summary["curve"][p][k]
            L = 11  # a study that stopped early keeps its last value

            def pad(v: list[float], L: int = L) -> FloatArray:
                return 100 * np.array((v + [v[-1]] * L)[:L])

            xs = np.arange(L)
            ax.plot(xs, pad(cur["mean"]), color=col, lw=2, marker="o", ms=3,
                    label=f"noise {k}%")
            ax.fill_between(xs, pad(cur["q25"]), pad(cur["q75"]), color=col, alpha=0.2)
        ax.set_title(p)
        ax.set_xlabel("number of cuts")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("success rate (%)")
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle("Success vs. number of cuts (cf. paper Fig. 6 right): mean, shaded IQR",
                 fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)


def write_outputs(
    summary: dict[str, Any], record: dict[str, Any] | None, out_dir: Path, *,
    figures: bool = True,
) -> list[Path]:
    """Write ``single_mode.json``, ``single_mode.md`` and the PNG figures (atomically).

    Parameters
    ----------
    summary : dict
        From :func:`summarize`.
    record : dict or None
        Figure data of one trial (from :func:`run`); no rollout figure without it.
    out_dir : Path
    figures : bool, optional
        Write the PNG figures.

    Returns
    -------
    list of Path
        The files written (JSON, Markdown, then figures).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    figs: list[str] = []
    if figures:
        curve_png = out_dir / "single_mode_cuts.png"
        _plot_curve(summary, curve_png)
        written.append(curve_png)
        figs.append(curve_png.name)
    if figures and record is not None:
        roll_png = out_dir / "single_mode_rollouts.png"
        _plot_rollouts(record, roll_png)
        written.append(roll_png)
        figs.append(roll_png.name)
    js = out_dir / "single_mode.json"
    atomic_write_text(js, canonical_json(summary))
    md = out_dir / "single_mode.md"
    atomic_write_text(md, markdown(summary, figures=figs))
    return [js, md, *written]

