"""Learn and certify the bundled models of the cooking, color-tracing and inspection worlds.

Usage: ``.venv/bin/python scripts/make_models.py [--world cooking|color-tracing|inspection|all]``
(from the repository root). Every step is a ``tli`` command, printed before it runs and run
in-process through :func:`tli_verify.cli.main`, so each line can be pasted into a shell:

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
  (:class:`tli_verify.worlds.ColorTracingWorld`).

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

SHARED = {
    "cooking": ("cooking-cb", "cooking-bc", "cooking-c", "cooking-cc"),
    "color-tracing": ("color-tracing-a", "color-tracing-b", "color-tracing-c"),
}
"""World -> the specs one learned set of DS is bound to."""

WITH_SPEC = {"inspection": "inspection"}
"""World -> the spec it is learned with directly."""


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
    from tli_verify.model import load_model, save_model
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


def main(argv: list[str] | None = None) -> int:
    """Entry point."""
    import os

    parser = argparse.ArgumentParser(prog="make_models.py")
    parser.add_argument("--world", choices=[*SHARED, *WITH_SPEC, "all"], default="all")
    args = parser.parse_args(argv)
    os.chdir(ROOT)
    names = [*SHARED, *WITH_SPEC] if args.world == "all" else [args.world]
    for world in names:
        make(world)
    return 0


if __name__ == "__main__":
    sys.exit(main())
