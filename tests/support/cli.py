"""Run the ``tli`` CLI in-process and capture what it printed (shared by the CLI tests)."""

from __future__ import annotations

import json
import signal
from typing import Any

import pytest

from tli_verify.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    """``tli argv...``: the exit code (argparse usage errors included), stdout and stderr."""
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse usage errors
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def json_records(out: str) -> list[dict[str, Any]]:
    """The JSON objects a ``--json`` command printed one after another (pretty-printed)."""
    dec = json.JSONDecoder()
    recs, i = [], 0
    while i < len(out):
        if out[i].isspace():
            i += 1
            continue
        obj, i = dec.raw_decode(out, i)
        recs.append(obj)
    return recs


def interactive_signals() -> None:
    """``preexec_fn`` of a child process: SIGINT and SIGTERM as an interactive shell leaves
    them (default), whatever this process inherited. A test run in the background
    (``make test &``, ``nohup``, some CI runners) has SIGINT ignored; Python then installs no
    KeyboardInterrupt handler in its children, and a test that interrupts one waits forever."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
