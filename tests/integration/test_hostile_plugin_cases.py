"""Issue 31, class 6: the pytest plugin's ``--tli-cases DIR`` under hostile case files.

A case file nested 100,000 deep fails as one test with a one-line reason (before: a 380-line
RecursionError); a FIFO or a link to ``/dev/zero`` named ``*.json`` fails as one test naming
it, in one line, and every other case still runs (before: it aborted the whole session, exit 4,
or would never end; then a skip with a warning that a CI run passes over).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

pytest_plugins = ["pytester"]


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not Path("/dev/zero").exists(),
                    reason="needs FIFOs and /dev/zero")
def test_hostile_case_files_fail_alone_in_one_line(pytester: pytest.Pytester) -> None:
    cases = pytester.path / "cases"
    cases.mkdir()
    (cases / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    (cases / "list.json").write_text("[1, 2, 3]")
    os.mkfifo(cases / "fifo.json")
    (cases / "zero.json").symlink_to("/dev/zero")
    result = pytester.runpytest_subprocess(f"--tli-cases={cases}", "-p", "no:cacheprovider",
                                           timeout=120)
    assert result.ret == 1, result.stdout.str()[-2000:]  # tests failed, not a usage error
    result.assert_outcomes(failed=4)
    out = result.stdout.str()
    assert "RecursionError" not in out and "Traceback" not in out
    result.stdout.fnmatch_lines_random([
        "*deep.json: not a readable case file*MAX_NESTING*",
        "*list.json: not a case file*",
        "FAILED *fifo.json::replay*",
        "FAILED *zero.json::replay*",
        "*fifo.json: not a readable case file*not a regular file*",
        "*zero.json: not a readable case file*not a regular file*"])
    assert len(out.splitlines()) < 60
