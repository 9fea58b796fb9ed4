"""GR(1) realizability: tli-verify (our fixpoint on dd.cudd) vs omega, side by side.

Same specs, same run: the shipped specs and seeded random specs of 10 to 40 Boolean variables
(half inputs, half outputs). Times are medians over seeds and repeats, from a parsed spec to
the verdict (game construction included for both). Also the issue's latency goal: the scoop
spec, parse + realizability + automaton, warm.
"""

from __future__ import annotations

import contextlib
import io
import statistics
import sys
import time
from pathlib import Path
from typing import Any

from tli_verify.io import atomic_write_text
from tli_verify.logic.check import synthesize
from tli_verify.logic.escape import markdown_text
from tli_verify.logic.generate import RandomSpecConfig, chain_spec_text, random_spec
from tli_verify.logic.gr1 import build_game, solve
from tli_verify.logic.spec import GR1Spec, load_spec, parse_spec

REPO = Path(__file__).resolve().parents[1]
REPEATS = 5
SEEDS = 8


def _omega_solver() -> Any:
    sys.path.insert(0, str(REPO))
    from tests.support.omega_oracle import omega_realizable

    return omega_realizable


def _time(fn: Any, *args: Any) -> tuple[float, Any]:
    best = []
    result = None
    for _ in range(REPEATS):
        start = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            result = fn(*args)
        best.append(time.perf_counter() - start)
    return statistics.median(best), result


def _ours(spec: GR1Spec) -> bool:
    return solve(build_game(spec), keep_iterates=False).realizable


def main(out_dir: Path) -> str:
    omega = _omega_solver()
    rows = []
    # Shipped specs.
    for path in sorted((REPO / "specs").glob("*.toml")):
        spec = load_spec(path)
        t_ours, v_ours = _time(_ours, spec)
        t_omega, v_omega = _time(omega, spec)
        n_vars = len(spec.inputs) + len(spec.outputs)
        rows.append((path.name, n_vars, 1, t_ours, t_omega, v_ours == v_omega, int(v_ours)))
    # Random specs by size.
    for n_vars in (10, 20, 30, 40):
        half = n_vars // 2
        config = RandomSpecConfig(n_inputs=half, n_outputs=n_vars - half,
                                  n_env_safety=half // 2 + 1, n_sys_safety=half,
                                  n_env_live=2, n_sys_live=3, depth=3)
        ours_t, omega_t, agree, real = [], [], True, 0
        for seed in range(SEEDS):
            spec = random_spec(config, 7919 * n_vars + seed)
            t1, v1 = _time(_ours, spec)
            t2, v2 = _time(omega, spec)
            ours_t.append(t1)
            omega_t.append(t2)
            agree &= v1 == v2
            real += int(v1)
        rows.append((f"random, {n_vars} vars", n_vars, SEEDS, statistics.median(ours_t),
                     statistics.median(omega_t), agree, real))
    # Realizable task chains (like color tracing) of 11 to 41 variables.
    for n_modes in (5, 10, 15, 20):
        spec = parse_spec(chain_spec_text(n_modes))
        t_ours, v_ours = _time(_ours, spec)
        t_omega, v_omega = _time(omega, spec)
        rows.append((f"task chain, {n_modes} modes", 2 * n_modes + 1, 1, t_ours, t_omega,
                     v_ours == v_omega, int(v_ours)))
    # Scoop end to end, warm.
    scoop = REPO / "specs" / "scoop.toml"
    synthesize(load_spec(scoop))
    e2e = []
    for _ in range(20):
        start = time.perf_counter()
        synthesize(load_spec(scoop))
        e2e.append(time.perf_counter() - start)
    e2e_ms = statistics.median(e2e) * 1000

    lines = [
        "## GR(1) realizability: tli-verify vs omega",
        "",
        f"Median seconds from parsed spec to verdict ({REPEATS} repeats; random rows: median "
        f"over {SEEDS} seeded specs). Verdicts compared in the same run.",
        "",
        "| specs | vars | n | realizable | tli-verify (ms) | omega (ms) | speed-up | agree |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for name, n_vars, n, t1, t2, ok, real in rows:
        lines.append(f"| {markdown_text(name)} | {n_vars} | {n} | {real}/{n} | {t1 * 1000:.2f} | "
                     f"{t2 * 1000:.2f} | "
                     f"{t2 / t1:.1f}x | {'yes' if ok else 'NO'} |")
    lines += ["", f"Scoop spec, parse + realizability + automaton, warm: median "
              f"**{e2e_ms:.1f} ms** over 20 runs (goal: < 50 ms).", ""]
    section = "\n".join(lines)
    atomic_write_text(out_dir / "gr1.md", section + "\n")
    return section
