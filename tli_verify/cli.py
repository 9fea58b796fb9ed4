"""The ``tli`` command line.

Conventions (``docs/design.md``, "Exit codes"): 0 success; 1 a check said no (unrealizable,
invalid certificate, gate blocked, property violated); 2 bad input or usage. Errors are one line
on stderr starting with ``error:``; a traceback only with ``--debug``.

Before any handler runs, :func:`check_paths` refuses outputs that cannot be written or that
resolve to one of the command's inputs (conventions in :mod:`tli_verify.commands`).

Each subcommand group lives in its own module under :mod:`tli_verify.commands` and exposes
``register(subparsers)``; the modules are imported only to build the parser, and they import
their heavy dependencies inside the handlers, so ``tli --help`` stays fast.

The environment is set up before anything is dispatched (:func:`main`), so that a hostile one
is bad input (exit 2, one ``error:`` line), never an internal error (70) or a traceback:

* **standard output closed** (``tli ... >&-``): refused before any work, exit 2 ("standard
  output is closed"). Most commands' result *is* their output (a verdict, JSON), so running
  with nowhere to print it would lose it; redirect to ``/dev/null`` to drop it on purpose.
  Closed descriptors 0-2 are first reopened on ``/dev/null``, so that no file the command
  opens can land on them. A closed standard input reads as empty; a closed standard error
  drops the messages (the exit code still tells).
* **standard output unwritable** (``> /dev/full``, a disk full, an I/O error): writes to
  :data:`sys.stdout` go through a stand-in that turns the failure into exit 2 and ``error:
  cannot write standard output: <reason>``; the output is flushed inside :func:`main` (not at
  the interpreter's exit), and what could not be written is dropped so that the exit does not
  fail a second time. A reader that left (``tli ... | head``, a broken pipe) is not an error:
  the rest of the output is dropped, and the exit is the command's code if it had finished,
  else 0.
  Writes to :data:`sys.stderr` that fail are dropped.
* **an encoding that cannot show a path** (``PYTHONIOENCODING=ascii``, a file name that is
  not UTF-8): standard output and error use ``errors="backslashreplace"`` (unless already
  lenient), so ``spéc.toml`` prints as ``sp\\xe9c.toml``.
* **matplotlib**: the CLI is headless; ``MPLBACKEND`` is set to ``agg`` whatever the
  environment says (a bogus or GUI backend would fail when a picture is drawn).
* **a deleted working directory**: refused before the handler runs (exit 2, "the working
  directory no longer exists"): relative paths cannot resolve there, and the project
  resolver and the output checks need the working directory; ``--help`` still works.
* **SIGTERM** stops ``tli`` as Ctrl-C does (:class:`KeyboardInterrupt`): ``finally:`` blocks
  run, temporary files are removed, a campaign writes its partial report; exit 130 and
  ``error: interrupted``. Processes forked from ``tli`` keep the default (SIGTERM ends them).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import signal
import sys
import traceback
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, ClassVar

from tli_verify._version import __version__
from tli_verify.arguments import check_path
from tli_verify.commands import check_report_dir, exit_code
from tli_verify.errors import OutputError, TliError
from tli_verify.io import check_output_dir, check_output_file
from tli_verify.snapshot import active as snapshot_active

__all__ = ["build_parser", "check_paths", "exit_code", "main"]

COMMAND_MODULES: tuple[str, ...] = (
    "tli_verify.commands.spec",
    "tli_verify.commands.motion",
    "tli_verify.commands.experiment",
    "tli_verify.commands.run",
    "tli_verify.commands.demo",
    "tli_verify.commands.verify",
    "tli_verify.commands.sim",
    "tli_verify.commands.task",
    "tli_verify.commands.deploy",
)


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose usage errors are one ``error:`` line and exit code 2."""

    _argv: ClassVar[list[str]] = []

    def parse_known_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                         namespace: argparse.Namespace | None = None
                         ) -> tuple[argparse.Namespace, list[str]]:
        top = not _Parser._argv  # the top-level parse: remember the words for the hint
        if top:
            _Parser._argv = [str(a) for a in (sys.argv[1:] if args is None else args)]
        try:
            return super().parse_known_args(args, namespace)
        finally:
            if top:
                _Parser._argv = []

    def error(self, message: str) -> None:  # type: ignore[override]
        sys.stderr.write(f"error: {self.prog}: {message}{_negative_hint(message, self._argv)}\n")
        raise SystemExit(2)


def _negative_hint(message: str, argv: Sequence[str]) -> str:
    """argparse reads ``--start -0.9,0`` as two options: say how to pass such a value."""
    import re

    m = re.match(r"argument (\S+?)(?:/\S+)?: expected (?:one|at least one) argument", message)
    if m is None:
        return ""
    names = {n for n in m.group(0).split(":", 1)[0].split(" ", 1)[1].split("/")}
    for i, word in enumerate(argv[:-1]):
        nxt = argv[i + 1]
        if word in names and re.match(r"-\.?\d", nxt):
            return (f" (a value that starts with '-' needs '=': {word}={nxt})")
    return ""


class _Version(argparse.Action):
    """``--version``: the installed distribution's version, read only when asked."""

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:

        sys.stdout.write(f"tli-verify {__version__}\n")  # stdout, as argparse's "version"
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    """Build the ``tli`` parser with every registered subcommand."""
    parser = _Parser(
        prog="tli",
        description="tli-verify: LTL task automata, certified LPV-DS motion policies, "
        "cutting-plane modulation and a deployment gate (Temporal Logic Imitation).",
    )
    parser.add_argument("--version", action=_Version, nargs=0,
                        help="show the version and exit")
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
    inputs: list[Path] = []
    for name, value in vars(args).items():
        for v in value if isinstance(value, list | tuple) else [value]:
            if isinstance(v, Path) and str(v) != "":  # every path fits the file system
                check_path(v, f"--{name.replace('_', '-')}", error=OutputError if name in (
                    "output", "out", "repair") else TliError)
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
        check_report_dir(out)


class _StdoutError(OutputError):
    """Standard output cannot be written (exit 2); raised by :class:`_Stream`."""


class _Stream:
    """A stand-in for :data:`sys.stdout` or :data:`sys.stderr` (module doc).

    Everything but :meth:`write`, :meth:`writelines` and :meth:`flush` is the wrapped
    stream's. On standard output (``strict``) a failed write is :class:`_StdoutError`, a
    broken pipe stays :class:`BrokenPipeError`; on standard error a failed write is dropped.
    """

    def __init__(self, stream: Any, *, strict: bool) -> None:
        self._stream = stream
        self._strict = strict

    def _failed(self, exc: Exception) -> None:
        if not self._strict:
            return
        if isinstance(exc, BrokenPipeError):
            raise exc
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise _StdoutError(f"cannot write standard output: {reason}") from None

    def write(self, text: str) -> int:
        try:
            return int(self._stream.write(text))
        except (OSError, ValueError) as exc:  # ValueError: the stream was closed
            self._failed(exc)
            return len(text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except (OSError, ValueError) as exc:
            self._failed(exc)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _say(line: str) -> None:
    """Write one line to standard error; never fails (there is nowhere left to report)."""
    try:
        if sys.stderr is not None:
            sys.stderr.write(line + "\n")
            sys.stderr.flush()
    except (OSError, ValueError):
        pass


def _plug_closed_descriptors() -> None:
    """Reopen closed descriptors 0, 1 and 2 on ``/dev/null`` (no file may land on them)."""
    for fd in (0, 1, 2):
        try:
            os.fstat(fd)
        except OSError:
            try:
                null = os.open(os.devnull, os.O_RDWR)
                if null != fd:
                    os.dup2(null, fd)
                    os.close(null)
            except OSError:  # pragma: no cover - no /dev/null: nothing better to do
                pass


def _lenient(stream: Any) -> Any:
    """Make ``stream`` print what its encoding cannot show as backslash escapes; return its
    former ``errors`` (``None`` if unchanged)."""
    errors = getattr(stream, "errors", None)
    if errors != "strict":
        return None
    try:
        stream.reconfigure(errors="backslashreplace")
    except (AttributeError, ValueError, OSError):
        return None
    return errors


def _drop_stdout(stream: Any) -> None:
    """Point standard output's descriptor at ``/dev/null``: what is still buffered is dropped
    there, and the interpreter's final flush succeeds."""
    with contextlib.suppress(Exception):
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, stream.fileno())
        finally:
            os.close(null)


def _flush_quietly(stream: Any) -> None:
    try:
        stream.flush()
    except Exception:
        _drop_stdout(stream)


def _check_cwd() -> None:
    """Refuse a working directory that no longer exists (module doc).

    Raises
    ------
    TliError
        (exit 2) ``os.getcwd()`` fails.
    """
    try:
        os.getcwd()
    except OSError as exc:
        try:  # Linux names the deleted directory: "/old/path (deleted)"
            was = os.readlink("/proc/self/cwd").removesuffix(" (deleted)")
        except OSError:
            was = ""
        detail = f"was {was}" if was else exc.strerror or str(exc)
        what = "no longer exists" if isinstance(exc, FileNotFoundError) else \
            "cannot be read"
        raise TliError(f"the working directory {what} ({detail}); cd to an existing "
                       "directory and rerun") from None


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Python was when it arrived (handled as Ctrl-C)."""


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """While inside, SIGTERM raises :class:`_Terminated` in this process (a forked child
    still dies of it); the former handler is restored after."""
    me = os.getpid()

    def on_sigterm(signum: int, frame: FrameType | None) -> None:
        if os.getpid() != me:  # a child forked from here: die as SIGTERM would kill it
            signal.signal(signum, signal.SIG_DFL)
            os.kill(os.getpid(), signum)
            return
        raise _Terminated

    try:
        previous = signal.signal(signal.SIGTERM, on_sigterm)
    except ValueError:  # not the main thread: signals are not ours to handle
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``tli`` and return its exit code (the environment set up first: module doc)."""
    _plug_closed_descriptors()
    if sys.stdout is None:  # descriptor 1 was closed when Python started
        _say("error: standard output is closed; redirect it (to /dev/null to drop the "
             "output) and rerun")
        return 2
    os.environ["MPLBACKEND"] = "agg"  # headless, before anything imports matplotlib
    saved: tuple[Any, Any, Any] = (sys.stdin, sys.stdout, sys.stderr)
    err: Any = sys.stderr if sys.stderr is not None else open(os.devnull, "w")
    if sys.stdin is None:  # descriptor 0 was closed: read as empty
        sys.stdin = open(os.devnull)
    out = sys.stdout
    errors = (_lenient(out), _lenient(err))
    sys.stdout = _Stream(out, strict=True)
    sys.stderr = _Stream(err, strict=False)
    try:
        with _sigterm_interrupts():
            try:
                return _dispatch(argv, out)
            except KeyboardInterrupt:  # a second one, while the first was being reported
                _say("error: interrupted")
                return 130
    finally:
        _flush_quietly(err)
        sys.stdin, sys.stdout, sys.stderr = saved
        for stream, former in zip((out, err), errors, strict=True):
            if former is not None:
                with contextlib.suppress(Exception):
                    stream.reconfigure(errors=former)


def _dispatch(argv: Sequence[str] | None, out: Any) -> int:
    """Parse, check and run one command; its output flushed, its errors one line (main)."""
    debug = "--debug" in list(sys.argv[1:] if argv is None else argv)
    code: int | None = None
    try:
        try:
            parser = build_parser()
            args = parser.parse_args(argv)
            debug = bool(args.debug)
            handler = getattr(args, "handler", None)
            if handler is None:
                parser.print_help(sys.stderr)
                code = 2
            else:
                _check_cwd()
                check_paths(args)
                with snapshot_active():  # each file read once, hashed and parsed from those bytes
                    code = int(handler(args))
        except SystemExit:  # argparse: --help, --version, usage errors
            sys.stdout.flush()  # raises _StdoutError if it cannot be written
            raise
        sys.stdout.flush()  # here, not at the interpreter's exit (module doc)
        return code
    except TliError as exc:
        if isinstance(exc, _StdoutError):
            _drop_stdout(out)
        elif debug:
            traceback.print_exc()
        _say(f"error: {exc}")
        _flush_quietly(sys.stdout)
        return exit_code(exc)
    except BrokenPipeError:  # e.g. `tli ... | head`: the reader left; not an error of ours
        _drop_stdout(out)
        return 0 if code is None else code
    except KeyboardInterrupt as exc:
        _flush_quietly(sys.stdout)
        _say("error: interrupted" + (" (SIGTERM)" if isinstance(exc, _Terminated) else ""))
        return 130
    except OSError as exc:
        if exc.errno not in (errno.ENAMETOOLONG, errno.EILSEQ):
            return _internal(exc, debug)
        # a path the file system cannot hold (a name longer than MAX_NAME_BYTES): bad input
        name = str(exc.filename or "")
        shown = name if len(name) <= 80 else name[:77] + "..."
        _say(f"error: {shown}: {exc.strerror or 'bad path'} (a path component is at most "
             "255 bytes, MAX_NAME_BYTES)")
        _flush_quietly(sys.stdout)
        return 2
    except Exception as exc:  # an internal bug: still one line unless --debug
        return _internal(exc, debug)


def _internal(exc: BaseException, debug: bool) -> int:
    """An internal bug: one ``error:`` line unless ``--debug``, exit 70."""
    if debug:
        traceback.print_exc()
    _say(f"error: internal error ({type(exc).__name__}: {' '.join(str(exc).split())}); "
         "rerun with --debug for a traceback")
    _flush_quietly(sys.stdout)
    return 70


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
