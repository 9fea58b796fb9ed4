"""Bit-identity check of the Franka loop across code versions (speed work must not change a bit).

``dump`` runs Panda trials (seeds 0, 1, 13 by default, each nominal and with its seeded
perturbations, a fresh executive each) and saves, per trial, every physics state after every
``mj_step`` / ``mj_step2`` (``mj_getState(..., mjSTATE_INTEGRATION)``: positions, velocities,
warm start, the motors' torques, the applied wrenches -- the rig's construction included), what
the robot saw and commanded each control period (:class:`~tli_verify.sim.loop.TraceStep`) and
the trial's JSON record without its wall time. ``compare`` says whether two dumps are equal
array by array (``np.array_equal``; exit 1 if not). Run ``dump`` once with each version on the
path, e.g. a checkout of main at ``/tmp/main``::

    PYTHONPATH=/tmp/main .venv/bin/python scripts/trial_fingerprint.py dump /tmp/ref.npz
    PYTHONPATH=. .venv/bin/python scripts/trial_fingerprint.py dump /tmp/new.npz
    .venv/bin/python scripts/trial_fingerprint.py compare /tmp/ref.npz /tmp/new.npz

``--awake`` runs the scene without island sleeping (the benchmark's comparison scene).
The trials run the loop's defaults (since issue 34: the passive-DS law and the robot's
sensors); ``--controller tracking --sensors ideal`` runs the loop of before, for a comparison
with a version older than that (which has neither option: leave them out there).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np


def dump(out: str, seeds: list[int], *, awake: bool = False,
         controller: str | None = None, sensors: str | None = None) -> None:
    """Run the trials of ``seeds`` (nominal and perturbed) and save their fingerprints to
    ``out`` (``.npz``; module doc)."""
    import mujoco

    import tli_verify
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import TraceStep, run_trial
    from tli_verify.sim.scene import PhysicsOptions

    print(f"tli_verify from {tli_verify.__file__}", file=sys.stderr)
    sig = mujoco.mjtState.mjSTATE_INTEGRATION
    states: list[np.ndarray] = []
    step, step2 = mujoco.mj_step, mujoco.mj_step2

    def grab(m: Any, d: Any) -> None:
        s = np.empty(mujoco.mj_stateSize(m, sig))
        mujoco.mj_getState(m, d, s, sig)
        states.append(s)

    def step_recorded(m: Any, d: Any, nstep: int = 1) -> None:
        step(m, d, nstep)
        grab(m, d)

    def step2_recorded(m: Any, d: Any) -> None:
        step2(m, d)
        grab(m, d)

    arrays: dict[str, Any] = {}
    mujoco.mj_step, mujoco.mj_step2 = step_recorded, step2_recorded  # the rigs look them up
    try:
        for seed in seeds:
            for perturbed in (False, True):
                states.clear()
                trace: list[TraceStep] = []
                extra: dict[str, Any] = {}
                if controller is not None:
                    extra["controller"] = controller
                if sensors is not None:
                    extra["sensors"] = sensors
                res = run_trial(load_policy("LTL-DS"), seed,
                                perturbations=None if perturbed else [], trace=trace,
                                physics=PhysicsOptions(sleep=False) if awake else None,
                                **extra)
                record = res.to_dict()
                record.pop("wall_time")
                key = f"s{seed}_{'perturbed' if perturbed else 'nominal'}"
                arrays[f"{key}_json"] = np.frombuffer(
                    json.dumps(record, sort_keys=True).encode(), dtype=np.uint8)
                arrays[f"{key}_states"] = np.array(states)
                arrays[f"{key}_trace"] = np.array(
                    [[s.time, *s.target, *s.measured, s.perturbed] for s in trace])
                arrays[f"{key}_modes"] = np.frombuffer(
                    "".join(s.mode for s in trace).encode(), dtype=np.uint8)
                print(f"{key}: {len(states)} physics states, {record['mode_sequence']}, "
                      f"{record['delivered']} delivered", file=sys.stderr)
    finally:
        mujoco.mj_step, mujoco.mj_step2 = step, step2
    np.savez_compressed(out, **arrays)


def compare(a: str, b: str) -> bool:
    """Whether the dumps ``a`` and ``b`` are equal array by array (printed per array)."""
    x, y = np.load(a), np.load(b)
    ok = sorted(x.files) == sorted(y.files)
    if not ok:
        print(f"different trials: {sorted(set(x.files) ^ set(y.files))}")
    for key in sorted(set(x.files) & set(y.files)):
        same = x[key].shape == y[key].shape and bool(np.array_equal(x[key], y[key]))
        ok &= same
        print(f"{key:28s} {x[key].shape!s:18s} {'equal' if same else 'DIFFERENT'}")
    print("all equal" if ok else "MISMATCH")
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("dump", help="run the trials and save their fingerprints")
    d.add_argument("out", metavar="OUT.npz")
    d.add_argument("--seeds", default="0,1,13", help="comma-separated (default 0,1,13)")
    d.add_argument("--awake", action="store_true", help="no island sleeping")
    d.add_argument("--controller", choices=("passive", "tracking"), default=None,
                   help="the Panda's control law (default: the loop's)")
    d.add_argument("--sensors", choices=("franka", "ideal"), default=None,
                   help="the sensor model (default: the loop's)")
    c = sub.add_parser("compare", help="compare two dumps")
    c.add_argument("a", metavar="A.npz")
    c.add_argument("b", metavar="B.npz")
    args = ap.parse_args(argv)
    if args.command == "dump":
        dump(args.out, [int(s) for s in args.seeds.split(",")], awake=args.awake,
             controller=args.controller, sensors=args.sensors)
        return 0
    return 0 if compare(args.a, args.b) else 1


if __name__ == "__main__":
    sys.exit(main())
