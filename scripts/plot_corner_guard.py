"""Draw why the corner guard exists: ``docs/img/corner_guard.png``.

The 3D case hypothesis found (``tests/unit/test_modulation.py::
test_mixed_corner_eq5_leaves_guard_stays``): ``x* = 0``, ``P = I``, a stable linear DS, the
regular cut ``x <= 0.5`` and the cut ``y <= 0`` through ``x*``. Both planes are vertical, so the
picture is the (x, y) projection: paper eq. 7 alone slides into the corner and out of the cuts;
eq. 7 with the guard stays inside and converges. Right: ``V = |x - x*|^2`` along both.

Usage: ``.venv/bin/python scripts/plot_corner_guard.py [--out docs/img/corner_guard.png]``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import Modulator

A = np.array([[-0.3, 0.0, -1.0], [0.0, -0.3, -1.0], [1.0, 1.0, -0.3]])
CUTS = [Cut(np.array([1.0, 0.0, 0.0]), np.array([0.5, 0.0, 0.0])),
        Cut(np.array([0.0, 1.0, 0.0]), np.zeros(3))]
X0 = np.array([[-1.0, -1.0, -1.0]]) * 2.999 / np.sqrt(3.0)
DT, T = 2e-3, 12.0


def _integrate(step: str) -> np.ndarray:
    """Euler path, shape (steps + 1, 3); stops following a path once it is 0.3 outside."""
    mod = Modulator.build(CUTS, np.zeros(3), lyapunov=np.eye(3))
    x = X0.copy()
    path = [x[0].copy()]
    for _ in range(round(T / DT)):
        f = x @ A.T
        v = mod.eq5(x, f) if step == "eq5" else mod(x, f, dt=DT)
        x = x + DT * v
        path.append(x[0].copy())
        if mod.gamma(x)[0] > 1.3:
            break
    return np.array(path)


def main(argv: list[str] | None = None) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    parser = argparse.ArgumentParser(prog="plot_corner_guard.py")
    parser.add_argument("--out", type=Path, default=Path("docs/img/corner_guard.png"))
    args = parser.parse_args(argv)
    eq5, guarded = _integrate("eq5"), _integrate("guard")
    fig, (ax, axz, axv) = plt.subplots(1, 3, figsize=(14, 4.4),
                                       gridspec_kw={"width_ratios": [1.1, 1.1, 1]})
    for axis, (xl, yl) in ((ax, ((-2.2, 1.6), (-2.2, 1.2))),
                           (axz, ((-0.25, 0.75), (-0.45, 0.3)))):
        axis.fill_between([-2.2, 0.5], -2.2, 0.0, color="0.93", label="inside both cuts")
        axis.plot([0.5, 0.5], [-2.2, 1.2], color="c", lw=2)
        axis.plot([-2.2, 1.6], [0.0, 0.0], color="c", lw=2,
                  label="cuts: x <= 0.5, and y <= 0 (holds x*)")
        axis.plot(eq5[:, 0], eq5[:, 1], color="tab:red", lw=1.5, label="eq. 7 alone: leaves")
        axis.plot(guarded[:, 0], guarded[:, 1], color="tab:blue", lw=1.5,
                  label="eq. 7 + corner guard: stays")
        axis.plot(0.0, 0.0, "o", color="orange", mec="k", ms=9, label="x*")
        axis.set_xlim(*xl)
        axis.set_ylim(*yl)
        axis.set_aspect("equal")
        axis.set_xlabel("x")
        axis.set_ylabel("y")
    ax.plot(*X0[0, :2], "ko", ms=5)
    ax.set_title("3D linear DS, (x, y) projection")
    axz.set_title("zoom on the corner")
    ax.legend(loc="lower right", fontsize=7.5)
    for path, color, name in ((eq5, "tab:red", "eq. 7 alone"),
                              (guarded, "tab:blue", "with guard")):
        t = DT * np.arange(path.shape[0])
        axv.semilogy(t, np.sum(path**2, axis=1), color=color, label=name)
    axv.set_xlabel("t (s)")
    axv.set_ylabel("V = |x - x*|^2")
    axv.set_title("V decreases along both (Thm. 1 (b))")
    axv.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, args.out, dpi=110)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
