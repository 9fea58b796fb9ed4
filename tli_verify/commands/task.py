"""``tli task check|list``, ``tli demos``, ``tli init`` and ``tli evidence``: tasks as files.

* ``tli task check FILE...`` loads task files (or names) and prints what each declares;
  ``--picture OUT.png`` draws the regions (pairwise projections beyond 2-D).
* ``tli task list`` lists the tasks the registry knows (bundled files, entry points).
* ``tli demos TASK`` writes the task's scripted demonstrations as CSV files.
* ``tli init DIR`` scaffolds a project for a new task: a commented task file and spec, the
  folders, a README with the commands, and a CI snippet that runs the gate.
* ``tli evidence [DIR]`` runs the campaign of every model of a project and writes the evidence
  ``tli gate`` requires (the physical campaign for a task whose sensors physics computes).

Exit codes: 0 success, 1 a campaign found a violation (``evidence``), 2 bad input.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.commands import check_plan, float_range, int_range, output_path
from tli_verify.commands.sim import robot_name
from tli_verify.commands.verify import keep_stronger
from tli_verify.errors import CheckFailed, OutputError, TaskError, TliError
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.limits import MAX_WORKERS
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.sim.physics_checks import MIN_PHYSICS_TRIALS
from tli_verify.tasks.scaffold import scaffold
from tli_verify.verify.evidence import write_campaign_evidence

if TYPE_CHECKING:
    from tli_verify.project import Session
    from tli_verify.sim.loop import TrialResult
    from tli_verify.sim.trial_oracle import TrialVerdict
    from tli_verify.tasks.task import Task
    from tli_verify.verify.config import CampaignConfig

__all__ = ["register"]

DEFAULT_EXAMPLES = 1000
"""Examples per model of ``tli evidence``: 2x the gate's minimum (the 95% bound on the failure
probability is then 0.3%)."""


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli task``, ``tli demos``, ``tli init`` and ``tli evidence``."""
    task = sub.add_parser("task", help="check and list task files (state space, regions, "
                          "sensors, goal)")
    tsub = task.add_subparsers(dest="task_command", metavar="SUBCOMMAND",
                               parser_class=type(task))
    task.set_defaults(handler=lambda _a: _usage(task))
    check = tsub.add_parser("check", help="load task files and print what each declares",
                            description="Exit 0 if every task loads, 2 on the first that does "
                            "not (one error line naming the file and field).")
    check.add_argument("tasks", nargs="+", metavar="TASK", help="task files or names")
    check.add_argument("--picture", type=output_path, default=None, metavar="OUT.png",
                       help="draw the (first) task's regions (pairwise projections in n-D)")
    check.add_argument("--json", action="store_true", help="one JSON object per task")
    check.add_argument("--spec", type=Path, default=None, metavar="SPEC.toml",
                       help="also decide, on the task's geometry, that every sensor change it "
                       "can produce under any push is one the spec's assumptions allow (exit 1 "
                       "naming the pair of regions otherwise)")
    check.set_defaults(handler=_check)
    lst = tsub.add_parser("list", help="the tasks the registry knows: the project's own "
                          "(tasks/*.toml), the bundled ones and entry points")
    lst.add_argument("--project", type=Path, default=Path("."),
                     help="the project whose tasks/ is listed too (default: the working "
                     "folder, where tli run and tli verify find a task by name first)")
    lst.set_defaults(handler=_list)

    demos = sub.add_parser(
        "demos", help="write a task's scripted demonstrations as CSV files",
        description="Seeded minimum-jerk demonstrations through the task's [demonstrator] "
        "scripts, read by the task's sensors; one CSV per demonstration (tli learn reads "
        "them).")
    demos.add_argument("task", metavar="TASK", help="task file or name")
    demos.add_argument("--out", type=output_path, default=None,
                       help="directory (default: demos/ of the task's project)")
    demos.add_argument("--seed", type=int_range(0, 2**32 - 1), default=None,
                       help="the demonstrator's seed (default 0)")
    demos.add_argument("--count", type=int_range(1, 1000), default=None,
                       help="demonstrations (default: the demonstrator's count)")
    demos.add_argument("--prefix", default=None, help="file name prefix (default: the task's "
                       "name)")
    demos.add_argument("--picture", type=output_path, default=None, metavar="OUT.png",
                       help="also draw the regions with the demonstrations")
    demos.add_argument("--from-pose", type=Path, nargs="+", default=None, metavar="POSE.csv",
                       help="instead of scripting demonstrations: convert these recorded pose "
                       "demonstrations (position and a quaternion per sample; '# quaternion: "
                       "scalar-first' or 'scalar-last' before the header) into demonstrations "
                       "of this pose task, read by its sensors: OUT/<name>.csv each")
    demos.set_defaults(handler=_demos)

    init = sub.add_parser(
        "init", help="scaffold a project for a new task (task, spec, folders, CI snippet)",
        description="Writes DIR/tasks/NAME.toml (a commented task: workspace, regions, "
        "sensors, goal, demonstrator), DIR/specs/NAME.toml (a realizable 3-mode spec over its "
        "sensors), the folders demos/, models/, certificates/, DIR/README.md with the "
        "commands from demonstrations to the gate, and DIR/ci/tli-gate.yml. Refuses to "
        "overwrite existing files.")
    init.add_argument("directory", type=output_path, metavar="DIR")
    init.add_argument("--name", default="mytask", help="task name (default mytask)")
    init.add_argument("--dim", type=int_range(1, 32), default=None,
                      help="state dimension of the template (default 2); with --pose, the "
                      "position coordinates (default 3; 1 to 29)")
    init.add_argument("--pose", action="store_true",
                      help="a pose task: the tool's orientation in the state after the "
                      "position, the zone counting only with the tool upright (a cone)")
    init.set_defaults(handler=_init)

    ev = sub.add_parser(
        "evidence", help="campaign evidence for every model of a project (for tli gate)",
        description="For each DIR/models/*.model.json: a bisimulation campaign on the model, "
        "its certificate, the spec it names and the spec's task, with the task's defaults; "
        "writes DIR/certificates/<name>.campaign.json. A task whose sensors physics computes "
        "gets its physical campaign (MuJoCo trials). Exit 0 when no campaign found a "
        "violation, 1 otherwise (the evidence is written either way, as an honest record).")
    ev.add_argument("directory", nargs="?", type=Path, default=Path("."), metavar="DIR")
    ev.add_argument("--examples", type=int_range(1, 10_000_000), default=DEFAULT_EXAMPLES,
                    help=f"examples per model (default {DEFAULT_EXAMPLES})")
    ev.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0)
    ev.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=None,
                    help="bisimulation campaigns: worker processes (default: the CPU count); "
                    "physical campaigns: contiguous chunks of seeds, one executive each "
                    "(default 1: one executive for every trial)")
    ev.add_argument("--backend", choices=("process", "serial", "dask"), default=None,
                    help="where the batches run (default: process for bisimulation campaigns, "
                    "serial for physical ones)")
    ev.add_argument("--random-starts", action="store_true", default=None,
                    help="bisimulation campaigns draw random starts (default: the task's "
                    "[starts]: its first nominal start, or random starts with random = true "
                    "or no nominal start)")
    ev.add_argument("--force", action="store_true",
                    help="replace evidence of a stronger campaign (more examples, random "
                    "starts, a longer window, more pushes); without it such evidence is kept "
                    "and nothing runs")
    ev.add_argument("--only", nargs="+", default=None, metavar="NAME",
                    help="only these models (models/NAME.model.json)")
    ev.add_argument("--trials", type=int_range(1, 100_000), default=None,
                    help="physical campaigns: trials (default: the gate's minimum, 30)")
    ev.add_argument("--robot", type=robot_name, default="panda",
                    help="physical campaigns: the robot (panda, default; or free-tool)")
    ev.add_argument("--no-retry", "--no-stall-rule", dest="no_retry", action="store_true",
                    help="physical campaigns: the stall rule off (tli_verify.runtime.stall)")
    ev.add_argument("--sensors", choices=("franka", "ideal"), default="franka",
                    help="physical campaigns: the sensor model (franka, default: the robot's "
                    "own; ideal: the simulator's)")
    ev.add_argument("--controller", choices=("measured", "passive", "tracking"), default=None,
                    help="physical campaigns: the control law (measured, default: the DS at "
                    "the measured pose integrated to the impedance law's target, the paper's; "
                    "passive: the passive-DS law; tracking: the DS on its own target -- the "
                    "gate takes evidence of the project's law only)")
    ev.add_argument("--duration", type=float_range(0.5, 600.0, "s"), default=40.0,
                    help="physical campaigns: budget per trial (simulated seconds; default "
                    "40, 0.5 to 600)")
    ev.set_defaults(handler=_evidence)


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


# ------------------------------------------------------------------------------ task check
def _summary(task: Any) -> dict[str, Any]:
    part = task.partition
    return {
        "task": task.name, "file": task.source.path, "dimension": task.dim,
        "state": list(task.state_names),
        "workspace": {"lower": list(task.lo), "upper": list(task.hi)},
        "regions": [c.name for c in part.cells], "background": part.background,
        "layers": [la.name for la in part.layers], "sensors": list(task.sensor_names),
        "latches": list(task.latent_names), "lag": task.lag, "dt": task.dt,
        "goal": task.goal.to_dict(), "nominal_starts": [list(s) for s in task.starts.nominal],
        "demonstrator": (None if task.demonstrator is None
                         else {"count": task.demonstrator.count,
                               "scripts": len(task.demonstrator.scripts)}),
        "spec": task.spec, "sha256": task.source.sha256 or task.source.source_sha256,
    }


def _check(args: argparse.Namespace) -> int:
    from tli_verify.tasks.registry import find_task

    loaded = [find_task(t) for t in args.tasks]
    for task in loaded:  # the sensors read once: a plug-in's failure is an error line here
        _read_once(task)
    spec = None
    if args.spec is not None:  # a spec that does not load is one error line before any output

        spec = load_spec(args.spec)
    if args.picture is not None:
        from tli_verify.viz.regions import plot_task

        check_plan(inputs=[t.source.path for t in loaded], outputs=[(args.picture, "picture")])
    for task in loaded:
        s = _summary(task)
        if args.json:
            sys.stdout.write(canonical_json(s))
            continue
        sys.stdout.write(
            f"{task.where}: task {task.name!r}, {task.dim}-D ({', '.join(task.state_names)}); "
            f"regions {', '.join(s['regions']) or 'none'} (background {s['background']}"
            + (f"; layers {', '.join(s['layers'])}" if s["layers"] else "") + "); sensors "
            f"{', '.join(task.sensor_names)}"
            + (f"; latches {', '.join(task.latent_names)}" if task.latent_names else "")
            + f"; goal {'sink modes' if task.goal.modes is None else ', '.join(task.goal.modes)}"
            + (f" with {', '.join(task.goal.sensors)}" if task.goal.sensors else "")
            + f"; dt {task.dt:g} s, lag {task.lag}\n")
    if args.picture is not None:
        plot_task(loaded[0], args.picture)
        if not args.json:
            sys.stdout.write(f"wrote {args.picture}\n")
    if spec is not None:
        return _check_fit(loaded, spec, args.spec, as_json=args.json)
    return 0


def _read_once(task: Any) -> None:
    """Read the task's sensors once, at its first nominal start (else the workspace's
    centre), two steps there (not a physics scene's sensors): a sensor plug-in's ``read()``
    runs, and its reading's shape is checked against the sensor names
    (:class:`~tli_verify.tasks.plugins.PluginSensors`): a reading of the wrong shape or type,
    an exception or an exit is one error line naming the plug-in and the task file, not a
    crash later in ``tli run``, ``tli verify`` or the gate."""
    import numpy as np

    if getattr(task.sensor_model, "physics", False):  # read by a simulated scene, not a state
        return
    if task.starts.nominal:
        x = np.asarray(task.starts.nominal[0], dtype=float)
    else:
        x = (np.asarray(task.lo, dtype=float) + np.asarray(task.hi, dtype=float)) / 2
    task.sensors(np.stack([x, x]))


def _check_fit(tasks: list[Any], spec: Any, spec_path: Path, *, as_json: bool) -> int:
    """``tli task check --spec``: inputs and sensors agree, and every sensor change the task
    can produce is one the spec's assumptions allow (:mod:`tli_verify.tasks.fit`)."""
    from tli_verify.tasks.fit import task_spec_mismatches

    bad = 0
    for task in tasks:
        missing = [i for i in spec.inputs if i not in task.sensor_names]
        extra = [s for s in task.sensor_names if s not in spec.inputs]
        if missing or extra:
            raise TaskError(f"{task.where}: does not fit {spec_path}: "
                            + (f"spec input(s) {', '.join(missing)} have no sensor in the task"
                               if missing else "")
                            + ("; " if missing and extra else "")
                            + (f"task sensor(s) {', '.join(extra)} are not inputs of the spec"
                               if extra else ""))
        found = task_spec_mismatches(task, synthesize(spec))
        bad += len(found)
        if as_json:
            sys.stdout.write(canonical_json({"task": task.name, "spec": str(spec_path),
                                             "mismatches": [m.describe() for m in found]}))
            continue
        for m in found:
            sys.stdout.write(f"FAIL  {task.where}: {m.describe()}\n")
        if not found:
            sys.stdout.write(f"ok    {task.where}: every sensor change it can produce under "
                             f"any push is allowed by {spec_path}'s assumptions\n")
    if bad:
        raise CheckFailed(f"{spec_path}: {bad} sensor change(s) the task can produce are ruled "
                          "out by the spec's assumptions (above): a task/spec mismatch")
    return 0


def _list(args: argparse.Namespace) -> int:
    from tli_verify.tasks.registry import bundled_tasks, task_names

    bundled = bundled_tasks()
    own = args.project / "tasks"
    for name in task_names(args.project):
        mine = own / f"{name}.toml"
        where = (f"{mine} (this project)" if mine.is_file() else bundled.get(name)
                 or "entry point")
        sys.stdout.write(f"{name}\t{where}\n")
    return 0


# ------------------------------------------------------------------------------ demos
def _demos(args: argparse.Namespace) -> int:
    from tli_verify.tasks.demonstrator import write_demos
    from tli_verify.tasks.project import project_root
    from tli_verify.tasks.registry import find_task

    task = find_task(args.task)
    if args.from_pose is not None:
        return _demos_from_pose(args, task)
    if task.demonstrator is None:
        raise TaskError(f"{task.where}: no [demonstrator] table: the task cannot write "
                        "demonstrations (record your own as CSV files)")
    out = args.out
    if out is None:
        out = (project_root(task.source.path) / "demos" if task.source.path is not None
               else Path("demos"))
    prefix = args.prefix or task.name
    if not prefix.replace("-", "_").replace(".", "_").isidentifier():
        raise TaskError(f"--prefix {prefix!r}: letters, digits, '-', '_' and '.' only")
    count = args.count or task.demonstrator.count
    files = [out / f"{prefix}_{i}.csv" for i in range(1, count + 1)]
    check_plan(inputs=[task.source.path],
               outputs=[*((f, "demonstration") for f in files), (args.picture, "picture")])
    paths = write_demos(task, out, seed=args.seed or 0, n_demos=count, prefix=prefix)
    for p in paths:
        sys.stdout.write(f"wrote {p}\n")
    if args.picture is not None:
        from tli_verify.demos import load_demo
        from tli_verify.viz.regions import plot_task

        plot_task(task, args.picture, demos=[load_demo(p) for p in paths])
        sys.stdout.write(f"wrote {args.picture}\n")
    return 0


def _demos_from_pose(args: argparse.Namespace, task: Task) -> int:
    """``tli demos TASK --from-pose FILE...``: recorded pose demonstrations as the task's."""
    from tli_verify.demos import demo_to_csv, load_pose_demo
    from tli_verify.tasks.project import project_root

    if task.orientation is None:
        raise TaskError(f"{task.where}: --from-pose needs a pose task ([state] orientation = "
                        "{ start = K, reference = [w, x, y, z] })")
    if args.count is not None or args.prefix is not None or args.seed is not None:
        raise TaskError("--from-pose converts the files given: --count, --prefix and --seed "
                        "do not apply")
    out = args.out
    if out is None:
        out = (project_root(task.source.path) / "demos" if task.source.path is not None
               else Path("demos"))
    files = [out / f"{Path(f).stem}.csv" for f in args.from_pose]
    if len(set(files)) != len(files):
        raise TaskError("--from-pose: two files have the same name; their demonstrations "
                        "would overwrite each other")
    check_plan(inputs=[task.source.path, *args.from_pose],
               outputs=[*((f, "demonstration") for f in files), (args.picture, "picture")])
    demos = []
    for src in args.from_pose:  # every file read and converted before anything is written
        pose = load_pose_demo(src)
        for note in pose.notes:
            sys.stderr.write(f"note: {note}\n")  # each note names its file
        demos.append(task.pose_demonstration(pose))
    for src, demo, path in zip(args.from_pose, demos, files, strict=True):
        atomic_write_text(path, f"# {task.name} demonstration from {Path(src).name} (tli demos "
                          "--from-pose)\n" + demo_to_csv(demo))
        sys.stdout.write(f"wrote {path}\n")
    if args.picture is not None:
        from tli_verify.viz.regions import plot_task

        plot_task(task, args.picture, demos=demos)
        sys.stdout.write(f"wrote {args.picture}\n")
    return 0


# ------------------------------------------------------------------------------ init
def _init(args: argparse.Namespace) -> int:
    from tli_verify.tasks.formula import is_name

    name = args.name
    if not is_name(name.replace("-", "_")) or len(name) > 64:
        raise TaskError(f"--name {name!r}: letters, digits, '_' and '-' only (a task name)")
    root: Path = args.directory
    if root.exists() and not root.is_dir():
        raise OutputError(f"{root}: exists and is not a directory")
    from tli_verify.tasks.values import MAX_TASK_DIM

    if args.pose and args.dim is not None and args.dim > MAX_TASK_DIM - 3:
        raise TaskError(f"--dim {args.dim} with --pose: at most {MAX_TASK_DIM - 3} position "
                        f"coordinates (the orientation takes 3 of {MAX_TASK_DIM})")
    dim = args.dim if args.dim is not None else (3 if args.pose else 2)
    files = scaffold(name, dim, pose=args.pose)
    targets = [(root / rel, what) for rel, (what, _) in files.items()]
    existing = [str(p) for p, _ in targets if p.exists()]
    if existing:
        raise OutputError(f"{existing[0]}: exists; tli init never overwrites a file (choose an "
                          "empty directory)")
    check_plan(inputs=[], outputs=targets)
    for folder in ("tasks", "specs", "demos", "models", "certificates", "ci"):
        (root / folder).mkdir(parents=True, exist_ok=True)
    for rel, (_, text) in files.items():
        atomic_write_text(root / rel, text)
        sys.stdout.write(f"wrote {root / rel}\n")
    sys.stdout.write(f"next: see {root / 'README.md'} (tli demos, learn, certify, verify "
                     "--evidence, gate)\n")
    return 0


# ------------------------------------------------------------------------------ evidence
def _evidence(args: argparse.Namespace) -> int:
    from tli_verify.tasks.project import model_files, model_stem

    root: Path = args.directory
    if not root.is_dir():
        raise TliError(f"{root}: not a directory")
    models = sorted((root / "models").glob("*.model.json"))
    if args.only:
        models = [m for m in models if model_stem(m) in set(args.only)]
        missing = sorted(set(args.only) - {model_stem(m) for m in models})
        if missing:
            raise TliError(f"--only: no models/{missing[0]}.model.json under {root}")
    if not models:
        raise TliError(f"{root / 'models'}: no *.model.json to make evidence for")
    plan = []
    from tli_verify.project import open_project

    for model in models:  # every model opens, and no evidence overwrites an input, first
        session = open_project(model=model)
        physical = bool(getattr(session.task.sensor_model, "physics", False))
        plan.append((model, session, physical))
        if not physical:  # nor replaces stronger evidence (unless --force)
            keep_stronger(model_files(model).evidence,
                          session.campaign_config(_config(args)), force=args.force)
    check_plan(inputs=[p for _, s, _ in plan for p in s.files.inputs],
               outputs=[(model_files(m).evidence, "campaign evidence") for m, _, _ in plan])
    status = 0
    for _, session, physical in plan:
        t0 = time.perf_counter()
        if physical:
            ok, line = _physical(args, session)
        else:
            ok, line = _kinematic(args, session)
        sys.stdout.write(f"{line} ({time.perf_counter() - t0:.1f} s)\n")
        status |= 0 if ok else 1
    return status


def _config(args: argparse.Namespace) -> CampaignConfig:
    """The bisimulation campaign ``tli evidence`` runs for one model (on the model's session
    files: :meth:`~tli_verify.project.Session.campaign_config`)."""
    from tli_verify.verify.config import CampaignConfig

    return CampaignConfig(examples=args.examples, seed=args.seed, modulation=True,
                          workers=args.workers, backend=args.backend or "process",
                          random_starts=args.random_starts)


def _kinematic(args: argparse.Namespace, session: Session) -> tuple[bool, str]:
    result = session.campaign(_config(args), progress=sys.stderr.isatty())
    if result.partial:  # Ctrl-C or SIGTERM: exit 130, and the evidence there stays as it was
        raise KeyboardInterrupt
    files = session.files
    path, doc = write_campaign_evidence(result.config, result, path=files.evidence)
    total = doc["violations"]["total"]
    return (not total and not result.partial,
            f"{path}: task {files.task.name!r}, seed {args.seed}, {args.examples} examples, "
            f"{'random starts' if result.config.random_starts else 'nominal start'}, "
            f"{result.runs} runs, {total} violation(s)")


def _physical(args: argparse.Namespace, session: Session) -> tuple[bool, str]:
    trials = MIN_PHYSICS_TRIALS if args.trials is None else args.trials
    if args.seed + trials > 2**32:
        raise TliError("--seed + --trials: every trial's seed must be below 2^32")
    workers = 1 if args.workers is None else args.workers
    backend = args.backend or "serial"

    def progress(k: int, res: TrialResult, verdict: TrialVerdict) -> None:
        judged = "ok" if verdict.ok else ", ".join(verdict.violations)
        sys.stderr.write(f"  trial {k + 1}/{trials} (seed {res.seed}): {judged}; "
                         f"{res.delivered} bead(s); modes {res.mode_sequence()}\n")

    def event(text: str) -> None:
        sys.stderr.write(f"note: {text}\n")

    result = session.physics_campaign(seed=args.seed, trials=trials, workers=workers,
                                      backend=backend, on_trial=progress, on_event=event,
                                      robot=args.robot, duration=args.duration,
                                      retry=not args.no_retry, sensors=args.sensors,
                                      **({} if args.controller is None else
                                         {"controller": args.controller}))
    try:
        from tli_verify.sim.physics_evidence import write_physics_evidence
    except ImportError as exc:  # pragma: no cover - the sim extra is missing
        raise TliError(f"{session.files.model}: a physical campaign needs the simulator (pip "
                       f"install 'tli-verify[sim]'): {exc}") from None
    resolved = session.files
    path, _ = write_physics_evidence(result, resolved.evidence)
    return result.ok, (f"{path}: physical campaign of task {resolved.task.name!r}, seed "
                       f"{args.seed}, {trials} trial(s) (robot {args.robot}, "
                       f"{args.duration:g} s, {len(result.chunks)} chunk(s) on "
                       f"{backend}), {result.successes} delivered, "
                       f"{sum(not v.ok for v in result.verdicts)} failed the oracle")
