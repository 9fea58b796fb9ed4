"""The MuJoCo soup-scooping scene with 30 beads: bare physics vs the LTL-DS closed loop.

Targets, measured side by side in one run, one core (``threadpoolctl``), CPU time
(``time.process_time``: the machine may be shared), for the free hand and for the Panda:

- **closed loop**: one nominal LTL-DS trial (:func:`tli_verify.sim.loop.run_trial`: sensors,
  :class:`~tli_verify.runtime.executive.LTLDSPolicy`, the rig's impedance law or the Panda's
  operational-space controller, ``mj_step``), its physics steps per CPU second. The rig's
  construction (scene compilation, bead settling, the Panda's move to the start) is timed
  separately and *not* counted: its steps are not in the trial's simulated time either;
- **bare ``mj_step`` on the same physical situation** (this comparison runs the *awake* scene,
  ``PhysicsOptions(sleep=False)``: replaying a sleeping scene is not its physics, since
  ``mj_setState`` wakes every body): every physics step of that trial is
  recorded (``mj_getState(..., mjSTATE_INTEGRATION)``: positions, velocities, warm start,
  controls, applied wrenches, mocap) in an untimed run, then replayed -- ``mj_setState`` +
  ``mj_step`` per recorded state, the ``mj_setState`` cost measured alone and subtracted. The
  replay is checked to reproduce the trial's trajectory exactly. (The old baseline timed the
  scene at rest, ladle held: a third fewer contacts in the constraint solver than while
  scooping, so the closed loop looked slower than it is.);
- **fraction** = closed-loop rate / bare rate, and the share of the closed loop's CPU time
  spent inside ``mj_step`` (``mj_step1`` + ``mj_step2`` for the Panda), measured in one more
  run with timers around the MuJoCo calls: the same states by construction (target >= 90%);
- **real-time factor** = simulated seconds / closed-loop CPU seconds (target >= 5x);
- ``TRIALS`` perturbed LTL-DS trials per robot (default 30; ``TLI_BENCH_FRANKA_TRIALS``, 0
  skips them) on 2 worker processes of one BLAS thread each (seeds split in two halves, each
  half with its own executive): wall time (target < 10 min on 2 cores) and the success count.

**Solver settings** (issue 21, item 7): for each :class:`~tli_verify.sim.scene.PhysicsOptions`
in ``TLI_BENCH_FRANKA_PHYSICS`` (default ``default,awake,cg,impratio1,awake+cg``; the default
sleeps, ``awake`` does not) the Panda's
nominal trial is measured as above, and the evidence's ``TRIALS`` perturbed trials (seeds
0..TRIALS-1, the same two halves) are run again: a setting keeps the outcomes when every seed
passes or fails as with the default (and the delivered beads are counted). The replay of a
sleeping scene is not the loop's physics (``mj_setState`` wakes every body), so for those rows
*bare* is the time inside ``mj_step`` in the loop itself.

Rates are medians of ``REPEATS`` runs (``TLI_BENCH_FRANKA_REPEATS``, default 3); the bare
replays and the closed-loop runs alternate, so both see the same load of a shared machine.
``TLI_BENCH_FRANKA_ROBOTS`` (default ``panda,free-tool``) picks the robots. The Panda rows need
the Menagerie assets (``make sim-assets``); without them they are skipped and say so.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import os
import sys
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_text, canonical_json

SEEDS = {"panda": 2, "free-tool": 1}
"""Bead placement of the nominal trial per robot."""
DURATION = 14.0
"""Step budget of the nominal trial (simulated seconds)."""


@dataclass
class Probe:
    """What the MuJoCo wrappers saw during one trial (construction excluded)."""

    record: bool
    timing: bool
    active: bool = False
    model: Any = None
    states: list[tuple[Any, int]] | None = None
    in_step: float = 0.0
    calls: int = 0
    build_cpu: float = 0.0


@contextlib.contextmanager
def probed(probe: Probe) -> Iterator[None]:
    """Wrap ``mujoco.mj_step`` / ``mj_step1`` / ``mj_step2`` and the rigs' constructors.

    The rigs call these through the ``mujoco`` module, so the wrappers see every physics step.
    A rig's constructor is timed (``probe.build_cpu``) and nothing is recorded while it runs;
    after it, each ``mj_step`` (and ``mj_step2``: the state then has the controller's torques)
    is recorded with its ``nstep`` when ``probe.record``, and the CPU time inside the MuJoCo
    calls is summed when ``probe.timing``.
    """
    import mujoco

    from tli_verify.sim import demos

    sig = mujoco.mjtState.mjSTATE_INTEGRATION
    saved = {name: getattr(mujoco, name) for name in ("mj_step", "mj_step1", "mj_step2")}
    inits = {cls: cls.__init__ for cls in (demos.MocapRig, demos.PandaRig)}
    clock = time.process_time

    def grab(m: Any, d: Any, nstep: int) -> None:
        if probe.record and probe.active:
            if probe.states is None:
                probe.states = []
                probe.model = m
            s = np.empty(mujoco.mj_stateSize(m, sig))
            mujoco.mj_getState(m, d, s, sig)
            probe.states.append((s, nstep))

    def timed(fn: Any, record: bool) -> Any:
        def call(m: Any, d: Any, nstep: int = 1) -> None:
            if record:
                grab(m, d, nstep)
            if not (probe.timing and probe.active):
                fn(m, d) if nstep == 1 else fn(m, d, nstep)
                return
            t0 = clock()
            fn(m, d) if nstep == 1 else fn(m, d, nstep)
            probe.in_step += clock() - t0
            probe.calls += 1
        return call

    def init_of(cls: Any) -> Any:
        orig = inits[cls]

        def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
            probe.active = False
            t0 = clock()
            orig(self, *args, **kwargs)
            probe.build_cpu += clock() - t0
            probe.active = True
        return __init__

    try:
        mujoco.mj_step = timed(saved["mj_step"], True)
        mujoco.mj_step1 = timed(saved["mj_step1"], False)
        mujoco.mj_step2 = timed(saved["mj_step2"], True)
        for cls in inits:
            cls.__init__ = init_of(cls)  # type: ignore[method-assign]
        yield
    finally:
        for name, fn in saved.items():
            setattr(mujoco, name, fn)
        for cls, fn in inits.items():
            cls.__init__ = fn  # type: ignore[method-assign]


PHYSICS_NAMES = {"default": {}, "awake": {"sleep": False}, "cg": {"solver": "cg"},
                 "impratio1": {"impratio": 1.0}, "awake+cg": {"sleep": False, "solver": "cg"}}
"""The solver settings the benchmark can measure (``TLI_BENCH_FRANKA_PHYSICS``)."""


def _physics(name: str) -> Any:
    from tli_verify.sim.scene import PhysicsOptions

    if name not in PHYSICS_NAMES:
        raise TliError(f"TLI_BENCH_FRANKA_PHYSICS: unknown setting {name!r} "
                       f"({', '.join(PHYSICS_NAMES)})")
    return PhysicsOptions(**PHYSICS_NAMES[name])  # type: ignore[arg-type]


def _trial(robot: str, probe: Probe, physics: Any = None) -> tuple[Any, float]:
    """One nominal LTL-DS trial with a fresh executive; its result and CPU seconds (the
    rig's construction excluded)."""
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import run_trial

    policy = load_policy("LTL-DS")  # fresh: cuts learned in an earlier run would change it
    with probed(probe):
        c0 = time.process_time()
        res = run_trial(policy, SEEDS[robot], perturbations=[], duration=DURATION, robot=robot,
                        physics=physics)
        cpu = time.process_time() - c0
    return res, cpu - probe.build_cpu


def _replay(model: Any, states: list[tuple[Any, int]], repeats: int
            ) -> tuple[float, float]:
    """Bare ``mj_step`` from each recorded state: median steps per CPU second over ``repeats``
    timed replays (NaN for none: :func:`_bare_rate` times them one by one), and the largest
    difference between a replayed step's result and the next recorded state (0: the replay
    is the trial's physics)."""
    import mujoco

    sig = mujoco.mjtState.mjSTATE_PHYSICS  # time, qpos, qvel, act: what a step produces
    data = mujoco.MjData(model)
    full = mujoco.mjtState.mjSTATE_INTEGRATION
    size = mujoco.mj_stateSize(model, sig)
    worst = 0.0
    got = np.empty(size)
    nxt = np.empty(size)
    probe_data = mujoco.MjData(model)
    for (s, n), (s2, _) in itertools.pairwise(states):
        mujoco.mj_setState(model, data, s, full)
        mujoco.mj_step(model, data, n)
        mujoco.mj_getState(model, data, got, sig)
        mujoco.mj_setState(model, probe_data, s2, full)
        mujoco.mj_getState(model, probe_data, nxt, sig)
        worst = max(worst, float(np.max(np.abs(got - nxt))))
    rates = [_bare_rate(model, states, data) for _ in range(repeats)]
    return (float(np.median(rates)) if rates else math.nan), worst


def _bare_rate(model: Any, states: list[tuple[Any, int]], data: Any = None) -> float:
    """One timed replay of ``states`` (``mj_setState`` + ``mj_step`` each, the
    ``mj_setState`` cost measured alone and subtracted): steps per CPU second."""
    import mujoco

    full = mujoco.mjtState.mjSTATE_INTEGRATION
    data = mujoco.MjData(model) if data is None else data
    steps = sum(n for _, n in states)
    c0 = time.process_time()
    for s, n in states:
        mujoco.mj_setState(model, data, s, full)
        mujoco.mj_step(model, data, n)
    total = time.process_time() - c0
    c0 = time.process_time()
    for s, _n in states:
        mujoco.mj_setState(model, data, s, full)
    return steps / (total - (time.process_time() - c0))


def _measure(robot: str, repeats: int, physics: Any = None) -> dict[str, Any]:
    """The side-by-side numbers of one robot (module doc) under ``physics``."""
    rec = Probe(record=True, timing=False)
    res0, _ = _trial(robot, rec, physics)
    if rec.states is None:  # pragma: no cover - a rig that never steps
        raise TliError(f"bench_franka_scene: no physics step recorded for {robot}")
    dt = float(rec.model.opt.timestep)
    steps = sum(n for _, n in rec.states)
    if abs(steps * dt - res0.sim_time) > 0.5 * dt:  # pragma: no cover - a wrapper missed some
        raise TliError(f"bench_franka_scene: recorded {steps} steps of a {res0.sim_time} s "
                       "trial")
    _, replay_err = _replay(rec.model, rec.states, 0)
    bares, cpus, builds, modes = [], [], [], set()
    for _ in range(repeats):  # bare and closed loop interleaved: both see the machine's load
        bares.append(_bare_rate(rec.model, rec.states))
        probe = Probe(record=False, timing=False)
        res, cpu = _trial(robot, probe, physics)
        cpus.append(cpu)
        builds.append(probe.build_cpu)
        modes.add((res.mode_sequence(), round(res.sim_time / dt)))
    bare = float(np.median(bares))
    timing = Probe(record=False, timing=True)
    res_t, cpu_t = _trial(robot, timing, physics)
    modes.add((res_t.mode_sequence(), round(res_t.sim_time / dt)))
    cpu = float(np.median(cpus))
    closed = steps / cpu
    return {
        "robot": robot, "seed": SEEDS[robot], "timestep_s": dt, "physics_steps": steps,
        "sim_time_s": res0.sim_time, "mode_sequence": res0.mode_sequence(),
        "same_trial_every_run": modes == {(res0.mode_sequence(), steps)},
        "bare_steps_per_s": bare, "bare_realtime_factor": bare * dt,
        "replay_max_abs_diff": replay_err,
        "closed_loop_cpu_s": cpu, "closed_loop_cpu_s_runs": cpus,
        "closed_loop_steps_per_s": closed, "closed_over_bare": closed / bare,
        "real_time_factor": res0.sim_time / cpu,
        "rig_build_cpu_s": float(np.median(builds)),
        "end_to_end_real_time_factor": res0.sim_time / (cpu + float(np.median(builds))),
        "share_in_mj_step": timing.in_step / cpu_t,
        "non_physics_us_per_step": 1e6 * (cpu_t - timing.in_step) / steps,
        "mj_step_us_per_step": 1e6 * timing.in_step / steps,
    }


def _trials_one_core(seeds: list[int], robot: str, physics: str = "default"
                     ) -> list[dict[str, Any]]:
    """:func:`tli_verify.sim.loop.run_trials` with one BLAS thread (a worker = one core)."""
    from threadpoolctl import threadpool_limits

    from tli_verify.sim.loop import run_trials

    with threadpool_limits(1):
        return run_trials(seeds, robot=robot, physics=_physics(physics))


def _campaign(trials: int, robot: str, physics: str = "default"
              ) -> tuple[float, list[dict[str, Any]]]:
    """``trials`` perturbed trials on 2 workers: wall seconds and the trials' records in seed
    order."""
    t0 = time.perf_counter()
    halves = [list(range(0, trials, 2)), list(range(1, trials, 2))]
    with ProcessPoolExecutor(2) as pool:
        recs = [r for part in pool.map(_trials_one_core, halves, [robot] * 2, [physics] * 2)
                for r in part]
    return time.perf_counter() - t0, sorted(recs, key=lambda r: int(r["seed"]))


def _physics_rows(names: list[str], repeats: int, trials: int,
                  default_trials: list[dict[str, Any]] | None) -> list[dict[str, Any]]:
    """The solver-settings table's rows (module doc): the Panda's nominal trial under each
    setting and, with ``trials``, the evidence's perturbed trials compared with the default."""
    rows = []
    for name in names:
        r = _measure("panda", repeats, _physics(name))
        row: dict[str, Any] = {"setting": name, **{k: r[k] for k in (
            "real_time_factor", "share_in_mj_step", "mj_step_us_per_step",
            "non_physics_us_per_step", "sim_time_s", "mode_sequence", "closed_over_bare",
            "replay_max_abs_diff")}}
        if trials > 0:
            wall: float | None = None  # the default's trials are the campaign's own
            if name == "default" and default_trials is not None:
                recs = default_trials
            else:
                wall, recs = _campaign(trials, "panda", name)
            row["campaign_wall_s"] = wall
            row["successes"] = sum(bool(x["success"]) for x in recs)
            row["delivered"] = sum(int(x["delivered"]) for x in recs)
            row["trials"] = len(recs)
            if default_trials is not None:
                row["same_outcomes"] = sum(
                    bool(a["success"]) == bool(b["success"])
                    for a, b in zip(recs, default_trials, strict=True))
                row["changed_seeds"] = [int(a["seed"]) for a, b in zip(
                    recs, default_trials, strict=True) if bool(a["success"]) != bool(b["success"])]
        rows.append(row)
        print(f"bench_franka_scene: {row}", file=sys.stderr, flush=True)  # partial results
    return rows


def main(out_dir: Path) -> str:
    import threadpoolctl

    from tli_verify.errors import AssetError

    trials = int(os.environ.get("TLI_BENCH_FRANKA_TRIALS", "30"))
    repeats = max(1, int(os.environ.get("TLI_BENCH_FRANKA_REPEATS", "3")))
    robots = [r.strip() for r in os.environ.get(
        "TLI_BENCH_FRANKA_ROBOTS", "panda,free-tool").split(",") if r.strip()]
    physics = [p.strip() for p in os.environ.get(
        "TLI_BENCH_FRANKA_PHYSICS", ",".join(PHYSICS_NAMES)).split(",") if p.strip()]
    unknown = sorted(set(robots) - set(SEEDS))
    if unknown:
        raise TliError(f"TLI_BENCH_FRANKA_ROBOTS: unknown robot {unknown[0]!r} "
                       f"({', '.join(SEEDS)})")
    for name in physics:
        _physics(name)
    rows: dict[str, dict[str, Any]] = {}
    skipped: dict[str, str] = {}
    with threadpoolctl.threadpool_limits(1):
        for robot in robots:
            try:
                rows[robot] = _measure(robot, repeats, _physics("awake"))
            except AssetError as exc:  # the Menagerie Panda not fetched: say so
                skipped[robot] = str(exc)
    campaigns: dict[str, dict[str, float]] = {}
    panda_trials: list[dict[str, Any]] | None = None
    if trials > 0:
        for robot in rows:  # the robots whose rig could be built
            wall, recs = _campaign(trials, robot)
            ok = sum(bool(r["success"]) for r in recs)
            campaigns[robot] = {"trials": trials, "wall_s": wall, "successes": ok}
            if robot == "panda":
                panda_trials = recs
    options: list[dict[str, Any]] = []
    if "panda" in rows and physics:
        with threadpoolctl.threadpool_limits(1):
            options = _physics_rows(physics, repeats, trials, panda_trials)
    data = {"repeats": repeats, "robots": rows, "skipped": skipped, "campaigns": campaigns,
            "physics_options": options}
    atomic_write_text(out_dir / "franka_scene.json", canonical_json(data))
    return format_results(data)


def format_results(data: dict[str, Any]) -> str:
    """The Markdown section of a run's JSON record (``franka_scene.json``)."""
    repeats = data["repeats"]
    rows: dict[str, dict[str, Any]] = data["robots"]
    skipped: dict[str, str] = data["skipped"]
    campaigns: dict[str, dict[str, float]] = data["campaigns"]
    options: list[dict[str, Any]] = data["physics_options"]

    def ok_(v: bool) -> str:
        return "met" if v else "**not met**"

    names = {"free-tool": "free tool (impedance law in Python every step)",
             "panda": "Panda (operational-space controller every step)"}
    lines = ["| robot | bare `mj_step`, same states | closed loop | fraction of bare | "
             "in `mj_step` | non-physics per step | real-time factor | targets |",
             "|---|---:|---:|---:|---:|---:|---:|---|"]
    for robot, r in rows.items():
        lines.append(
            f"| {names[robot]} | {r['bare_steps_per_s']:,.0f} steps/s "
            f"({r['bare_realtime_factor']:.1f}x) | {r['closed_loop_steps_per_s']:,.0f} steps/s "
            f"| {r['closed_over_bare']:.0%} | {r['share_in_mj_step']:.0%} "
            f"| {r['non_physics_us_per_step']:.0f} us | {r['real_time_factor']:.1f}x "
            f"({r['end_to_end_real_time_factor']:.1f}x with the rig's construction) "
            f"| >= 90% of bare: {ok_(r['share_in_mj_step'] >= 0.9)} |")
    for robot, why in skipped.items():
        lines.append(f"| {names[robot]} | skipped: {why} | | | | | | |")
    notes = [
        "The comparison with bare `mj_step` runs the *awake* scene (replaying a sleeping scene "
        "is not its physics: `mj_setState` wakes every body); the scene's default sleeps (the "
        "settings table below).",
        f"Nominal trial per robot ({DURATION:g} s budget, seeds "
        f"{', '.join(f'{k} {v}' for k, v in SEEDS.items())}), 30 beads, one core, CPU time, "
        f"medians of {repeats} runs, bare and closed loop alternating. *Bare* = `mj_step` "
        "replayed from every recorded state of that trial (the same contacts), `mj_setState` "
        "cost subtracted; *closed loop* excludes the rig's construction (scene compilation, "
        "bead settling), as the trial's simulated time does.",
    ]
    for robot, r in rows.items():
        notes.append(
            f"{robot}: {r['physics_steps']} physics steps ({r['sim_time_s']:.2f} s, modes "
            f"{r['mode_sequence']}), replay reproduces the trial "
            f"(max |diff| {r['replay_max_abs_diff']:.1e}), same trial every run: "
            f"{r['same_trial_every_run']}, `mj_step` {r['mj_step_us_per_step']:.0f} us/step "
            f"inside the loop.")
    tail = "".join(
        f"| {c['trials']:.0f} perturbed LTL-DS trials, {names[robot].split(' (')[0]}, "
        f"2 workers | {c['wall_s']:.0f} s wall, {c['successes']:.0f}/{c['trials']:.0f} "
        f"delivered | < 600 s: {ok_(c['wall_s'] < 600)} |\n" for robot, c in campaigns.items())
    if not campaigns:
        tail = "| perturbed trials | skipped (`TLI_BENCH_FRANKA_TRIALS=0`) | < 600 s |\n"
    opt_lines = ""
    if options:
        opt_lines = (
            "\n### Solver settings on the Panda\n\n"
            "| setting | nominal trial | real-time factor | in `mj_step` | `mj_step` per step | "
            "non-physics per step | evidence trials passed | same outcome as default | "
            "beads delivered |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n")
        for o in options:
            same = (f"{o['same_outcomes']}/{o['trials']}"
                    + (f" (seeds {', '.join(map(str, o['changed_seeds']))} differ)"
                       if o.get("changed_seeds") else "")) if "same_outcomes" in o else "-"
            passed = f"{o['successes']}/{o['trials']}" if "successes" in o else "-"
            opt_lines += (
                f"| {o['setting']} | {o['sim_time_s']:.2f} s, {o['mode_sequence']} "
                f"| {o['real_time_factor']:.1f}x | {o['share_in_mj_step']:.0%} "
                f"| {o['mj_step_us_per_step']:.0f} us | {o['non_physics_us_per_step']:.0f} us "
                f"| {passed} | {same} | {o.get('delivered', '-')} |\n")
        opt_lines += (
            "\nA setting may become the default only if it keeps every outcome of the "
            "evidence's trials (the default's row is the evidence's own setting).\n")
        default = next((o for o in options if o["setting"] == "default"), None)
        if default is not None:
            opt_lines += (f"\nReal time with the default setting: "
                          f"{default['real_time_factor']:.1f}x; target >= 5x: "
                          f"{ok_(default['real_time_factor'] >= 5)}.\n")
    return (
        "## The soup-scooping scene in MuJoCo, 30 beads (`bench_franka_scene`)\n\n"
        + "\n".join(lines) + "\n\n" + "\n\n".join(notes) + "\n\n"
        "| measurement | value | target |\n|---|---:|---:|\n" + tail + opt_lines
    )
