"""The Fig. 11-style picture of the Franka model: each mode's modulated DS flow with its cuts."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from tli_verify.io import atomic_write_bytes
from tli_verify.sim.demos import CONTROL_DT, pitch_column

__all__ = ["plot_flow"]


def plot_flow(model: Any, path: str | os.PathLike[str], *,
              demos: list[Any] | None = None, title: str = "") -> None:
    """A Fig. 11-style picture: each mode's modulated DS flow in (y, z, pitch), with the cuts.

    Streamlines: the certified DS of each mode (``model.modes[mode].velocity``, cuts
    included) integrated at the control period from a grid of starts around its demonstrated
    region (on a 6-D pose DS, also turned about roll and yaw by up to 0.1 rad: the flow
    straightens them), drawn in (y, z, pitch = ``ry``); the cut planes in the slice where the
    other coordinates are the attractor's; the learned cut planes of each mode drawn as
    patches of their hyperplane in that slice; the demonstrations in black.

    Parameters
    ----------
    model : Model
        E.g. ``policy.model`` after trials (with the cuts learned online).
    path : path-like
        PNG to write (atomically).
    demos : list of Demonstration, optional
    title : str, optional
    """
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"a": "tab:gray", "b": "tab:orange", "c": "tab:red", "d": "tab:green"}
    fig = plt.figure(figsize=(8, 6.5))
    ax = fig.add_subplot(projection="3d")
    rng = np.random.default_rng(0)
    for key, mm in sorted(model.modes.items()):
        mode = key.split("->")[0]
        x_star = mm.ds.attractor
        means = np.asarray(mm.ds.means)
        pc = pitch_column(len(x_star))
        scale = np.full(len(x_star), 0.1)
        scale[0], scale[1] = 0.0, 0.15
        starts = means[rng.integers(0, len(means), size=10)] + \
            rng.normal(scale=scale, size=(10, len(x_star)))
        starts[:, 0] = x_star[0]
        others = [k for k in range(len(x_star)) if k not in (1, 2, pc)]
        for z in starts:
            pts = [z.copy()]
            for _ in range(400):
                v = mm.velocity(pts[-1], dt=CONTROL_DT)
                pts.append(pts[-1] + CONTROL_DT * v)
            arr = np.array(pts)
            ax.plot(arr[:, 1], arr[:, 2], arr[:, pc], color=colors.get(mode, "b"), lw=0.8,
                    alpha=0.8)
        ax.scatter([x_star[1]], [x_star[2]], [x_star[pc]], color=colors.get(mode, "b"),
                   marker="*", s=120, edgecolor="k", label=f"mode {mode}: DS and x*")
        for cut in model.region_cuts(mode):
            n, p = np.asarray(cut.normal), np.asarray(cut.point)
            if abs(n[pc]) < 1e-9:
                continue
            u = np.linspace(-0.4, 0.4, 2)
            yy, zz = np.meshgrid(p[1] + u, p[2] + u)
            rest = sum(float(n[k] * (x_star[k] - p[k])) for k in others)
            pp = p[pc] - (n[1] * (yy - p[1]) + n[2] * (zz - p[2]) + rest) / n[pc]
            pp = np.clip(pp, -1.0, 2.0)  # a plane nearly along the pitch axis: clipped
            ax.plot_surface(yy, zz, pp, color=colors.get(mode, "b"), alpha=0.3)
    for demo in demos or []:
        pd = pitch_column(demo.x.shape[1])
        ax.plot(demo.x[:, 1], demo.x[:, 2], demo.x[:, pd], color="k", lw=1.2, alpha=0.7)
    ax.set_xlabel("y (dm)")
    ax.set_ylabel("z (dm)")
    ax.set_zlabel("pitch (rad)")
    ax.set_zlim(-1.0, 2.0)
    ax.set_title(title or "Modulated LTL-DS flow per mode (y, z, pitch) with learned cuts")
    ax.legend(loc="upper left", fontsize=8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
