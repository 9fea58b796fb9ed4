"""The ``tli`` command line.

Conventions (``docs/design.md``, "Exit codes"): 0 success; 1 a check said no (unrealizable,
invalid certificate, gate blocked, property violated); 2 bad input or usage. Errors are one line
on stderr starting with ``error:``; a traceback only with ``--debug``.

Before any handler runs, :func:`check_paths` refuses outputs that cannot be written or that
resolve to one of the command's inputs (conventions in :mod:`tli_verify.commands`).

Each subcommand group lives in its own module under :mod:`tli_verify.commands` and exposes
``register(subparsers)``; the modules are imported only to build the parser, and they import
their heavy dependencies inside the handlers, so ``tli --help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import traceback
from collections.abc import Sequence
from pathlib import Path

from tli_verify import __version__
from tli_verify.errors import TliError

__all__ = ["build_parser", "check_paths", "main"]

COMMAND_MODULES: tuple[str, ...] = (
    "tli_verify.commands.spec",
    "tli_verify.commands.motion",
    "tli_verify.commands.experiment",
    "tli_verify.commands.run",
    "tli_verify.commands.demo",
    "tli_verify.commands.verify",
    "tli_verify.commands.sim",
    "tli_verify.commands.task",
)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one ``error:`` line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    """Build the ``tli`` parser with every registered subcommand."""
    parser = _Parser(
        prog="tli",
        description="tli-verify: LTL task automata, certified LPV-DS motion policies, "
        "cutting-plane modulation and a deployment gate (Temporal Logic Imitation).",
    )
    parser.add_argument("--version", action="version", version=f"tli-verify {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def check_paths(args: argparse.Namespace) -> None:
    """Refuse bad output paths of a parsed command line before any work is done.

    ``args.output`` and ``args.repair`` are output files, ``args.out`` an output directory;
    every other :class:`~pathlib.Path` value (or list of them) is an input file the outputs
    must not overwrite (:func:`tli_verify.io.check_output_file`).

    Raises
    ------
    OutputError
        (exit 2) Naming the output and what is wrong with it.
    """
    from tli_verify.io import check_output_dir, check_output_file

    inputs: list[Path] = []
    for name, value in vars(args).items():
        if name in ("output", "out", "repair"):
            continue
        if isinstance(value, Path):
            inputs.append(value)
        elif isinstance(value, list | tuple):
            inputs += [v for v in value if isinstance(v, Path)]
    for name in ("repair", "output"):  # output files: never an input, never each other
        output = getattr(args, name, None)
        if isinstance(output, Path):
            check_output_file(output, inputs=inputs)
            inputs.append(output)
    out = getattr(args, "out", None)
    if isinstance(out, Path):
        check_output_dir(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``tli`` and return its exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        check_paths(args)
        return int(handler(args))
    except TliError as exc:
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(f"error: {exc}\n")
        return exc.exit_code
    except BrokenPipeError:  # e.g. `tli ... | head`: the reader left; not an error of ours
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        sys.stderr.write("error: interrupted\n")
        return 130
    except Exception as exc:  # an internal bug: still one line unless --debug
        if args.debug:
            traceback.print_exc()
        sys.stderr.write(
            f"error: internal error ({type(exc).__name__}: {' '.join(str(exc).split())}); "
            "rerun with --debug for a traceback\n"
        )
        return 70


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
