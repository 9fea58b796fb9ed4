"""The runtime: modulator cache, the batched rollout engine, the executive's step rate.

Side by side in one run (one core; ``threadpoolctl`` limits BLAS to one thread):

- single-state ``Model.velocity`` latency with 10 cuts (2-D, K = 10 components), *before*
  (the modulator rebuilt on every call, as ``ModeModel.velocity`` did: the DS plus
  :func:`tli_verify.boundary.modulation.modulate`) and *after* (the modulator cached on the
  ``ModeModel``, built once per cut set); the outputs must agree exactly;
- the rollout engine (:func:`tli_verify.runtime.rollout.rollout`): policy steps per second of
  the modulated DS batched over 2,000 starts, against a per-step Python loop over the same
  policy, one start at a time (on 20 of the starts);
- the executive (:class:`tli_verify.runtime.executive.LTLDSPolicy`) in closed loop on a 3-mode
  chain world: one episode (per-step Python loop) and 500 episodes batched across starts
  (:func:`tli_verify.runtime.loop.run_episodes`).
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import modulate
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.model.serialize import model_from_dict
from tli_verify.model.types import Model


def _median_time(fn: Callable[[], object], repeats: int, inner: int = 1) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner)
    return float(np.median(times))


def _ds_entry(rng: np.random.Generator, x_star: np.ndarray, K: int) -> dict[str, Any]:
    n = x_star.size
    L = rng.uniform(-0.5, 0.5, (n, n))
    P = L @ L.T + 0.5 * np.eye(n)
    P = 0.5 * (P + P.T)
    comps = []
    for _ in range(K):
        S = rng.uniform(-1, 1, (n, n))
        R = rng.uniform(-0.5, 0.5, (n, n))
        A = np.linalg.solve(P, (S - S.T) - (R @ R.T + 0.3 * np.eye(n)))
        comps.append({"prior": 1.0 / K, "mean": (x_star + rng.uniform(-8, 8, n)).tolist(),
                      "cov": np.diag(rng.uniform(1, 4, n)).tolist(), "A": A.tolist()})
    comps[-1]["prior"] = 1.0 - sum(c["prior"] for c in comps[:-1])
    return {"attractor": x_star.tolist(), "P": P.tolist(), "components": comps, "cuts": []}


def _model_with_cuts(seed: int = 0, m: int = 10) -> Model:
    rng = np.random.default_rng(seed)
    x_star = np.array([10.0, 10.0])
    doc = {"schema_version": 1, "state_names": ["x0", "x1"], "spec": None,
           "modes": {"a": _ds_entry(rng, x_star, 10)}}
    model = model_from_dict(doc)
    for k in range(m):
        ang = 2 * np.pi * k / m + rng.uniform(-0.2, 0.2)
        w = np.array([np.cos(ang), np.sin(ang)])
        model = model.add_cut("a", Cut(normal=w, point=x_star + rng.uniform(4, 8) * w))
    return model


class _Chain:
    def reset(self, x0: np.ndarray) -> None:
        pass

    def read(self, x: np.ndarray) -> Mapping[str, bool]:
        return {"u": bool(0.0 <= x[0] < 4.0 and x[1] >= -2.0), "v": bool(x[0] >= 4.0)}


def _chain_policy(root: Path) -> Any:
    """The chain world of ``tests/integration/test_executive.py`` (certified at dt = 1/100)."""
    from tests.support.instances import CHAIN_SPEC
    from tli_verify.certification.certificate import issue_certificate, write_certificate
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import parse_spec
    from tli_verify.model.serialize import load_model, save_model
    from tli_verify.runtime.executive import LTLDSPolicy

    spec_text = CHAIN_SPEC
    i2 = [[1.0, 0.0], [0.0, 1.0]]

    def ds(mode: str, nxt: str | None, att: list[float], A: list[list[float]]) -> dict[str, Any]:
        return {"mode": mode, "next_mode": nxt, "attractor": att, "P": i2,
                "components": [{"prior": 1.0, "mean": att, "cov": i2, "A": A}], "cuts": []}

    (root / "specs").mkdir()
    (root / "specs" / "chain.toml").write_text(spec_text)
    doc = {"schema_version": 1, "state_names": ["x0", "x1"], "spec": "specs/chain.toml",
           "modes": {"a": ds("a", "b", [1.0, 3.0], [[-1.0, 0.0], [0.0, -1.0]]),
                     "b": ds("b", "c", [6.0, 0.0], [[-1.0, -1.0], [1.0, -1.0]]),
                     "c": ds("c", None, [6.0, 0.0], [[-1.0, 0.0], [0.0, -1.0]])}}
    mpath = root / "chain.model.json"
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = root / "chain.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    return LTLDSPolicy(synthesize(parse_spec(spec_text)), load_model(mpath), cpath)


def _scoop_steps(n: int) -> float:
    """Seconds for ``n`` executive steps on the shipped scoop model and certificate."""
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.runtime.executive import LTLDSPolicy

    root = Path(__file__).resolve().parents[1]
    pol = LTLDSPolicy(synthesize(load_spec(root / "specs" / "scoop.toml")),
                      load_model(root / "models" / "scoop.model.json"),
                      root / "certificates" / "scoop.cert.json")
    x = np.array([-5.0, 0.0])
    reading = {"r": False, "s": False, "t": False}
    pol.reset(x, reading)
    t0 = time.perf_counter()
    for _ in range(n):
        pol.step(x, reading)
    return time.perf_counter() - t0


def main(out_dir: Path) -> str:
    from threadpoolctl import threadpool_limits

    from tli_verify.runtime.loop import run_episode, run_episodes
    from tli_verify.runtime.rollout import cap_speed, rollout

    results: dict[str, Any] = {}
    with threadpool_limits(1):
        # -- single-state latency, before / after the modulator cache
        model = _model_with_cuts()
        mm = model.modes["a"]
        dt = 1e-3
        x = np.array([12.5, 8.0])

        def before() -> np.ndarray:
            F = mm.ds.velocity(x)
            return modulate(x[None, :], F[None, :], mm.cuts, mm.ds.attractor,
                            lyapunov=mm.ds.P, dt=dt)[0]

        def after() -> np.ndarray:
            return model.velocity(x, "a", dt=dt)

        same = bool(np.array_equal(before(), after()))
        t_before = _median_time(before, 7, inner=2000)
        t_after = _median_time(after, 7, inner=2000)
        t_nocut = _median_time(lambda: mm.ds.velocity(x), 7, inner=2000)
        # -- batched rollout vs a per-step loop over the same policy
        rng = np.random.default_rng(1)
        x_star = mm.ds.attractor
        starts = x_star + rng.uniform(-6, 6, (2000, 2))
        inside = lambda X: np.all(np.abs(X - x_star) <= 9.0, axis=1)  # noqa: E731
        policy = lambda X: model.velocity(X, "a", dt=0.01)  # noqa: E731
        steps = 300
        t0 = time.perf_counter()
        res = rollout(policy, starts, inside, x_star, dt=0.01, steps=steps, goal_tolerance=0.05)
        t_batch = time.perf_counter() - t0
        ends = np.where(res.reached | res.left, np.maximum(res.exit_step, 0), steps)
        batch_steps = int(ends.sum())
        few = starts[:20]
        t0 = time.perf_counter()
        loop_steps = 0
        for x0 in few:
            xx = x0.copy()
            for _ in range(steps):
                v = cap_speed(policy(xx[None, :]), 20.0)[0]
                xx = xx + 0.01 * v
                loop_steps += 1
                if not inside(xx[None, :])[0] or np.linalg.norm(xx - x_star) <= 0.05:
                    break
        t_loop = time.perf_counter() - t0
        # -- the executive in closed loop
        with tempfile.TemporaryDirectory() as tmp:
            pol = _chain_policy(Path(tmp))
            run_episode(pol.fork(), _Chain(), [-3.0, 4.0], steps=3000, speed_cap=20.0)
            t0 = time.perf_counter()
            one = run_episode(pol.fork(), _Chain(), [-3.0, 4.0], steps=3000, speed_cap=20.0)
            t_one = time.perf_counter() - t0
            r2 = np.random.default_rng(2)
            E = 500
            X0 = np.column_stack([r2.uniform(-5, -0.5, E), r2.uniform(-1.5, 5, E)])
            forks = [pol.fork() for _ in range(E)]
            t0 = time.perf_counter()
            many = run_episodes(forks, [_Chain() for _ in range(E)], X0, steps=3000,
                                speed_cap=20.0)
            t_many = time.perf_counter() - t0
            many_steps = sum(r.steps for r in many)
            many_ok = sum(r.success for r in many)
        # -- the executive's step on the shipped scoop model (mode a, 2,000 steps)
        t_scoop = _scoop_steps(2000)
    results.update(
        single_state_before_us=1e6 * t_before, single_state_after_us=1e6 * t_after,
        single_state_ds_only_us=1e6 * t_nocut, cache_outputs_identical=same,
        rollout_batched_steps_per_s=batch_steps / t_batch, rollout_batched_starts=len(starts),
        rollout_loop_steps_per_s=loop_steps / t_loop,
        episode_steps=one.steps, episode_ms=1e3 * t_one, episode_success=one.success,
        episodes_batched=E, episodes_batched_steps_per_s=many_steps / t_many,
        episodes_batched_success=many_ok, episodes_batched_seconds=t_many,
        scoop_2000_steps_ms=1e3 * t_scoop,
    )
    atomic_write_text(out_dir / "runtime.json", canonical_json(json.loads(json.dumps(results))))
    return (
        "## Runtime: modulator cache, rollout engine, executive\n\n"
        "2-D LPV-DS with K = 10 components and 10 cuts (single state and rollouts, control "
        "period 1 ms / 10 ms); the executive on the 3-mode chain world of "
        "`tests/integration/test_executive.py` (dt = 10 ms); medians, one core.\n\n"
        "| Measure | Result | Baseline | Note |\n|---|---|---|---|\n"
        f"| Single-state `Model.velocity`, 10 cuts | {1e6 * t_after:.0f} us (modulator "
        f"cached) | {1e6 * t_before:.0f} us (rebuilt per call) | DS alone "
        f"{1e6 * t_nocut:.0f} us; outputs identical: {'yes' if same else 'NO'} |\n"
        f"| Rollout engine, batched over {len(starts):,} starts | "
        f"{batch_steps / t_batch:,.0f} policy steps/s | {loop_steps / t_loop:,.0f} steps/s "
        f"(per-step Python loop, one start at a time) | "
        f"{(batch_steps / t_batch) / (loop_steps / t_loop):,.0f}x |\n"
        f"| Executive, one episode ({one.steps} steps, per-step loop) | {1e3 * t_one:.1f} ms "
        f"({one.steps / t_one:,.0f} steps/s) | - | success: {one.success} |\n"
        f"| Executive, {E} episodes batched across starts | "
        f"{many_steps / t_many:,.0f} policy steps/s | {one.steps / t_one:,.0f} steps/s (one "
        f"episode) | {t_many:.1f} s, {many_ok}/{E} reach the goal |\n"
        f"| Executive, 2,000 steps on the shipped scoop model (mode a) | {1e3 * t_scoop:.0f} ms"
        f" | goal <= 50 ms per ~2,000-step episode | {1e6 * t_scoop / 2000:.0f} us per step "
        "(automaton, monitor, DS; no world) |\n"
    )
