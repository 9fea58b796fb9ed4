"""``tli sim franka``: perturbed LTL-DS trials of soup scooping in MuJoCo (paper Sec. 7.2).

Before anything moves, the bundled Franka scoop model must be covered by its certificate
(``<certificates>/franka-scoop.cert.json``), exactly as the gate checks it: a missing, invalid
or tampered certificate, or a model it does not cover, is refused with exit 1 naming the
certificate.

Exit codes: 0 every trial delivered soup; 1 a trial did not (or the certificate refused);
2 bad arguments.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import int_range, output_path

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli sim``."""
    p = sub.add_parser(
        "sim", help="closed-loop LTL-DS trials in the MuJoCo soup-scooping scene",
        description="Physical soup scooping with beads: sensors from the physics, the "
        "certified LTL-DS executive, wrench perturbations (pushes and spilling tilts).")
    simsub = p.add_subparsers(dest="scene", metavar="SCENE")
    simsub.required = True
    f = simsub.add_parser(
        "franka", help="perturbed scooping trials (success: a bead ends in the target bowl)",
        description="Run N seeded, perturbed trials of the certified Franka scoop model. "
        "Exit 0: every trial delivered soup; 1: one did not, or the certificate refused the "
        "model; 2: bad arguments.")
    f.add_argument("--trials", type=int_range(1, 1000), default=1,
                   help="number of trials (default 1)")
    f.add_argument("--seed", type=int_range(0), default=0,
                   help="seed of the first trial (default 0)")
    f.add_argument("--certificates", type=Path, default=None, metavar="DIR",
                   help="certificates directory of a project holding "
                   "franka-scoop.cert.json, with models/ and specs/ next to it (default: "
                   "sim/franka/certificates)")
    f.add_argument("--no-modulation", action="store_true", help="learn no cuts (ablation)")
    f.add_argument("--no-replan", action="store_true",
                   help="run the demonstrated mode sequence open loop (ablation)")
    f.add_argument("--no-perturb", action="store_true", help="nominal trials, no wrenches")
    f.add_argument("--robot", choices=("hand", "panda"), default="hand",
                   help="hand: the ladle on a free body under a Cartesian impedance law (the "
                   "demonstrations' rig); panda: on the Panda hand under the operational-space "
                   "controller (needs the Menagerie assets: python -m tli_verify.sim.assets "
                   "fetch). Default hand")
    f.add_argument("--duration", type=float, default=20.0,
                   help="step budget per trial, simulated seconds (default 20)")
    f.add_argument("--json", action="store_true", help="one JSON object per trial, then a "
                   "summary object")
    f.add_argument("--video", type=output_path, default=None, metavar="OUT.mp4",
                   help="render the first trial to an MP4 (headless: EGL, else OSMesa)")
    f.add_argument("--fig9", type=output_path, default=None, metavar="OUT.png",
                   help="after the trials, plot each mode's modulated DS flow in (y, z, "
                   "pitch) with the cuts learned in them (Fig. 9 style)")
    p.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:
    from tli_verify.errors import TliError

    if args.no_modulation and args.no_replan:
        raise TliError("--no-modulation and --no-replan: choose one ablation")
    if not (0.5 <= args.duration <= 600):
        raise TliError(f"--duration must be between 0.5 and 600 s, got {args.duration}")
    if args.certificates is not None and not args.certificates.is_dir():
        raise TliError(f"--certificates {args.certificates}: not a directory")
    if args.video is not None:  # MuJoCo fixes its OpenGL backend on import (next lines)
        from tli_verify.sim.render import select_backend

        select_backend()  # MUJOCO_GL: the user's, else egl, else osmesa; none: exit 2
    from tli_verify.io import check_output_file
    from tli_verify.sim.loop import project_dir

    # the project's files (spec, model, certificate, demonstrations) are inputs: never written
    base = args.certificates.parent if args.certificates is not None else project_dir()
    inputs = [f for sub in ("specs", "models", "certificates", "demos")
              for f in sorted((base / sub).rglob("*")) if f.is_file()]
    if args.fig9 is not None:
        check_output_file(args.fig9, inputs=inputs, what="Fig. 9 plot")
    if args.video is not None:
        check_output_file(args.video, inputs=[*inputs, *([args.fig9] if args.fig9 else [])],
                          what="video")
    try:
        import mujoco  # noqa: F401
    except ImportError:
        raise TliError("tli sim needs MuJoCo: pip install 'tli-verify[sim]'") from None
    from tli_verify.io import canonical_json
    from tli_verify.sim.loop import load_policy, run_trial

    variant = ("no-modulation" if args.no_modulation else
               "no-replan" if args.no_replan else "LTL-DS")
    policy = load_policy(variant, certificates=args.certificates)  # exit 1 if not covered
    recorder = None
    if args.video is not None:
        from tli_verify.sim.render import Recorder

        recorder = Recorder()
    results = []
    for k in range(args.trials):
        seed = args.seed + k
        res = run_trial(policy, seed, variant=variant,
                        perturbations=[] if args.no_perturb else None,
                        duration=args.duration, robot=args.robot,
                        frame=recorder.frame if recorder is not None and k == 0 else None)
        results.append(res)
        if args.json:
            sys.stdout.write(canonical_json(res.to_json()))
        else:
            sys.stdout.write(
                f"trial {k + 1}/{args.trials} (seed {seed}, {variant}): "
                f"{'success' if res.success else 'FAILED'}, {res.delivered} bead(s) delivered; "
                f"modes {res.mode_sequence()}; {res.cuts_added} cut(s); "
                f"{res.sim_time:.1f} s simulated in {res.wall_time:.1f} s\n")
        sys.stdout.flush()
    ok = sum(r.success for r in results)
    summary = {"summary": True, "variant": variant, "trials": len(results), "successes": ok,
               "cuts_added": sum(r.cuts_added for r in results),
               "wall_time": round(sum(r.wall_time for r in results), 2)}
    if recorder is not None:
        recorder.save(args.video)
        summary["video"] = str(args.video)
    if args.fig9 is not None:
        from tli_verify.sim.loop import bundled_demos, plot_flow

        demos = bundled_demos()
        plot_flow(policy.model, args.fig9, demos=demos,
                  title=f"tli sim franka: {variant} flow after {len(results)} trial(s), "
                  f"{summary['cuts_added']} cut(s) learned")
        summary["fig9"] = str(args.fig9)
    if args.json:
        sys.stdout.write(canonical_json(summary))
    else:
        sys.stdout.write(f"{variant}: {ok}/{len(results)} trials delivered soup"
                         + (f"; video {args.video}" if args.video is not None else "") + "\n")
    return 0 if ok == len(results) else 1
