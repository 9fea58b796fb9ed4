"""``tli run``: one closed-loop LTL-DS episode on a task (paper eq. 6, Fig. 7).

The task (``--task NAME|FILE``), its spec, model and certificate are
found by the project rules (:func:`tli_verify.tasks.project.resolve`): a bundled task runs its
shipped spec, certified model and certificate; ``--spec`` picks another spec of the task (its
model by the project layout), ``--model`` another model (the spec it names, the certificate by
the project layout). Works in any dimension: ``--start`` and ``--perturb`` take one number per
coordinate, random pushes are drawn on the sphere.

``--learn-transitions`` grows the spec online (paper appendix F): the run may then start from
another spec than the model names (``--spec``, e.g. one ``tli spec infer`` wrote), provided it
has the same sensors and the same ``[modes]`` labels; transitions the spec lacks are added as
the episode shows them, and ``--grown-spec OUT.toml`` writes the grown spec. The model and its
certificate keep binding the spec the model names.

Exit codes: 0 the episode reached the goal, 1 it did not (or the certificate does not cover
the model: the executive refuses it), 2 bad arguments.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from tli_verify.commands import check_plan, int_range, output_path
from tli_verify.commands.experiment import scoop_study
from tli_verify.defaults import Stream, rng
from tli_verify.errors import CertificateError, TliError
from tli_verify.io import atomic_write_text, bundled_root, canonical_json, read_json
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec

__all__ = ["add_task_arguments", "demo_stage", "open_args", "parse_floats", "parse_perturb",
           "register"]

MAX_RUN_STEPS = MAX_CAMPAIGN_STEPS
"""Largest ``--steps`` of ``tli run`` (100,000 control steps: 1,000 s at 10 ms)."""


class _FormerTaskOption(argparse.Action):
    """``--world``: stores the task as ``--task`` does, with a note that it is the old name."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: object, option_string: str | None = None) -> None:
        print("note: --world is the former name of --task", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_task_arguments(p: argparse.ArgumentParser, *, what: str = "run") -> None:
    """``--task``, ``--spec``, ``--model``, ``--certificate``, ``--lag``: the files of a
    closed-loop command, resolved by the project rules. ``--world``, the option's former name,
    is still accepted (not listed in ``--help``) and says so on stderr."""
    p.add_argument("--task", dest="task", default=None, metavar="TASK",
                   help="task name (bundled: scoop, cooking, color-tracing, inspection; or a "
                   "project's tasks/NAME.toml) or task file; default: the task the spec names")
    p.add_argument("--world", dest="task", default=None, action=_FormerTaskOption,
                   help=argparse.SUPPRESS)
    p.add_argument("--spec", type=Path, default=None,
                   help="spec file (default: the model's, else the task's default spec)")
    p.add_argument("--model", type=Path, default=None,
                   help="model file (default: models/<spec>.model.json of the spec's project)")
    p.add_argument("--certificate", type=Path, default=None,
                   help="certificate (default: certificates/<model>.cert.json of the model's "
                   "project)")
    p.add_argument("--lag", type=int_range(0, MAX_CAMPAIGN_STEPS), default=None,
                   help="sensor lag in control steps (default: the task's)")


def open_args(args: argparse.Namespace, *, use_spec: bool = True) -> Any:
    """The project session (:func:`tli_verify.project.open_project`) of the command's task
    options (``use_spec`` False: ``--spec`` is not the model's spec, e.g. the spec
    ``--learn-transitions`` grows)."""
    from tli_verify.project import open_project

    return open_project(task=args.task, spec=args.spec if use_spec else None,
                        model=args.model, certificate=args.certificate, lag=args.lag)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli run``."""
    p = sub.add_parser(
        "run", help="run one closed-loop LTL-DS episode on a task",
        description="Task automaton + certified, modulated DS per mode in closed loop with a "
        "task's sensors; perturbations, online cuts, replanning. Writes run.json and a "
        "Fig. 7-style run.png to --out. Exit 0: the goal was reached; 1: it was not.")
    add_task_arguments(p)
    p.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0,
                   help="seed of the start and of random:N")
    start = p.add_mutually_exclusive_group()
    start.add_argument("--start", default=None, metavar="X1,...,Xn",
                       help="start state, one number per coordinate; a negative first number "
                       "needs '=' (--start=-0.9,0) (default: the task's first nominal start, "
                       "[starts] nominal; a task without one: as --random-start)")
    start.add_argument("--random-start", action="store_true",
                       help="a seeded random start (--seed) whose reading is an initial one "
                       "of the spec, instead of the task's nominal start")
    p.add_argument("--perturb", action="append", default=[], metavar="T:D1,...,Dn|random:N",
                   help="displace the state by (D1, ..., Dn) before step T (repeatable), or N "
                   "seeded random perturbations (directions uniform on the sphere, magnitudes "
                   "up to the task's bound, steps 1..700)")
    p.add_argument("--no-modulation", action="store_true", help="learn no cuts")
    p.add_argument("--no-replan", action="store_true",
                   help="run the demonstrated mode sequence open loop")
    p.add_argument("--steps", type=int_range(1, MAX_RUN_STEPS), default=3000,
                   help=f"step budget (default 3000, at most {MAX_RUN_STEPS})")
    p.add_argument("--learn-transitions", action="store_true",
                   help="add a valid transition the spec lacks (into a known mode) to it "
                   "online, re-synthesize and carry on (paper appendix F); --spec is then the "
                   "spec to grow from")
    p.add_argument("--grown-spec", type=output_path, default=None, metavar="OUT.toml",
                   help="with --learn-transitions: write the (grown) spec here, atomically")
    p.add_argument("--out", type=output_path, default=Path("out/run"),
                   help="output directory (default out/run)")
    p.add_argument("--animate", nargs="?", const=60, default=None, metavar="FRAMES",
                   type=int_range(2, 1000),
                   help="also write run.gif to --out: the episode animated in FRAMES frames "
                   "(default 60; regions, path, cuts as they are learned, the mode)")
    p.add_argument("--json", action="store_true", help="print the episode record as JSON")
    p.add_argument("-o", "--output", type=output_path, default=None, metavar="MODEL.json",
                   help="save the model with the cuts learned in the episode, and a re-issued "
                   "certificate (at the certified period) where the project layout puts it "
                   "(certificates/<name>.cert.json of the model's project); both written "
                   "atomically, nothing written if it does not certify")
    p.set_defaults(handler=_run)


def parse_floats(text: str, n: int, what: str) -> list[float]:
    """``n`` comma-separated finite numbers (``--start``, a push's displacement).

    Raises
    ------
    TliError
        (exit 2) Naming the option and how many numbers it needs.
    """
    import math

    parts = text.split(",")
    try:
        vals = [float(v) for v in parts]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise TliError(f"{what}: expected {n} comma-separated finite numbers (one per "
                       f"coordinate of the {n}-D state), got {text!r}")
    return vals


def parse_perturb(items: list[str], *, seed: int, task: Any, steps: int | None = None
                  ) -> dict[int, Any]:
    """``--perturb`` values -> ``{step: displacement}`` (n numbers each).

    Raises
    ------
    TliError
        (exit 2) A malformed item, a step < 1 or beyond the step budget, a repeated step, a
        count N that is not an integer in ``[0, MAX_PUSHES]``.
    """
    import numpy as np

    from tli_verify.runtime.episodes import random_perturbations

    out: dict[int, Any] = {}
    draws = rng(seed, Stream.PUSHES)
    for item in items:
        if item.startswith("random:"):
            n_text = item[len("random:"):]
            if not n_text.isdigit() or int(n_text) > MAX_PUSHES:
                raise TliError(f"--perturb {item!r}: random:N needs a count N in "
                               f"[0, {MAX_PUSHES}] (MAX_PUSHES)")
            last = 700 if steps is None else min(700, steps)
            for t, d in random_perturbations(draws, int(n_text), task, last=last).items():
                if t in out:
                    raise TliError(f"--perturb {item!r}: step {t} is perturbed twice")
                out[t] = d
            continue
        head, sep, tail = item.partition(":")
        if not sep or not head.strip().isdigit():
            raise TliError(f"--perturb {item!r}: expected T:D1,...,D{task.dim} (T a step >= 1) "
                           "or random:N")
        t = int(head)
        if t < 1:
            raise TliError(f"--perturb {item!r}: step must be >= 1")
        if steps is not None and t > steps:
            raise TliError(f"--perturb {item!r}: step {t} is beyond the step budget "
                           f"(--steps {steps}): it could never happen")
        if t in out:
            raise TliError(f"--perturb {item!r}: step {t} is perturbed twice")
        out[t] = np.array(parse_floats(tail, task.dim, f"--perturb {item!r}"))
    if len(out) > MAX_PUSHES:
        raise TliError(f"--perturb: {len(out)} perturbations, more than MAX_PUSHES "
                       f"({MAX_PUSHES})")
    return out


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from tli_verify.runtime.episodes import (
        episode_json,
        mode_string,
        random_start,
        run_variant,
    )
    from tli_verify.tasks.project import model_files

    if args.no_modulation and args.no_replan:
        raise TliError("--no-modulation and --no-replan: choose one ablation")
    if args.grown_spec is not None and not args.learn_transitions:
        raise TliError("--grown-spec needs --learn-transitions")
    session = open_args(args, use_spec=not args.learn_transitions)
    resolved = session.files
    out: Path = args.out
    saved_cert = model_files(args.output).certificate if args.output is not None else None
    check_plan(inputs=[*resolved.inputs, args.spec],
               outputs=[(out / "run.json", "episode record"), (out / "run.png", "picture"),
                        (out / "run.gif" if args.animate is not None else None, "animation"),
                        (args.output, "model"), (saved_cert, "certificate"),
                        (args.grown_spec, "grown spec")])
    setup = session.setup
    task = setup.task
    start_spec = _growth_start(setup, args.spec) if args.learn_transitions else None
    grown = None
    if start_spec is not None:
        from dataclasses import replace

        grown = synthesize(start_spec)
        setup = replace(setup, automaton=grown)
    perturbations = parse_perturb(args.perturb, seed=args.seed, task=task, steps=args.steps)
    if args.start is not None:
        x0 = np.array(parse_floats(args.start, task.dim, f"--start {args.start!r}"))
        if not bool(task.in_workspace(x0[None])[0]):
            box = " x ".join(f"[{a:g}, {b:g}]" for a, b in zip(task.lo, task.hi, strict=True))
            raise TliError(f"--start {args.start!r}: outside the workspace {box} of task "
                           f"{task.name!r}")
    elif task.starts.nominal and not args.random_start:
        x0 = np.array(task.starts.nominal[0], dtype=np.float64)  # what tli verify starts at
    else:
        x0 = random_start(task, setup.automaton, rng(args.seed, Stream.START))
    variant = ("no-modulation" if args.no_modulation else
               "no-replan" if args.no_replan else "LTL-DS")
    # refuses a model its certificate does not cover
    if start_spec is None:
        policy = session.policy(variant)
    else:
        from tli_verify.runtime.setup import make_policy

        policy = make_policy(setup, variant, spec=start_spec, learn_transitions=True)
    t0 = time.perf_counter()
    res = run_variant(setup, variant, x0, perturbations, steps=args.steps, policy=policy)
    seconds = time.perf_counter() - t0
    nominal = run_variant(setup, variant, x0, {}, steps=args.steps,
                          policy=session.policy(variant, automaton=grown))
    record = episode_json(res, task=task.name, variant=variant, seconds=seconds, x0=x0,
                          perturbations=perturbations, dt=policy.dt)
    record["files"] = {"task": task.where, "spec": str(resolved.spec),
                       "model": str(resolved.model), "certificate": str(resolved.certificate)}
    record["nominal_success"] = bool(nominal.success)
    record["nominal_mode_sequence"] = mode_string(nominal)
    if start_spec is not None:
        record["learned_transitions"] = [list(e) for e in policy.learned]
        record["spec"] = str(start_spec.path)
        if args.grown_spec is not None:
            _write_grown(policy, start_spec, args.grown_spec)
            record["grown_spec"] = str(args.grown_spec)
    if args.output is not None:
        from tli_verify.runtime.persist import save_certified

        assert saved_cert is not None
        save_certified(res.model, args.output, saved_cert, dt=_certified_dt(policy))
        record["saved"] = {"model": str(args.output), "certificate": str(saved_cert)}
    out.mkdir(parents=True, exist_ok=True)
    notes = []
    if args.animate is not None:
        from tli_verify.viz.episodes import animate_episode

        try:
            animate_episode(task, res, out / "run.gif", frames=args.animate,
                            title=f"{task.name} ({variant})")
            record["animation"] = str(out / "run.gif")
        except TliError as exc:
            notes.append(f"animation not drawn: {exc}")
    outside = ~task.in_workspace(res.states)
    if outside.any():  # a bound of the task: flagged, never clipped silently
        k = int(np.argmax(outside))
        record["beyond_workspace"] = {"steps": int(outside.sum()), "first_step": k,
                                      "state": [float(v) for v in res.states[k]]}
        notes.append(f"the state left the workspace box at step {k} "
                     f"({[round(float(v), 4) for v in res.states[k]]}; {int(outside.sum())} "
                     "step(s) beyond it): the workspace is a bound of the task (joint limits "
                     "in a joint-space task), and the picture shows the box only")
    picture = _picture(task, res, nominal, out / "run.png", variant, args.seed, notes)
    if picture is not None:
        record["picture"] = str(picture)
    atomic_write_text(out / "run.json", canonical_json(record))
    for n in notes:
        sys.stderr.write(f"note: {n}\n")
    if args.json:
        sys.stdout.write(canonical_json(record))
    else:
        seq = record["mode_sequence"]
        wrote = [str(out / "run.json"), *( [record["picture"]] if "picture" in record else []),
                 *([record["animation"]] if "animation" in record else [])]
        if "saved" in record:
            wrote += [record["saved"]["model"], record["saved"]["certificate"]]
        if "grown_spec" in record:
            wrote.append(record["grown_spec"])
        sys.stdout.write(
            f"{task.name} ({variant}): {'reached' if res.success else 'did NOT reach'} the "
            f"goal in {res.steps} steps ({res.steps * policy.dt:.2f} s simulated, "
            f"{seconds * 1e3:.0f} ms); modes {seq if len(seq) <= 40 else seq[:37] + '...'}; "
            f"{len(perturbations)} perturbation(s), {res.cuts_added} cut(s) added\n"
            + (_growth_line(res) if start_spec is not None else "")
            + f"wrote {', '.join(wrote)}\n")
    return 0 if res.success else 1


def _certified_dt(policy: Any) -> str:
    """The control period the policy's certificate proves (a saved model is re-certified at
    it)."""
    doc = read_json(policy.certificate, what="certificate", error=CertificateError)
    return str(doc["control_period"]["dt"])


def _picture(task: Any, res: Any, nominal: Any, path: Path, variant: str, seed: int,
             notes: list[str]) -> Path | None:
    """The Fig. 7-style picture of the episode, or None (with a note) if it cannot be drawn."""
    from tli_verify.viz.episodes import plot_episodes

    try:
        plot_episodes(task, [("", res)], path, nominal=nominal,
                      title=f"tli run --task {task.name} ({variant}, seed {seed})")
    except TliError as exc:
        notes.append(f"picture not drawn: {exc}")
        return None
    return path


def _growth_start(setup: Any, spec: Path | None) -> Any:
    """The spec to grow from (``--spec``, default the model's): same inputs and ``[modes]``
    labels as the spec the model names (the DS were learned on those labels).

    Raises
    ------
    TliError
        (exit 2) A spec that does not load or labels the modes otherwise.
    """
    named_path = Path(setup.spec)
    named = load_spec(named_path)
    if spec is None:
        return named
    start = load_spec(spec)
    if tuple(start.inputs) != tuple(named.inputs) or start.modes != named.modes:
        raise TliError(f"--spec {spec}: its sensors or [modes] labels differ from those of "
                       f"{named_path}, the spec the model names (its DS were learned on those "
                       "labels)")
    return start


def _write_grown(policy: Any, start: Any, path: Path) -> None:
    """Write the policy's current spec as TOML (atomically), with a provenance header."""
    learned = " ".join(f"{a}->{b}" for a, b in policy.learned) or "none"
    header = (f"# Grown online by `tli run --learn-transitions` from {start.path}.\n"
              f"# Transitions learned in this run: {learned}.\n")
    atomic_write_text(path, header + policy.spec_toml)


def _growth_line(res: Any) -> str:
    from tli_verify.runtime.events import TransitionLearned, TransitionRefused

    parts = []
    for e in res.events:
        if isinstance(e, TransitionLearned):
            parts.append(f"+{e.from_mode}->{e.to_mode} (step {e.step}: automaton {e.states} "
                         f"states, {e.mode_edges} mode changes)")
        elif isinstance(e, TransitionRefused):
            parts.append(f"refused {e.from_mode}->{e.to_mode or '?'} (step {e.step}: "
                         f"{e.reason})")
    return f"learned transitions: {', '.join(parts) if parts else 'none'}\n"


def demo_stage(out: Path) -> list[str]:
    """``tli demo``: gate the shipped files, run a perturbed scoop episode with and without
    modulation (``out/run/``), and the quick scoop experiment (``out/scoop/``)."""
    import os

    from tli_verify.deploy.gate import run_gate
    from tli_verify.experiments.scoop import ExperimentConfig
    from tli_verify.experiments.scoop_task import scoop_setup
    from tli_verify.runtime.episodes import episode_json, mode_string, random_start, run_variant
    from tli_verify.viz.episodes import plot_episodes

    root = bundled_root()
    report = run_gate(root)
    lines = [f"[run] gate on the shipped tasks/specs/models/certificates: "
             f"{'pass' if report.ok else 'BLOCKED'} ({len(report.items)} checks)"]
    if not report.ok:
        return [*lines, f"[run] gate blocked: {report.blockers[0].path}: "
                        f"{report.blockers[0].message}; episodes skipped"]
    setup = scoop_setup()
    seed = 19  # the unmodulated run loops (Fig. 7); LTL-DS cuts once
    perturbations = parse_perturb(["random:3"], seed=seed, task=setup.task)
    x0 = random_start(setup.task, setup.automaton, rng(seed, Stream.START))
    target = out / "run"
    results = {}
    for variant in ("LTL-DS", "no-modulation"):
        t0 = time.perf_counter()
        res = run_variant(setup, variant, x0, perturbations)
        rec = episode_json(res, task="scoop", variant=variant,
                           seconds=time.perf_counter() - t0, x0=x0,
                           perturbations=perturbations, dt=setup.task.dt)
        atomic_write_text(target / f"{variant}.json", canonical_json(rec))
        results[variant] = res
        seq = mode_string(res)
        lines.append(f"[run] scoop, 3 random perturbations (seed {seed}), {variant}: "
                     f"{'reached d' if res.success else 'did NOT reach d'} in {res.steps} "
                     f"steps, modes {seq if len(seq) <= 40 else seq[:37] + '...'}, "
                     f"{res.cuts_added} cut(s)")
    plot_episodes(setup.task, [("LTL-DS", results["LTL-DS"]),
                               ("no modulation", results["no-modulation"])],
                  target / "scoop_modulation.png", nominal=run_variant(setup, "LTL-DS", x0, {}),
                  goal_label="d",
                  title=f"tli run --task scoop --seed {seed} --perturb random:3: LTL-DS (left), "
                        "without modulation (right)")
    lines.append(f"[run] episodes -> {target}/LTL-DS.json, {target}/no-modulation.json, "
                 f"{target / 'scoop_modulation.png'}")
    cfg = ExperimentConfig(experiments=2, episodes=20, bc_epochs=60, steps=2000)
    summary, files = scoop_study(cfg, out / "scoop", workers=min(2, os.cpu_count() or 1),
                                 fig7_tries=0)
    row = ", ".join(f"{v} {t['percent']:.0f}%" for v, t in summary["totals"].items())
    lines.append(f"[run] scoop experiment (quick: 2 models x 20 perturbed episodes): {row}")
    lines.append(f"[run] scoop report: {files[0]}")
    return lines
