"""``tli demo``: run the whole pipeline, as far as it exists, on the bundled defaults."""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import output_path
from tli_verify.errors import OutputError

DEMO_STAGES: tuple[str, ...] = (
    "tli_verify.commands.spec",
    "tli_verify.commands.motion",
    "tli_verify.commands.experiment",
    "tli_verify.commands.run",
)


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli demo``."""
    p = sub.add_parser("demo", help="run the pipeline on the bundled specs and demos")
    p.add_argument("--out", type=output_path, default=Path("out"),
                   help="output directory (default: out)")
    p.set_defaults(handler=_run)


def _run(args: argparse.Namespace) -> int:

    out: Path = args.out  # checked by tli_verify.cli.check_paths before this handler
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out}: cannot create the output directory: "
                          f"{exc.strerror or exc}") from None
    for name in DEMO_STAGES:
        for line in importlib.import_module(name).demo_stage(out):
            sys.stdout.write(line + "\n")
    sys.stdout.write(f"results written under {out}/\n")
    return 0
