"""``tli run``: one closed-loop LTL-DS episode on a task world (paper eq. 6, Fig. 7).

Every world ships a spec, a certified model and its certificate (certified at ``dt = 1/100``),
listed in :data:`REGISTRY`: scoop (``specs/scoop.toml``), cooking (``cooking-cb``, the default,
and ``cooking-bc/c/cc`` through ``--spec``: one set of learned DS bound to each),
color tracing (``color-tracing-a``, default, ``-b``, ``-c``) and inspection.

``--learn-transitions`` grows the spec online (paper appendix E; README section 7): the run may
then start from another spec than the model names (``--spec``, e.g. one ``tli spec infer``
wrote), provided it has the same sensors and the same ``[modes]`` labels; transitions the spec
lacks are added as the episode shows them, and ``--grown-spec OUT.toml`` writes the grown spec.
The model and its certificate keep binding the spec the model names.

Exit codes: 0 the episode reached the goal, 1 it did not (or the certificate does not cover
the model: the executive refuses it), 2 bad arguments.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

from tli_verify.commands import int_range, output_path
from tli_verify.runtime.bundles import REGISTRY, Bundle

__all__ = ["REGISTRY", "Bundle", "demo_stage", "parse_perturb", "register", "world_setup"]

SUPPORTED = tuple(REGISTRY)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli run``."""
    p = sub.add_parser(
        "run", help="run one closed-loop LTL-DS episode on a world",
        description="Task automaton + certified, modulated DS per mode in closed loop with a "
        "world's sensors; perturbations, online cuts, replanning. Writes run.json and a "
        "Fig. 7-style run.png to --out. Exit 0: the goal mode was reached; 1: it was not.")
    p.add_argument("--world", required=True,
                   help=f"world name ({', '.join(REGISTRY)})")
    p.add_argument("--seed", type=int, default=0, help="seed of the start and of random:N")
    p.add_argument("--start", default=None, metavar="X1,X2",
                   help="start state (default: a seeded random state whose reading is an "
                   "initial one of the spec)")
    p.add_argument("--perturb", action="append", default=[], metavar="T:DX,DY|random:N",
                   help="displace the state by (DX, DY) before step T (repeatable), or N "
                   "seeded random perturbations (directions uniform, magnitudes up to the "
                   "workspace size)")
    p.add_argument("--no-modulation", action="store_true", help="learn no cuts")
    p.add_argument("--no-replan", action="store_true",
                   help="run the demonstrated mode sequence open loop")
    p.add_argument("--steps", type=int, default=3000, help="step budget (default 3000)")
    p.add_argument("--lag", type=int, default=0, help="sensor lag in steps (default 0)")
    p.add_argument("--model", type=Path, default=None, help="model file (default: bundled)")
    p.add_argument("--certificate", type=Path, default=None,
                   help="certificate file (default: bundled)")
    p.add_argument("--spec", type=Path, default=None,
                   help="spec file (default: the world's first bundled spec; a world's other "
                   "bundled spec picks its bundled model and certificate; with "
                   "--learn-transitions the spec to grow from, with the same sensors and "
                   "[modes] labels)")
    p.add_argument("--learn-transitions", action="store_true",
                   help="add a valid transition the spec lacks (into a known mode) to it "
                   "online, re-synthesize and carry on (paper appendix E)")
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
                   "certificate (at dt = 1/100) next to it as <name>.cert.json; both written "
                   "atomically, nothing written if it does not certify")
    p.set_defaults(handler=_run)


def _floats(text: str, n: int, what: str) -> list[float]:
    import math

    from tli_verify.errors import TliError

    parts = text.split(",")
    try:
        vals = [float(v) for v in parts]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise TliError(f"{what}: expected {n} comma-separated finite numbers, got {text!r}")
    return vals


def parse_perturb(items: list[str], *, seed: int, world: Any) -> dict[int, Any]:
    """``--perturb`` values -> ``{step: displacement}``.

    Raises
    ------
    TliError
        (exit 2) A malformed item, a step < 1, a repeated step, N < 0.
    """
    import numpy as np

    from tli_verify.errors import TliError
    from tli_verify.experiments.scoop import random_perturbations

    out: dict[int, Any] = {}
    rng = np.random.default_rng([seed, 11])
    for item in items:
        if item.startswith("random:"):
            n_text = item[len("random:"):]
            if not n_text.isdigit():
                raise TliError(f"--perturb {item!r}: random:N needs a count N >= 0")
            for t, d in random_perturbations(rng, int(n_text), world).items():
                if t in out:
                    raise TliError(f"--perturb {item!r}: step {t} is perturbed twice")
                out[t] = d
            continue
        head, sep, tail = item.partition(":")
        if not sep or not head.strip().isdigit():
            raise TliError(f"--perturb {item!r}: expected T:DX,DY (T a step >= 1) or random:N")
        t = int(head)
        if t < 1:
            raise TliError(f"--perturb {item!r}: step must be >= 1")
        if t in out:
            raise TliError(f"--perturb {item!r}: step {t} is perturbed twice")
        out[t] = np.array(_floats(tail, 2, f"--perturb {item!r}"))
    return out


def certificate_next_to(model: Path) -> Path:
    """``<dir>/<name>.cert.json`` for ``<dir>/<name>.model.json`` (or ``<name>.json``)."""
    name = model.name
    for suffix in (".model.json", ".json"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
            break
    return model.with_name(f"{name}.cert.json")


def world_setup(world: str, *, model: Path | None = None, certificate: Path | None = None,
                spec: Path | None = None, lag: int = 0) -> tuple[Any, Bundle]:
    """The closed-loop setup of a world: its bundle (``--spec`` picks one), files, world.

    Parameters
    ----------
    world : str
        A key of :data:`REGISTRY`.
    model, certificate, spec : Path, optional
        Files given on the command line (default: the bundle's).
    lag : int, optional
        Sensor lag (steps).

    Returns
    -------
    setup : tli_verify.experiments.scoop.Setup
    bundle : Bundle
        The bundle whose goal the episode uses: the one of ``--spec``, else of the spec the
        model names, else the default (``bundled_setup`` checks the spec against the model).

    Raises
    ------
    SpecError, ModelError, TliError
        (exit 2) Unreadable files; a spec that is not the one the model names.
    """
    import dataclasses

    from tli_verify.experiments.scoop import bundled_setup
    from tli_verify.io import bundled_dir
    from tli_verify.worlds import WORLDS

    bundles = REGISTRY[world]
    bundle = bundles[0]
    if spec is not None:
        real = os.path.realpath(spec)
        for b in bundles:
            if os.path.realpath(bundled_dir("specs") / f"{b.spec}.toml") == real:
                bundle = b
                break
    setup = bundled_setup(
        model=model if model is not None else bundled_dir("models") / bundle.model_file,
        certificate=(certificate if certificate is not None
                     else bundled_dir("certificates") / bundle.certificate_file),
        spec=spec, lag=lag)
    named = setup.model.spec_path
    if spec is None and named is not None:  # --model: the goal of the spec it names
        for b in bundles:
            if os.path.realpath(bundled_dir("specs") / f"{b.spec}.toml") == \
                    os.path.realpath(named):
                bundle = b
                break
    world_model: Any = WORLDS[world](lag=lag)  # Setup is typed for scoop; any World runs
    return dataclasses.replace(setup, world=world_model), bundle


def initial_start(setup: Any, rng: Any, *, tries: int = 10000) -> Any:
    """A uniform random state of the workspace whose first reading is an initial one of the
    automaton (the spec's ``assume.init``), shape (2,).

    Raises
    ------
    TliError
        (exit 2) No such state in ``tries`` draws.
    """
    import numpy as np

    from tli_verify.errors import TliError
    from tli_verify.logic.automaton import AssumptionViolation

    world = setup.world
    lo, hi = np.array(world.lo), np.array(world.hi)
    names = world.sensor_names
    for _ in range(tries):
        x = rng.uniform(lo, hi)
        reading = world.sensors(x[None])[0]
        try:
            setup.automaton.initial_state({n: bool(v) for n, v in zip(names, reading,
                                                                       strict=True)})
        except AssumptionViolation:
            continue
        return x
    raise TliError(f"{world.name}: no start with an initial reading in {tries} draws")


def bundle_policy(setup: Any, variant: str, bundle: Bundle) -> Any:
    """The executive of a variant, with the bundle's goal (:func:`make_policy` otherwise).

    A bundle with ``goal_inputs`` (inspection: ``rel``) is done in a goal mode only on a
    reading with those sensors true (the spec's goal ``b & rel``, not just mode ``b``).

    Raises
    ------
    CertificateError
        (exit 1) The certificate does not cover the model.
    """
    from tli_verify.experiments.scoop import make_policy

    if bundle.goal_modes is None and not bundle.goal_inputs:
        return make_policy(setup, variant)
    from tli_verify.experiments.scoop import SequencePolicy
    from tli_verify.runtime.executive import LTLDSPolicy

    cls = SequencePolicy if variant == "no-replan" else LTLDSPolicy
    kwargs: dict[str, Any] = ({} if variant == "no-replan"
                              else {"learn_cuts": variant != "no-modulation"})
    return cls(setup.automaton, setup.model, setup.certificate, goal_modes=bundle.goal_modes,
               goal_inputs=bundle.goal_inputs, **kwargs)


def _run(args: argparse.Namespace) -> int:
    import numpy as np

    from tli_verify.errors import TliError
    from tli_verify.experiments.scoop import (
        episode_json,
        mode_string,
        plot_episode,
        random_start,
        run_variant,
    )
    from tli_verify.io import atomic_write_text, canonical_json

    if args.world not in REGISTRY:
        raise TliError(f"--world {args.world!r}: unknown world (worlds: "
                       f"{', '.join(sorted(REGISTRY))})")
    if args.steps < 1:
        raise TliError(f"--steps must be >= 1, got {args.steps}")
    if args.lag < 0:
        raise TliError(f"--lag must be >= 0, got {args.lag}")
    if args.seed < 0:
        raise TliError(f"--seed must be >= 0, got {args.seed}")
    if args.no_modulation and args.no_replan:
        raise TliError("--no-modulation and --no-replan: choose one ablation")
    if args.grown_spec is not None and not args.learn_transitions:
        raise TliError("--grown-spec needs --learn-transitions")
    if args.grown_spec is not None:
        from tli_verify.io import check_output_file

        inputs = [p for p in (args.model, args.certificate, args.spec) if p is not None]
        check_output_file(args.grown_spec, inputs=inputs, what="grown spec")
    if args.output is not None:  # the certificate written next to -o must not be an input
        from tli_verify.io import check_output_file

        inputs = [p for p in (args.model, args.certificate, args.spec) if p is not None]
        check_output_file(certificate_next_to(args.output), inputs=[args.output, *inputs],
                          what="certificate")
    setup, bundle = world_setup(args.world, model=args.model, certificate=args.certificate,
                                spec=None if args.learn_transitions else args.spec,
                                lag=args.lag)
    start_spec = _growth_start(setup, args.spec) if args.learn_transitions else None
    if args.grown_spec is not None:  # never over the files the certificate binds
        from tli_verify.io import check_output_file

        bound = [setup.model.path, setup.certificate, setup.model.spec_path,
                 None if start_spec is None else start_spec.path]
        check_output_file(args.grown_spec, inputs=[p for p in bound if p is not None],
                          what="grown spec")
    if start_spec is not None:
        from dataclasses import replace

        from tli_verify.logic.check import synthesize

        setup = replace(setup, automaton=synthesize(start_spec))
    world = setup.world
    perturbations = parse_perturb(args.perturb, seed=args.seed, world=world)
    if args.start is not None:
        x0 = np.array(_floats(args.start, 2, f"--start {args.start!r}"))
        if not bool(world.in_workspace(x0[None])[0]):
            raise TliError(f"--start {args.start!r}: outside the workspace "
                           f"[{world.lo[0]:g}, {world.hi[0]:g}] x [{world.lo[1]:g}, "
                           f"{world.hi[1]:g}]")
    elif args.world == "scoop":
        x0 = random_start(world, np.random.default_rng([args.seed, 3]))
    else:
        x0 = initial_start(setup, np.random.default_rng([args.seed, 3]))
    variant = ("no-modulation" if args.no_modulation else
               "no-replan" if args.no_replan else "LTL-DS")
    # refuses a model its certificate does not cover
    policy = (bundle_policy(setup, variant, bundle) if start_spec is None
              else _growing_policy(setup, variant, start_spec))
    t0 = time.perf_counter()
    res = run_variant(setup, variant, x0, perturbations, steps=args.steps, policy=policy)
    seconds = time.perf_counter() - t0
    nominal = run_variant(setup, variant, x0, {}, steps=args.steps,
                          policy=bundle_policy(setup, variant, bundle))
    record = episode_json(res, world=args.world, variant=variant, seconds=seconds, x0=x0,
                          perturbations=perturbations, dt=policy.dt)
    record["nominal_success"] = bool(nominal.success)
    record["nominal_mode_sequence"] = mode_string(nominal)
    if start_spec is not None:
        record["learned_transitions"] = [list(e) for e in policy.learned]
        record["spec"] = str(start_spec.path)
        if args.grown_spec is not None:
            _write_grown(policy, start_spec, args.grown_spec)
            record["grown_spec"] = str(args.grown_spec)
    if args.output is not None:
        from tli_verify.experiments.scoop import CERT_DT
        from tli_verify.runtime.persist import save_certified

        cert = certificate_next_to(args.output)
        save_certified(res.model, args.output, cert, dt=CERT_DT)
        record["saved"] = {"model": str(args.output), "certificate": str(cert)}
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    if args.animate is not None:
        from tli_verify.experiments.scoop import animate_episode

        animate_episode(world, res, out / "run.gif", frames=args.animate,
                        title=f"{args.world} ({variant})")
        record["animation"] = str(out / "run.gif")
    atomic_write_text(out / "run.json", canonical_json(record))
    plot_episode(world, res, out / "run.png", nominal=nominal,
                 title=f"tli run --world {args.world} ({variant}, seed {args.seed})")
    if args.json:
        sys.stdout.write(canonical_json(record))
    else:
        seq = record["mode_sequence"]
        sys.stdout.write(
            f"{args.world} ({variant}): {'reached' if res.success else 'did NOT reach'} the "
            f"goal mode in {res.steps} steps ({res.steps * policy.dt:.2f} s simulated, "
            f"{seconds * 1e3:.0f} ms); modes {seq if len(seq) <= 40 else seq[:37] + '...'}; "
            f"{len(perturbations)} perturbation(s), {res.cuts_added} cut(s) added\n"
            + (_growth_line(res) if start_spec is not None else "")
            + f"wrote {out / 'run.json'}, {out / 'run.png'}"
            + (f", {record['animation']}" if "animation" in record else "")
            + (f", {record['saved']['model']}, {record['saved']['certificate']}"
               if "saved" in record else "")
            + (f", {record['grown_spec']}" if "grown_spec" in record else "") + "\n")
    return 0 if res.success else 1


def _growth_start(setup: Any, spec: Path | None) -> Any:
    """The spec to grow from (``--spec``, default the model's): same inputs and ``[modes]``
    labels as the spec the model names (the DS were learned on those labels).

    Raises
    ------
    TliError
        (exit 2) A spec that does not load or labels the modes otherwise.
    """
    from tli_verify.errors import TliError
    from tli_verify.io import bundled_dir
    from tli_verify.logic.spec import load_spec

    named_path = setup.model.spec_path or bundled_dir("specs") / "scoop.toml"
    named = load_spec(named_path)
    if spec is None:
        return named
    start = load_spec(spec)
    if tuple(start.inputs) != tuple(named.inputs) or start.modes != named.modes:
        raise TliError(f"--spec {spec}: its sensors or [modes] labels differ from those of "
                       f"{named_path}, the spec the model names (its DS were learned on those "
                       "labels)", exit_code=2)
    return start


def _growing_policy(setup: Any, variant: str, spec: Any) -> Any:
    """:func:`~tli_verify.experiments.scoop.make_policy` with ``learn_transitions``."""
    from tli_verify.experiments.scoop import SequencePolicy
    from tli_verify.runtime.executive import LTLDSPolicy

    if variant == "no-replan":
        return SequencePolicy(setup.automaton, setup.model, setup.certificate, spec=spec,
                              learn_transitions=True)
    return LTLDSPolicy(setup.automaton, setup.model, setup.certificate,
                       learn_cuts=variant != "no-modulation", spec=spec,
                       learn_transitions=True)


def _write_grown(policy: Any, start: Any, path: Path) -> None:
    """Write the policy's current spec as TOML (atomically), with a provenance header."""
    from tli_verify.io import atomic_write_text

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
    import numpy as np

    from tli_verify.certify.gate import run_gate
    from tli_verify.commands.experiment import scoop_study
    from tli_verify.experiments.scoop import (
        ExperimentConfig,
        bundled_setup,
        episode_json,
        mode_string,
        plot_episode,
        random_start,
        run_variant,
    )
    from tli_verify.io import atomic_write_text, bundled_dir, canonical_json

    root = bundled_dir("models").parent
    report = run_gate(root)
    lines = [f"[run] gate on the shipped specs/models/certificates: "
             f"{'pass' if report.ok else 'BLOCKED'} ({len(report.items)} checks)"]
    if not report.ok:
        return [*lines, f"[run] gate blocked: {report.blockers[0].path}: "
                        f"{report.blockers[0].message}; episodes skipped"]
    setup = bundled_setup()
    seed = 19  # the unmodulated run loops (Fig. 7); LTL-DS cuts once
    perturbations = parse_perturb(["random:3"], seed=seed, world=setup.world)
    x0 = random_start(setup.world, np.random.default_rng([seed, 3]))
    target = out / "run"
    results = {}
    for variant in ("LTL-DS", "no-modulation"):
        t0 = time.perf_counter()
        res = run_variant(setup, variant, x0, perturbations)
        rec = episode_json(res, world="scoop", variant=variant,
                           seconds=time.perf_counter() - t0, x0=x0,
                           perturbations=perturbations, dt=0.01)
        atomic_write_text(target / f"{variant}.json", canonical_json(rec))
        results[variant] = res
        seq = mode_string(res)
        lines.append(f"[run] scoop, 3 random perturbations (seed {seed}), {variant}: "
                     f"{'reached d' if res.success else 'did NOT reach d'} in {res.steps} "
                     f"steps, modes {seq if len(seq) <= 40 else seq[:37] + '...'}, "
                     f"{res.cuts_added} cut(s)")
    plot_episode(setup.world, results["LTL-DS"], target / "scoop_modulation.png",
                 others=[("no modulation", results["no-modulation"])],
                 nominal=run_variant(setup, "LTL-DS", x0, {}),
                 title=f"tli run --world scoop --seed {seed} --perturb random:3: LTL-DS (left), "
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
