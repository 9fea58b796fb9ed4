"""Learn and certify the bundled models of the cooking, color-tracing and inspection worlds.

Usage: ``.venv/bin/python scripts/make_models.py [--task cooking|color-tracing|inspection|all]
[--check N [--perturbations K]] [--recovery]`` (from the repository root). ``--check`` learns
nothing: it runs N seeded perturbed ``tli run`` episodes per bundled spec and prints the
success counts; ``--recovery`` prints the first tile the color-tracing recovery DS enter from
uniform dark starts.
Every step is a ``tli`` command, printed before it runs and run in-process through
:func:`tli_verify.cli.main`, so each line can be pasted into a shell:

* **inspection**: ``tli learn demos/inspection_*.csv --spec specs/inspection.toml`` (two modes,
  learned with the spec), then ``tli certify``;
* **cooking**: *one* ``tli learn`` of ``demos/cooking_*.csv`` *without* a spec (one DS per
  demonstrated sensor transition, modes named by readings), then a re-binding step
  (:func:`tli_verify.rebind.rebind_model`, no learning: the same DS objects keyed by each spec's
  modes) to ``models/cooking-{cb,bc,c,cc}.model.json``, then ``tli certify`` of each. The four
  files carry the same DS bit for bit (paper appendix "Generalization": "learned once and
  reused, without relearning");
* **color-tracing**: the same for ``specs/color-tracing-{a,b,c}.toml`` from the tile
  demonstration and the recovery demonstrations out of the dark region
  (``tasks/color-tracing.toml``).

Learning uses ``--control-dt 0.01`` and certification ``--dt 0.01``: the period ``tli run``
runs at. The scoop model (``models/scoop.model.json``) is not touched here (see
``scripts/make_demos.py``). The learned, spec-free intermediate is written to a temporary
directory and deleted: only bound, certified models are deployed (the gate refuses a model
that names no spec).
"""

from __future__ import annotations

import argparse
import shlex
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SEED = 0
CONTROL_DT = "0.01"

SCOOP = "scoop"
"""The scoop model is made by its own recipe (scripts/make_demos.py), not here."""


def specs_of(task: str) -> tuple[str, ...]:
    """The bundled specs written over a task (their ``task`` key), expected realizable."""
    from tli_verify.logic.spec import load_spec

    out = []
    for path in sorted((ROOT / "specs").glob("*.toml")):
        spec = load_spec(path)
        if spec.task == task and spec.expect == "realizable":
            out.append(path.stem)
    return tuple(out)


def recipes() -> tuple[dict[str, tuple[str, ...]], dict[str, str]]:
    """Task -> specs of one learned DS set (several specs: learn once, rebind to each), and
    task -> the one spec it is learned with directly; from the specs' task keys."""
    from tli_verify.tasks.registry import bundled_tasks

    shared: dict[str, tuple[str, ...]] = {}
    with_spec: dict[str, str] = {}
    for task in sorted(bundled_tasks()):
        if task == SCOOP:
            continue
        specs = specs_of(task)
        if len(specs) > 1:
            shared[task] = specs
        elif specs:
            with_spec[task] = specs[0]
    return shared, with_spec


SHARED, WITH_SPEC = recipes()
"""Task -> the specs one learned set of DS is bound to; task -> the spec it is learned with
directly (derived from the specs' ``task`` keys: no list of worlds here)."""


def tli(*argv: str) -> None:
    """Print and run one ``tli`` command; stop on a non-zero exit."""
    from tli_verify.cli import main

    sys.stdout.write("$ tli " + " ".join(shlex.quote(a) for a in argv) + "\n")
    sys.stdout.flush()
    code = main(list(argv))
    if code != 0:
        raise SystemExit(f"tli {argv[0]} exited with {code}")


def demos(world: str) -> list[str]:
    """The world's bundled demonstrations, relative to the repository root."""
    paths = sorted((ROOT / "demos").glob(f"{world}_*.csv"))
    if not paths:
        raise SystemExit(f"no demos/{world}_*.csv")
    return [str(p.relative_to(ROOT)) for p in paths]


def make(world: str) -> list[Path]:
    """Learn, bind and certify one world's models; return the model files."""
    from tli_verify.model.serialize import load_model, save_model
    from tli_verify.rebind import rebind_model

    out: list[Path] = []
    if world in WITH_SPEC:
        name = WITH_SPEC[world]
        model = f"models/{name}.model.json"
        tli("learn", *demos(world), "--spec", f"specs/{name}.toml", "-o", model,
            "--seed", str(SEED), "--control-dt", CONTROL_DT)
        out.append(ROOT / model)
    else:
        with tempfile.TemporaryDirectory(prefix=f"tli-{world}-") as tmp:
            learned = str(Path(tmp) / f"{world}.learned.json")
            tli("learn", *demos(world), "-o", learned, "--seed", str(SEED),
                "--control-dt", CONTROL_DT)
            base = load_model(learned)
            for name in SHARED[world]:
                model = ROOT / "models" / f"{name}.model.json"
                sys.stdout.write(f"# rebind (no learning): {world} DS -> specs/{name}.toml -> "
                                 f"models/{name}.model.json\n")
                save_model(rebind_model(base, ROOT / "specs" / f"{name}.toml", model), model)
                out.append(model)
    for model in out:
        rel = str(model.relative_to(ROOT))
        tli("certify", rel, "--dt", CONTROL_DT)
    return out


def check(world: str, episodes: int, perturbations: int) -> None:
    """Closed-loop success of every bundle of a world on seeded perturbed episodes.

    Prints, per bundle: LTL-DS success, episodes with an assumption violation (a perturbation
    or a DS crossing into a region the spec's assumptions rule out), cuts learned. Seeds
    ``0 .. episodes-1``, as ``tli run --spec S --seed K --perturb random:N``.
    """
    import numpy as np

    from tli_verify.commands.run import parse_perturb
    from tli_verify.loaded import load_project
    from tli_verify.runtime.episodes import random_start, run_variant
    from tli_verify.runtime.events import AssumptionViolationEvent
    from tli_verify.runtime.setup import make_policy

    for spec in (*SHARED.get(world, ()), *([WITH_SPEC[world]] if world in WITH_SPEC else [])):
        setup = load_project(spec=ROOT / "specs" / f"{spec}.toml").setup
        ok = violated = cuts = 0
        for seed in range(episodes):
            pert = parse_perturb([f"random:{perturbations}"], seed=seed, task=setup.task)
            x0 = random_start(setup.task, setup.automaton, np.random.default_rng([seed, 3]))
            res = run_variant(setup, "LTL-DS", x0, pert, policy=make_policy(setup, "LTL-DS"))
            ok += bool(res.success)
            violated += any(isinstance(e, AssumptionViolationEvent) for e in res.events)
            cuts += res.cuts_added
        sys.stdout.write(f"{spec}: LTL-DS reached the goal in {ok}/{episodes} episodes "
                         f"(random:{perturbations}); {violated} with an assumption violation; "
                         f"{cuts} cut(s)\n")


def recovery_entries(starts: int = 300, steps: int = 4000) -> None:
    """Where the color-tracing recovery DS first leave the dark, from uniform dark starts.

    Each dark mode's DS alone (no automaton, no cuts; Euler at dt = 0.01, seed 0) from the
    same ``starts`` uniform states of the dark region: the first tile each run enters (the
    dark region is not convex, so Lemma 2 does not promise the re-entry tile).
    """
    import numpy as np

    from tli_verify.model.serialize import load_model
    from tli_verify.tasks.registry import find_task

    world = find_task("color-tracing")
    X0 = world.sample_region("dark", starts, np.random.default_rng(0))
    names = np.array([*world.region_names, "none"])
    for spec, mode, nxt in (("color-tracing-a", "d1", "y"), ("color-tracing-b", "d2", "b"),
                            ("color-tracing-c", "d2", "pk")):
        model = load_model(ROOT / "models" / f"{spec}.model.json")
        X = X0.copy()
        first = np.full(len(X), -1)
        for _ in range(steps):
            X = X + 0.01 * model.velocity(X, mode=mode, next_mode=nxt)
            idx = world.region_index(X)
            new = (first < 0) & (idx != world.region_names.index("dark"))
            first[new] = idx[new]
            if (first >= 0).all():
                break
        got = names[np.where(first < 0, len(names) - 1, first)]
        counts = ", ".join(f"{n} {int((got == n).sum())}" for n in names if (got == n).any())
        sys.stdout.write(f"{spec} {mode}->{nxt}: first tile entered from {starts} dark "
                         f"starts: {counts}\n")


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    import os

    parser = argparse.ArgumentParser(prog="make_models.py")
    parser.add_argument("--task", choices=[*SHARED, *WITH_SPEC, "all"],
                        default="all")
    parser.add_argument("--check", type=int, default=0, metavar="N",
                        help="instead of learning: run N seeded perturbed episodes per bundled "
                        "spec and print the success counts")
    parser.add_argument("--perturbations", type=int, default=2, metavar="K",
                        help="random perturbations per --check episode (default 2)")
    parser.add_argument("--recovery", action="store_true",
                        help="instead of learning: where the color-tracing recovery DS first "
                        "leave the dark, from 300 uniform dark starts")
    args = parser.parse_args(argv)
    os.chdir(ROOT)
    if args.recovery:
        recovery_entries()
        return 0
    names = [*SHARED, *WITH_SPEC] if args.task == "all" else [args.task]
    for world in names:
        if args.check > 0:
            check(world, args.check, args.perturbations)
        else:
            make(world)
    return 0


if __name__ == "__main__":
    sys.exit(main())
