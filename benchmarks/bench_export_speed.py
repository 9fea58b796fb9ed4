"""One control step of the exported policy in C against the Python runtime (issue 36).

The step a 1 kHz controller calls: the automaton update on the reading, the stall rule's test
(``tli_verify.runtime.stall``, as the Franka artifact carries it) and the modulated
LPV-DS, at ``n = 7`` with ``K = 10`` components per DS and 3 cuts on the DS being run (the
written task of ``tests/support/ndtask.py``, certified at dt = 1/100). The same 2,000 states
(around the attractor of the DS run, most of them inside its cuts, so eq. 7 and the guard's
screen run on every step) and the same reading go through

- the C evaluator (``tli_verify/deploy/c``, built with the system compiler, ``-O2
  -ffp-contract=off``), timed inside C (``clock_gettime``; no Python in the loop): median over
  repeats of the mean step time;
- the Python executive (:class:`~tli_verify.runtime.executive.LTLDSPolicy.step`).

The C velocities are checked against Python's on every state first (ctypes binding), and the
fraction of states where the corner guard's projection ran is reported.
"""

from __future__ import annotations

import json
import platform
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.io import atomic_write_text

HARNESS = r"""
#define _POSIX_C_SOURCE 199309L
#include "tli_policy.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
int main(int argc, char **argv) {
    char err[512];
    tli_policy *p;
    tli_step_info info;
    int n, N, r, i, R;
    double *X, v[TLI_MAX_DIM], sink = 0.0;
    FILE *f;
    if (argc != 4) return 1;
    R = atoi(argv[3]);
    if (tli_policy_load(argv[1], &p, err, sizeof err)) { fprintf(stderr, "%s\n", err); return 2; }
    n = tli_policy_dim(p);
    f = fopen(argv[2], "rb");
    fseek(f, 0, SEEK_END); N = (int)(ftell(f) / (long)(8 * n)); fseek(f, 0, SEEK_SET);
    X = malloc(sizeof(double) * (size_t)N * (size_t)n);
    if (fread(X, 8, (size_t)N * (size_t)n, f) != (size_t)N * (size_t)n) return 3;
    fclose(f);
    tli_policy_reset(p, X, 0, &info);
    for (r = 0; r < R; r++) {
        struct timespec a, b;
        clock_gettime(CLOCK_MONOTONIC, &a);
        for (i = 0; i < N; i++) {
            tli_policy_step(p, X + (size_t)i * n, 0, 0, v, &info);
            sink += v[0];
        }
        clock_gettime(CLOCK_MONOTONIC, &b);
        printf("%.3f\n", ((double)(b.tv_sec - a.tv_sec) * 1e9
                          + (double)(b.tv_nsec - a.tv_nsec)) / N);
    }
    fprintf(stderr, "%g\n", sink);
    tli_policy_free(p);
    return 0;
}
"""


def _build(tmp: Path) -> Path:
    from tests.support.cpolicy import CFLAGS, c_source_dir, compiler

    cc = compiler()
    if cc is None:
        raise RuntimeError("no system C compiler (cc/gcc)")
    (tmp / "bench.c").write_text(HARNESS)
    exe = tmp / "bench_step"
    subprocess.run([cc, *CFLAGS, "-I", str(c_source_dir()), "-o", str(exe), str(tmp / "bench.c"),
                    str(c_source_dir() / "tli_policy.c"), "-lm"], check=True,
                   capture_output=True, text=True)
    return exe


def measure(n: int = 7, K: int = 10, cuts: int = 3, states: int = 2000, seed: int = 0
            ) -> dict[str, Any]:
    """Time one control step in C and in Python on the same states; check they agree."""
    from threadpoolctl import threadpool_limits

    from tests.support.cpolicy import build, library
    from tests.support.ndtask import write_nd
    from tli_verify.deploy.export import build_artifact, write_artifact
    from tli_verify.runtime.stall import StallRule

    with tempfile.TemporaryDirectory() as d, threadpool_limits(1):
        tmp = Path(d)
        nd = write_nd(tmp, n, K=K, seed=seed, cuts=cuts)
        art = build_artifact(nd.setup, goal_modes=("d",), goal_inputs=(),
                             sources={k: None for k in ("spec", "model", "certificate",
                                                        "task", "evidence")},
                             stall=StallRule())
        ex = write_artifact(art, tmp / "bench.tli.json")
        mm = nd.model.modes["a"]
        rng = np.random.default_rng(seed)
        lib = library(build(tmp))
        exe = _build(tmp)
        sets = {"around x*": mm.ds.attractor + rng.normal(scale=0.25, size=(states, n)),
                "at corners": _corners(mm, rng, states)}
        rows = {}
        for name, X in sets.items():
            rows[name] = _one_set(X, tmp, ex, exe, lib, nd, mm)
    return {"n": n, "K": K, "cuts": cuts, "states": states, "sets": rows,
            "machine": platform.machine(), "target_us": 5.0}


def _corners(mm: Any, rng: np.random.Generator, count: int) -> np.ndarray:
    """States within 1e-4 of two of the DS's cut planes at once (where eq. 7's velocity
    may push out through the other plane and the guard's projection runs)."""
    W = np.array([c.normal for c in mm.cuts])
    h = np.array([c.offset(mm.ds.attractor) for c in mm.cuts])
    n = W.shape[1]
    out = []
    while len(out) < count:
        i, j = rng.choice(len(W), size=2, replace=False)
        W2 = W[[i, j]]
        target = h[[i, j]] - rng.uniform(0.0, 1e-4, size=2)
        base = W2.T @ np.linalg.solve(W2 @ W2.T, target)
        null = rng.normal(scale=0.1, size=n)
        null -= W2.T @ np.linalg.solve(W2 @ W2.T, W2 @ null)
        x = mm.ds.attractor + base + null
        if mm.modulator.gamma(x[None])[0] <= 1.0:
            out.append(x)
    return np.array(out)


def _one_set(X: np.ndarray, tmp: Path, ex: Any, exe: Path, lib: Any, nd: Any, mm: Any
             ) -> dict[str, float]:
    from tests.support.cpolicy import CPolicy
    from tli_verify.runtime.executive import LTLDSPolicy

    states = X.shape[0]
    X.astype("<f8").tofile(tmp / "states.bin")
    # agreement first (ctypes), and how often the guard's projection runs
    c = CPolicy(lib, ex.text_path)
    from tli_verify.runtime.stall import StallRule

    pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01)
    pol.stall_rule = StallRule()  # as deployed: its V test runs every step, on both sides
    pol.reset(X[0], {})
    c.reset(X[0], 0)
    worst, guard, inside = 0.0, 0, 0
    for x in X:
        v_py = pol.step(x, {})
        c.decide(x, 0)
        v_c = c.velocity()
        worst = max(worst, float(np.max(np.abs(v_py - v_c))
                                 / max(1.0, float(np.max(np.abs(v_py))))))
        eq7 = mm.modulator.eq5(x[None], mm.ds.velocity(x)[None])[0]
        guard += int(not np.array_equal(eq7, v_py))
        inside += int(mm.modulator.gamma(x[None])[0] <= 1.0)
    # C, timed in C
    out = subprocess.run([str(exe), str(ex.text_path), str(tmp / "states.bin"), "15"],
                         check=True, capture_output=True, text=True).stdout.split()
    c_ns = float(np.median([float(v) for v in out]))
    # Python
    times = []
    for _ in range(5):
        pol.reset(X[0], {})
        t0 = time.perf_counter()
        for x in X:
            pol.step(x, {})
        times.append((time.perf_counter() - t0) / states)
    py_us = float(np.median(times)) * 1e6
    return {"c_us": c_ns / 1e3, "python_us": py_us, "speedup": py_us / (c_ns / 1e3),
            "max_rel_diff": worst, "guard_fraction": guard / states,
            "inside_fraction": inside / states}


def main(out_dir: Path) -> str:
    r = measure()
    atomic_write_text(out_dir / "export_speed.json", json.dumps(r, indent=2, sort_keys=True)
                      + "\n")
    lines = [
        "## Exported policy: one control step, C evaluator vs Python runtime",
        "",
        f"Automaton update + the stall rule's test + modulated LPV-DS, n = {r['n']}, "
        f"K = {r['K']} components, "
        f"{r['cuts']} cuts on the DS run (the written task of tests/support/ndtask.py); "
        f"the same {r['states']} states and reading for both: around the DS's attractor, and "
        "at corners (within 1e-4 of two cut planes, where the corner guard may project). C "
        "timed inside C (clock_gettime, median of 15 passes), Python median of 5 passes; one "
        f"core ({r['machine']}). Target: <= {r['target_us']:g} us per step in C.",
        "",
        "| states | inside the cuts | guard's projection ran | C per step | Python per step "
        "| speed-up | max rel. velocity diff |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, row in r["sets"].items():
        lines.append(f"| {name} | {100 * row['inside_fraction']:.0f}% | "
                     f"{100 * row['guard_fraction']:.1f}% | {row['c_us']:.2f} us | "
                     f"{row['python_us']:.0f} us | {row['speedup']:.0f}x | "
                     f"{row['max_rel_diff']:.1e} |")
    lines += ["", "Reproduce: `python -m benchmarks --only export_speed` (writes this table and "
              "export_speed.json)."]
    return "\n".join(lines) + "\n"
