"""Campaign evidence for every bundled model: ``certificates/<name>.campaign.json`` (issue 12 D).

For each ``models/<name>.model.json`` of the repository (or of ``--root DIR``), runs a
bisimulation campaign (:func:`tli_verify.verify.campaign.run_campaign`) on the model, its
certificate ``certificates/<name>.cert.json`` and the spec the model names, with the sensor
model of the world that ships it (``tli_verify.runtime.bundles``; else the world named
``<name>``; ``--world NAME=WORLD`` for another), modulation on,
and writes the evidence ``tli gate`` requires (:mod:`tli_verify.verify.evidence`).

Usage (after any bundled model or certificate changed; one command)::

    .venv/bin/python scripts/make_evidence.py [--examples 1000] [--seed 0] [--workers W]
        [--backend process|serial|dask] [--only NAME ...] [--root DIR]

Prints one line per model. Exit 0 when every campaign found nothing (the gate then passes on
the evidence), 1 when one found a violation (its evidence is written anyway, as an honest
record the gate refuses), 2 on bad arguments or files.

The Franka policy (``sim/franka``, issue 13) has a physical campaign instead: ``--franka`` runs
``--trials`` (default 30, the gate's minimum) seeded, perturbed MuJoCo trials of the certified
LTL-DS executive (:func:`tli_verify.sim.campaign.run_physics_campaign`, the same trials as
``tli sim franka --trials N --seed S --evidence``) and writes
``sim/franka/certificates/franka-scoop.campaign.json``; ``tli gate sim/franka`` then checks it::

    .venv/bin/python scripts/make_evidence.py --franka [--trials 30] [--seed 0]
        [--robot hand|panda] [--duration 40] [--root sim/franka]

Re-run it whenever the Franka model or certificate is regenerated (the evidence binds their
SHA-256). One line per trial on stderr, then the evidence line; exit as above.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from tli_verify.errors import TliError
from tli_verify.verify.evidence import (
    MIN_EVIDENCE_EXAMPLES,
    evidence_path_for,
    model_stem,
    write_campaign_evidence,
)

DEFAULT_EXAMPLES = 1000
"""Examples per bundled model: 2x :data:`MIN_EVIDENCE_EXAMPLES` (the 95% bound on the failure
probability is then 0.3%)."""


def _world_map(items: list[str]) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, world = item.partition("=")
        if not sep or not name or not world:
            raise TliError(f"--world {item!r}: expected NAME=WORLD")
        out[name] = world
    return out


def _run(args: argparse.Namespace) -> int:
    import importlib

    from tli_verify.io import bundled_dir
    from tli_verify.runtime.bundles import world_of_model
    from tli_verify.worlds import WORLDS

    campaign = importlib.import_module("tli_verify.verify.campaign")  # the verify branch's
    CampaignConfig, run_campaign = campaign.CampaignConfig, campaign.run_campaign

    root = args.root if args.root is not None else bundled_dir("models").parent
    models = sorted((root / "models").glob("*.model.json"))
    if args.only:
        models = [m for m in models if model_stem(m) in set(args.only)]
        missing = sorted(set(args.only) - {model_stem(m) for m in models})
        if missing:
            raise TliError(f"--only: no models/{missing[0]}.model.json under {root}")
    if not models:
        raise TliError(f"{root / 'models'}: no *.model.json to make evidence for")
    worlds = _world_map(args.world)
    status = 0
    for model in models:
        name = model_stem(model)
        # the world that ships the model (tli run's registry), else the world named NAME
        world = worlds.get(name) or world_of_model(model) or name
        if world not in WORLDS:
            raise TliError(f"{model}: no world named {world!r} ({', '.join(sorted(WORLDS))}); "
                           f"pass --world {name}=WORLD")
        cert = root / "certificates" / f"{name}.cert.json"
        config = CampaignConfig(world=world, model=str(model), certificate=str(cert),
                                examples=args.examples, seed=args.seed, modulation=True,
                                workers=args.workers, backend=args.backend,
                                # worlds without a nominal start: starts drawn in the regions
                                # of the spec's initial states
                                random_starts=world not in campaign.NOMINAL_STARTS)
        t0 = time.perf_counter()
        result = run_campaign(config, progress=sys.stderr.isatty())
        seconds = time.perf_counter() - t0
        path, doc = write_campaign_evidence(config, result, evidence_path_for(model, root))
        total = doc["violations"]["total"]
        shown = path.relative_to(root) if path.is_relative_to(root) else path
        print(f"{shown}: world {world!r}, seed {args.seed}, {args.examples} examples, "
              f"{result.runs} runs, {total} violation(s), {seconds:.1f} s")
        if total or result.partial:
            status = 1
    return status


def _run_franka(args: argparse.Namespace) -> int:
    from tli_verify.sim.campaign import (
        PhysicsConfig,
        TrialVerdict,
        run_physics_campaign,
        write_physics_evidence,
    )
    from tli_verify.sim.loop import TrialResult, project_dir

    root = args.root if args.root is not None else project_dir()
    config = PhysicsConfig(root=str(root), seed=args.seed, trials=args.trials,
                           robot=args.robot, duration=args.duration)

    def progress(k: int, res: TrialResult, verdict: TrialVerdict) -> None:
        judged = "ok" if verdict.ok else ", ".join(verdict.violations)
        sys.stderr.write(f"  trial {k + 1}/{args.trials} (seed {res.seed}): {judged}; "
                         f"{res.delivered} bead(s); modes {res.mode_sequence()}\n")

    t0 = time.perf_counter()
    result = run_physics_campaign(config, on_trial=progress)
    path, _ = write_physics_evidence(result)
    shown = path.relative_to(root) if path.is_relative_to(root) else path
    print(f"{shown}: physical campaign, seed {args.seed}, {args.trials} trial(s) (robot "
          f"{args.robot}, {args.duration:g} s), {result.successes} delivered, "
          f"{sum(not v.ok for v in result.verdicts)} failed the oracle, "
          f"{time.perf_counter() - t0:.1f} s")
    return 0 if result.ok else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=DEFAULT_EXAMPLES,
                        help=f"examples per model (default {DEFAULT_EXAMPLES}; the gate needs "
                        f"at least {MIN_EVIDENCE_EXAMPLES})")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--backend", default="process", choices=("process", "serial", "dask"))
    parser.add_argument("--only", nargs="+", default=None, metavar="NAME",
                        help="only these models (models/NAME.model.json)")
    parser.add_argument("--world", action="append", default=[], metavar="NAME=WORLD",
                        help="the world of model NAME (default: the world named NAME)")
    parser.add_argument("--root", type=Path, default=None,
                        help="project directory (default: the repository; with --franka "
                        "sim/franka)")
    franka = parser.add_argument_group("the Franka policy's physical campaign (issue 13)")
    franka.add_argument("--franka", action="store_true",
                        help="run the physical campaign of sim/franka instead")
    franka.add_argument("--trials", type=int, default=None,
                        help="perturbed trials (default: the gate's minimum, 30)")
    franka.add_argument("--robot", default="hand", choices=("hand", "panda"))
    franka.add_argument("--duration", type=float, default=40.0,
                        help="step budget per trial, simulated seconds (default 20)")
    args = parser.parse_args(argv)
    if args.examples < 1 or not 0 <= args.seed < 2**32:
        parser.error("--examples must be >= 1 and --seed in [0, 2^32)")
    if args.franka:
        from tli_verify.verify.evidence import MIN_PHYSICS_TRIALS

        args.trials = MIN_PHYSICS_TRIALS if args.trials is None else args.trials
        if args.trials < 1 or args.seed + args.trials > 2**32:
            parser.error("--trials must be >= 1, with every trial's seed below 2^32")
    elif args.trials is not None:
        parser.error("--trials is for --franka")
    try:
        if args.franka:
            return _run_franka(args)
        return _run(args)
    except TliError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return exc.exit_code
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        return 130


if __name__ == "__main__":
    sys.exit(main())
