"""Check paper Lemma 2 on the scoop task: each mode's DS alone enters the next mode's region.

Lemma 2 (paper Sec. 5.1) needs the attractor ``x*_i`` of mode ``i`` strictly inside the sensor
region ``delta_j`` of the next mode ``j``: the DS then reaches ``delta_j`` in finite time from
every start, and the sensors report the transition the automaton waits for. This script learns
the scoop model from the bundled demonstrations (``demos/scoop_*.csv`` with ``specs/scoop.toml``,
:func:`tli_verify.model.learn.learn_model`), or loads a model file, draws random starts in each
mode's *true* region (the paper's scoop world, ``tasks/scoop.toml``), integrates the mode's
nominal DS alone (``f`` of paper eq. 4, no cuts; explicit Euler, vectorised over the starts) and
prints, per mode: the fraction of starts that enter the next mode's region within the horizon
and the worst entry time. A second table counts the components that satisfy the sampled-data
condition ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` at ``dt = 1 ms`` (floats, margin 1e-9) and
the smallest certified decay rate, for the learned model and the committed
``models/scoop.model.json``.

True regions: the paper's scoop task (``tasks/scoop.toml``, workspace
``[-8, 8]^2``); starts are uniform in the states where the world's sensors read the mode,
entry is membership of the next mode's colour region:

* ``a`` (reach, ``!r & !s & !t``): white, and pink or green with an empty spoon (all of the
  workspace but yellow); next ``b`` (``r``): yellow (``x2 <= -4``, outside the pink column);
* ``b`` (scoop, ``r``): yellow; next ``c`` (``s``): pink (``2 <= x1 <= 6``, ``x2 <= 6``);
* ``c`` (transport, ``s``): pink; next ``d`` (``t``): green (``2 <= x1 <= 6``, ``x2 > 6``).

Usage: ``.venv/bin/python scripts/lemma2_check.py [--model FILE] [--starts 300] [--seed 0]
[--dt 0.01] [--horizon 60] [--rate R]`` (``--rate 0``: learn with the old margin-only
learner). Exit 0 when every start of every mode enters the next region, 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from tli_verify.model.learn import learn_model
from tli_verify.model.serialize import load_model
from tli_verify.model.types import Model
from tli_verify.tasks.registry import find_task

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

ROOT = Path(__file__).resolve().parents[1]
WORLD = find_task("scoop")
"""The paper's scoop world: the true regions the starts are drawn from and entries are read in."""
MODE_REGION = {"a": "white", "b": "yellow", "c": "pink", "d": "green"}
"""The region each mode of ``specs/scoop.toml`` runs in (nominally)."""


def region(mode: str, X: FloatArray) -> BoolArray:
    """Membership of the true region of a scoop mode ``a``, ``b``, ``c`` or ``d``.

    Where the world's sensors read the mode's label: b yellow, c pink (with soup on the
    spoon), d green (soup delivered) -- :data:`MODE_REGION` -- and
    a everywhere else, i.e. white and also pink or green with an empty spoon (reached
    without scooping, or after a spill).
    """
    if mode not in MODE_REGION:
        raise ValueError(f"unknown scoop mode {mode!r}")
    if mode == "a":
        return np.asarray(~WORLD.in_region("yellow", X))
    return WORLD.in_region(MODE_REGION[mode], X)


NEXT = {"a": "b", "b": "c", "c": "d"}
"""The mode each scoop mode hands over to (the demonstrated sequence)."""


def sample_starts(mode: str, n: int, rng: np.random.Generator) -> FloatArray:
    """``n`` uniform random states of the mode's true region (in the workspace ``[-8, 8]^2``)."""
    lo, hi = np.array(WORLD.lo), np.array(WORLD.hi)
    out = np.empty((0, 2))
    while out.shape[0] < n:
        X = rng.uniform(lo, hi, size=(4 * n, 2))
        out = np.vstack([out, X[region(mode, X)]])
    return out[:n]


@dataclass(frozen=True, slots=True)
class EntryResult:
    """How the DS of one mode reaches the next mode's region.

    Attributes
    ----------
    mode, next_mode : str
    n_starts : int
    entered : int
        Starts whose trajectory entered the next region within the horizon.
    worst_time : float
        Largest entry time over the starts that entered (s); ``inf`` if none did.
    attractor_inside : bool
        Whether the DS's attractor itself lies in the next region.
    """

    mode: str
    next_mode: str
    n_starts: int
    entered: int
    worst_time: float
    attractor_inside: bool

    @property
    def fraction(self) -> float:
        """``entered / n_starts``."""
        return self.entered / self.n_starts


def entry_times(model: Model, mode: str, starts: FloatArray, *, dt: float, horizon: float
                ) -> FloatArray:
    """First time each trajectory of the mode's nominal DS is in the next mode's region.

    Parameters
    ----------
    model : Model
    mode : str
        ``a``, ``b`` or ``c``.
    starts : ndarray, shape (S, 2)
    dt : float
        Explicit Euler step (s).
    horizon : float
        Integration time (s).

    Returns
    -------
    ndarray, shape (S,)
        Entry times (s); ``inf`` where the trajectory never entered within the horizon.
    """
    ds = model.modes[model.key(mode)].ds
    nxt = NEXT[mode]
    X = np.array(starts, dtype=np.float64)
    times = np.full(X.shape[0], np.inf)
    active = np.ones(X.shape[0], dtype=bool)
    for step in range(int(np.ceil(horizon / dt)) + 1):
        hit = active & region(nxt, X)
        times[hit] = step * dt
        active &= ~hit
        if not active.any():
            break
        X[active] += dt * ds.velocity(X[active])
    return times


def check(model: Model, *, n_starts: int = 300, seed: int = 0, dt: float = 0.01,
          horizon: float = 60.0) -> list[EntryResult]:
    """Run :func:`entry_times` for modes ``a``, ``b``, ``c`` from random starts (seeded)."""
    rng = np.random.default_rng(seed)
    out = []
    for mode, nxt in NEXT.items():
        starts = sample_starts(mode, n_starts, rng)
        times = entry_times(model, mode, starts, dt=dt, horizon=horizon)
        ok = np.isfinite(times)
        attractor = model.modes[model.key(mode)].ds.attractor[None, :]
        out.append(EntryResult(mode, nxt, n_starts, int(ok.sum()),
                               float(times[ok].max()) if ok.any() else float("inf"),
                               bool(region(nxt, attractor)[0])))
    return out


def learn_bundled(**options: object) -> Model:
    """The scoop model learned from the bundled demonstrations and spec (not written)."""
    demos = sorted((ROOT / "demos").glob("scoop_*.csv"))
    with tempfile.TemporaryDirectory() as tmp:
        return learn_model(demos, out_path=Path(tmp) / "scoop.model.json",
                           spec_path=ROOT / "specs" / "scoop.toml", **options)  # type: ignore[arg-type]


def sampled_count(model: Model, dt: float = 1e-3, margin: float = 1e-9) -> tuple[int, int]:
    """Components (over all DS) with ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` (floats).

    Returns
    -------
    passing, total : int
    """
    from tli_verify.ds.lyapunov import sampled_growth

    passing = total = 0
    for mm in model.modes.values():
        for a in mm.ds.A:
            total += 1
            passing += sampled_growth(mm.ds.P, a[None], dt) < -margin
    return passing, total


def min_rate(model: Model) -> float:
    """Smallest certified decay rate over the model's DS (floats)."""
    from tli_verify.ds.lyapunov import decay_rate

    return min(decay_rate(mm.ds.P, mm.ds.A) for mm in model.modes.values())


def table(results: list[EntryResult]) -> str:
    """Markdown table of the results."""
    lines = ["| mode -> next | attractor in next region | entered | fraction | "
             "worst entry time (s) |", "|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r.mode} -> {r.next_mode} | {'yes' if r.attractor_inside else 'NO'} | "
                     f"{r.entered}/{r.n_starts} | {100 * r.fraction:.1f}% | "
                     f"{r.worst_time:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="lemma2_check.py")
    parser.add_argument("--model", type=Path, default=None,
                        help="model file (default: learn from demos/scoop_*.csv)")
    parser.add_argument("--starts", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--horizon", type=float, default=60.0)
    parser.add_argument("--rate", type=float, default=None,
                        help="learner decay rate (default: the learner's; 0: the old margin-only "
                        "learner)")
    args = parser.parse_args(argv)
    options = {} if args.rate is None else {"rate": args.rate}
    model = load_model(args.model) if args.model else learn_bundled(**options)
    results = check(model, n_starts=args.starts, seed=args.seed, dt=args.dt,
                    horizon=args.horizon)
    what = (str(args.model) if args.model else "learned from demos/scoop_*.csv"
            + ("" if args.rate is None else f" with rate {args.rate:g}"))
    sys.stdout.write(f"Lemma 2 on the scoop task ({what}; {args.starts} random starts per mode, "
                     f"seed {args.seed}, Euler dt {args.dt} s, horizon {args.horizon} s)\n\n")
    sys.stdout.write(table(results) + "\n")
    models = {what: model}
    committed = ROOT / "models" / "scoop.model.json"
    if args.model is None and committed.is_file():
        models = {"models/scoop.model.json (committed)": load_model(committed), **models}
    sys.stdout.write("\n| model | components with (I + dt A_k)^T P (I + dt A_k) < P at dt = 1 ms "
                     "| smallest certified decay rate (1/s) |\n|---|---|---|\n")
    for name, m in models.items():
        passing, total = sampled_count(m)
        sys.stdout.write(f"| {name} | {passing}/{total} | {min_rate(m):.3g} |\n")
    return 0 if all(r.entered == r.n_starts for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
