"""``tli sim franka``: perturbed LTL-DS trials of soup scooping in MuJoCo (paper Sec. 7.2).

Before anything moves, the bundled Franka scoop model must be covered by its certificate
(``<certificates>/franka-scoop.cert.json``), exactly as the gate checks it: a missing, invalid
or tampered certificate, or a model it does not cover, is refused with exit 1 naming the
certificate.

Every trial is judged by the physics oracle (:func:`tli_verify.sim.trial_oracle.check_trial`): soup
delivered, the goal mode reached, the mode trace a run of the task automaton. ``--evidence
[PATH]`` writes the run as campaign evidence for ``tli gate`` (default
``<project>/certificates/franka-scoop.campaign.json``; :mod:`tli_verify.verify.evidence`).

Exit codes: 0 every trial passed the oracle (delivered soup); 1 a trial did not (or the
certificate refused); 2 bad arguments.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import (
    DEFAULT_PATH,
    check_plan,
    chosen_path,
    float_range,
    int_range,
    output_path,
)
from tli_verify.errors import TliError
from tli_verify.io import canonical_json
from tli_verify.limits import MAX_WORKERS
from tli_verify.sim import TRIAL_DURATION
from tli_verify.sim.franka_files import MODEL_NAME
from tli_verify.sim.render import Recorder, select_backend
from tli_verify.verify.evidence import EVIDENCE_SUFFIX

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli sim``."""
    p = sub.add_parser(
        "sim", help="closed-loop LTL-DS trials in the MuJoCo soup-scooping scene",
        description="Physical soup scooping with beads: sensors from the physics, the "
        "certified LTL-DS executive, perturbations by a person's hand (pushes and spilling "
        "tilts).")
    simsub = p.add_subparsers(dest="scene", metavar="SCENE")
    simsub.required = True
    f = simsub.add_parser(
        "franka", help="perturbed scooping trials (success: a bead ends in the target bowl)",
        description="Run N seeded, perturbed trials of the certified Franka scoop model, "
        "each judged by the physics oracle (soup delivered, goal mode reached, the mode trace "
        "a run of the task automaton). Exit 0: every trial passed; 1: one did not, or the "
        "certificate refused the model; 2: bad arguments.")
    f.add_argument("--trials", type=int_range(1, 1000), default=1,
                   help="number of trials (default 1)")
    f.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0,
                   help="seed of the first trial (default 0)")
    f.add_argument("--certificates", type=Path, default=None, metavar="DIR",
                   help="certificates directory of a project holding "
                   "franka-scoop.cert.json, with models/ and specs/ next to it (default: "
                   "sim/franka/certificates)")
    f.add_argument("--no-modulation", action="store_true", help="learn no cuts (ablation)")
    f.add_argument("--no-replan", action="store_true",
                   help="run the demonstrated mode sequence open loop (ablation)")
    f.add_argument("--no-perturb", action="store_true", help="nominal trials, no perturbations")
    f.add_argument("--robot", type=robot_name, default="panda",
                   help="panda (default): the ladle on the Panda hand under the Cartesian "
                   "impedance controller within the Franka's limits (needs the Menagerie "
                   "assets: python -m tli_verify.sim.assets fetch); free-tool: the ladle on a "
                   "free body under an impedance law, no arm (no limits: the gate does not "
                   "take its evidence)")
    f.add_argument("--no-retry", "--no-stall-rule", dest="no_retry", action="store_true",
                   help="switch the stall rule off (the executive's documented answer to a "
                   "converged DS without the next mode's reading: re-enter the mode from its "
                   "predecessor, tli_verify.runtime.stall)")
    f.add_argument("--sensors", choices=("franka", "ideal"), default="franka",
                   help="franka (default): s from a wrist F/T load, r and t from the noisy "
                   "kinematic pose, with latency (tli_verify.sim.franka_sensors); ideal: "
                   "noise-free sensors from the physics")
    f.add_argument("--controller", choices=("measured", "passive", "tracking"), default=None,
                   help="measured (default; the paper's robot): the DS at the measured pose "
                   "every period, its velocity integrated to a target pose the Cartesian "
                   "impedance law tracks; passive (the Panda only): the DS at the measured pose "
                   "tracked by the passive-DS damping law (tli_verify.sim.passive); tracking: "
                   "the DS run on its own integrated target (for comparison)")
    f.add_argument("--duration", type=float_range(0.5, 600.0, "s"), default=TRIAL_DURATION,
                   help="step budget per trial, simulated seconds (default %(default)g; 0.5 "
                   "to 600)")
    f.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=1,
                   help="split the seeds into N contiguous chunks, one executive each (its "
                   "cuts carry over between the trials of its chunk only); default 1: one "
                   "executive for every trial. The same seed, trials and workers give the "
                   "same trials on every backend")
    f.add_argument("--backend", choices=("serial", "process", "dask"), default="serial",
                   help="where the chunks run: serial (default, this process), process "
                   "(local worker processes) or dask ('tli-verify[cluster]')")
    f.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (--backend dask; default: a LocalCluster)")
    f.add_argument("--json", action="store_true", help="one JSON object per trial, then a "
                   "summary object")
    f.add_argument("--video", type=output_path, default=None, metavar="OUT.mp4",
                   help="render the first trial to an MP4 (headless: EGL, else OSMesa)")
    f.add_argument("--fig9", type=output_path, default=None, metavar="OUT.png",
                   help="after the trials, plot each mode's modulated DS flow in (y, z, "
                   "pitch) with the cuts learned in them (paper Fig. 11 style)")
    f.add_argument("--c-evaluator", type=Path, default=None, metavar="POLICY.tli.json",
                   help="drive the robot with this exported artifact (tli export) in the C "
                   "evaluator, built with the system compiler; the Python executive runs "
                   "alongside as its supervisor (same automaton, cuts solved in Python and "
                   "handed to the evaluator); the artifact must have been exported from the "
                   "model being run, and its stall rule (the one its evidence ran) must be "
                   "this run's (--no-stall-rule only for an artifact without one); with "
                   "--evidence the evidence records its hash (serial backend, one worker)")
    f.add_argument("--evidence", nargs="?", type=output_path, const=DEFAULT_PATH, default=None,
                   metavar="PATH",
                   help="write the trials as campaign evidence for tli gate (default "
                   "<project>/certificates/franka-scoop.campaign.json); the gate needs "
                   "at least 30 perturbed LTL-DS trials, all passing")
    p.set_defaults(handler=_run)


def robot_name(text: str) -> str:
    """``--robot``: ``panda`` or ``free-tool``; the old name ``hand`` is refused with a hint."""
    if text == "hand":
        raise argparse.ArgumentTypeError("'hand' is now called 'free-tool' (the ladle on a "
                                         "free body, no arm); the default is 'panda'")
    if text not in ("panda", "free-tool"):
        raise argparse.ArgumentTypeError(f"{text!r}: one of panda, free-tool")
    return text


def _run(args: argparse.Namespace) -> int:

    if args.no_modulation and args.no_replan:
        raise TliError("--no-modulation and --no-replan: choose one ablation")
    if not (0.5 <= args.duration <= 600):
        raise TliError(f"--duration must be between 0.5 and 600 s, got {args.duration}")
    if args.certificates is not None and not args.certificates.is_dir():
        raise TliError(f"--certificates {args.certificates}: not a directory")
    if args.video is not None:  # MuJoCo fixes its OpenGL backend on import (next lines)

        select_backend()  # MUJOCO_GL: the user's, else egl, else osmesa; none: exit 2
    if args.evidence is not None and (args.no_perturb or args.no_modulation or args.no_replan):
        raise TliError("--evidence: evidence is for the deployed policy under perturbations; "
                       "not with --no-perturb, --no-modulation or --no-replan")
    if args.scheduler is not None and args.backend != "dask":
        raise TliError("--scheduler needs --backend dask")
    if args.backend != "serial" and (args.video is not None or args.fig9 is not None):
        raise TliError(f"--backend {args.backend}: --video and --fig9 need the trials in this "
                       "process (--backend serial)")
    if args.fig9 is not None and args.workers > 1:
        raise TliError(f"--fig9 plots the cuts one executive learned: not with --workers "
                       f"{args.workers} (one executive per chunk)")
    if args.c_evaluator is not None and (args.backend != "serial" or args.workers > 1
                                         or args.no_modulation or args.no_replan):
        raise TliError("--c-evaluator: one executive in this process (--backend serial, "
                       "--workers 1), the deployed variant (no --no-modulation, --no-replan)")
    if args.evidence is not None and args.seed + args.trials > 2**32:
        raise TliError(f"--seed {args.seed}: with --evidence the trials' seeds must be below "
                       "2^32")
    if args.controller == "passive" and args.robot == "free-tool":
        raise TliError("--controller passive runs on the Panda only; the free tool tracks a "
                       "target (--controller measured or tracking)")
    try:  # before anything imports MuJoCo indirectly (sim.loop does)
        import mujoco  # noqa: F401
    except ImportError:
        raise TliError("tli sim needs MuJoCo: pip install 'tli-verify[sim]'") from None
    except RuntimeError as exc:  # e.g. MUJOCO_GL set to a backend MuJoCo does not know
        import os

        raise TliError(f"MuJoCo refused to load with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}: "
                       f"{' '.join(str(exc).split())[:120]}") from None
    from tli_verify.sim.franka_project import project_dir

    # the project's files (task, spec, model, certificate, demonstrations) are inputs: never
    # written; its evidence may be replaced by new evidence only
    base = args.certificates.parent if args.certificates is not None else project_dir()
    inputs = [f for sub in ("tasks", "specs", "models", "certificates", "demos")
              for f in sorted((base / sub).rglob("*")) if f.is_file()]
    if args.certificates is not None:  # a certificates directory not named certificates/
        inputs += [f for f in sorted(args.certificates.rglob("*")) if f.is_file()]
    evidence = None
    if args.evidence is not None:  # before any work: never over an input or another output

        cert_dir = args.certificates if args.certificates is not None else \
            base / "certificates"
        evidence = chosen_path(args.evidence) or cert_dir / f"{MODEL_NAME}{EVIDENCE_SUFFIX}"
    check_plan(inputs=[f for f in inputs if not f.name.endswith(EVIDENCE_SUFFIX)],
               outputs=[(args.video, "video"), (args.fig9, "Fig. 11 plot"),
                        (evidence, "campaign evidence")])
    check_plan(inputs=inputs, outputs=[(args.video, "video"), (args.fig9, "Fig. 11 plot")])
    from tli_verify.sim.campaign import run_physics_campaign
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import TrialResult, default_controller
    from tli_verify.sim.physics_config import PhysicsConfig
    from tli_verify.sim.physics_evidence import write_physics_evidence
    from tli_verify.sim.trial_oracle import TrialVerdict

    variant = ("no-modulation" if args.no_modulation else
               "no-replan" if args.no_replan else "LTL-DS")
    # exit 1 if the certificate does not cover the model (on the other backends the campaign
    # checks it before any worker starts, and each chunk loads its own executive)
    policy: Any = load_policy(variant, certificates=args.certificates) \
        if args.backend == "serial" else None
    evaluator = None
    if args.c_evaluator is not None:
        import tempfile

        from tli_verify.deploy.cloop import describe_stall, in_the_loop
        from tli_verify.runtime.stall import StallRule

        with tempfile.TemporaryDirectory(prefix="tli-c-") as build_dir:  # loaded: removable
            policy = evaluator = in_the_loop(policy, args.c_evaluator, build_dir)
        asked = None if args.no_retry else StallRule()
        if evaluator.stall_rule != asked:  # the trials record the rule: the robot's must be it
            raise TliError(f"--c-evaluator {args.c_evaluator}: the artifact runs "
                           f"{describe_stall(evaluator.stall_rule)}, this run "
                           f"{describe_stall(asked)}: export it from evidence made with the "
                           "same rule, or "
                           f"{'drop' if args.no_retry else 'add'} --no-stall-rule")
        sys.stderr.write(f"note: the C evaluator drives the robot: artifact "
                         f"{evaluator.sha256}\n")
    recorder = None
    if args.video is not None:

        recorder = Recorder()
    config = PhysicsConfig(root=str(base), seed=args.seed, trials=args.trials,
                           robot=args.robot, variant=variant, duration=args.duration,
                           retry=not args.no_retry, sensors=args.sensors,
                           controller=args.controller or default_controller(args.robot),
                           pushes=0 if args.no_perturb else 1,
                           tilts=0 if args.no_perturb else 1,
                           certificates=None if args.certificates is None
                           else str(args.certificates),
                           workers=args.workers, backend=args.backend)

    def report(k: int, res: TrialResult, verdict: TrialVerdict) -> None:
        if args.json:
            sys.stdout.write(canonical_json(dict(res.to_dict(),
                                                 violations=list(verdict.violations))))
        else:
            judged = "oracle ok" if verdict.ok else \
                f"oracle: {', '.join(verdict.violations)}"
            sys.stdout.write(
                f"trial {k + 1}/{args.trials} (seed {res.seed}, {variant}): "
                f"{'success' if res.success else 'FAILED'}, {res.delivered} bead(s) delivered; "
                f"modes {res.mode_sequence()}; {res.cuts_added} cut(s); {res.retries} "
                f"retr{'y' if res.retries == 1 else 'ies'}; {judged}; "
                f"{res.sim_time:.1f} s simulated in {res.wall_time:.1f} s\n")
        sys.stdout.flush()

    def event(text: str) -> None:
        sys.stderr.write(f"note: {text}\n")

    campaign = run_physics_campaign(config, policy=policy, on_trial=report,
                                    frame=recorder.frame if recorder is not None else None,
                                    on_event=event, scheduler=args.scheduler)
    results = campaign.results
    ok = campaign.successes
    passed = sum(v.ok for v in campaign.verdicts)
    summary: dict[str, object] = {
        "summary": True, "variant": variant, "trials": len(results), "successes": ok,
        "passed": passed, "violations": campaign.violations,
        "cuts_added": sum(r.cuts_added for r in results),
        "wall_time": round(sum(r.wall_time for r in results), 2),
        "workers": args.workers, "backend": args.backend,
        "chunks": [list(c) for c in campaign.chunks]}
    record: dict[str, Any] | None = None
    if evaluator is not None:
        record = {"kind": "c", "artifact_sha256": evaluator.sha256, "steps": evaluator.steps,
                  "max_rel_diff": evaluator.max_rel_diff}
        summary["evaluator"] = record
    if evidence is not None:
        target, _ = write_physics_evidence(campaign, evidence, evaluator=record)
        summary["evidence"] = str(target)
    if recorder is not None:
        recorder.save(args.video)
        summary["video"] = str(args.video)
    if args.fig9 is not None and policy is not None:  # serial and one executive (above)
        from tli_verify.sim.flow_plot import plot_flow
        from tli_verify.sim.franka_project import bundled_demos

        demos = bundled_demos()
        plot_flow(policy.model, args.fig9, demos=demos,
                  title=f"tli sim franka: {variant} flow after {len(results)} trial(s), "
                  f"{summary['cuts_added']} cut(s) learned")
        summary["fig9"] = str(args.fig9)
    if args.json:
        sys.stdout.write(canonical_json(summary))
    else:
        sys.stdout.write(f"{variant}: {ok}/{len(results)} trials delivered soup, {passed} "
                         "passed the oracle"
                         + (f"; C evaluator {evaluator.sha256[:12]}: {evaluator.steps} steps, "
                            f"velocities within {evaluator.max_rel_diff:.1e} of the runtime's"
                            if evaluator is not None else "")
                         + (f"; video {args.video}" if args.video is not None else "")
                         + (f"; evidence {summary['evidence']}" if evidence is not None
                            else "") + "\n")
    return 0 if passed == len(results) else 1
