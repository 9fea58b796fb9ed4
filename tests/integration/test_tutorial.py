"""The docs' tutorials (``docs/tutorial/*.md``) run as written, and so does the README's example.

In every tutorial page, each console block between ``<!-- tutorial:begin -->`` and
``<!-- tutorial:end -->`` is parsed: every ``$ tli ...`` line runs as a user would run it (a new
process, in the folder the ``cd`` lines reach), must exit 0 -- or the code a trailing
``# exit N`` names -- and every output line the page shows under it must appear in what the
command printed (timings excepted: numbers in parentheses that end in ``ms`` or ``s`` are
compared as a pattern). The blocks of one page run in order in one folder: an empty one, or,
for a page marked ``<!-- tutorial:project bundled-scoop -->``, a copy of the repository's
bundled scoop files (task, specs, demos, model, certificate, evidence).

The Python block between ``<!-- tutorial:python:begin -->`` and ``<!-- tutorial:python:end -->``
of ``byo-task.md`` runs in a project ``tli init`` wrote, and the README shows the same code.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIAL = ROOT / "docs" / "tutorial"
README = ROOT / "README.md"
PAGES = sorted(p.name for p in TUTORIAL.glob("*.md"))
#: Pages whose commands take a minute or more (each runs a campaign and the gate): ``make
#: test-all`` runs them; ``make test`` runs the tutorial's Python example and the README check.
SLOW_PAGES = {"walkthrough.md", "byo-task.md"}
_EXIT = re.compile(r"\s+#\s*exit\s+(\d+)\s*$")


def _blocks(text: str, tag: str) -> list[str]:
    begin, end = f"<!-- {tag}:begin -->", f"<!-- {tag}:end -->"
    return [part.split(end, 1)[0] for part in text.split(begin)[1:]]


def _steps(text: str) -> list[tuple[str, int, list[str]]]:
    """``(command, expected exit code, shown output lines)`` of every tutorial block."""
    steps: list[tuple[str, int, list[str]]] = []
    for block in _blocks(text, "tutorial"):
        for line in block.splitlines():
            if line.startswith("$ "):
                cmd, code = line[2:], 0
                m = _EXIT.search(cmd)
                if m:
                    cmd, code = cmd[:m.start()], int(m.group(1))
                steps.append((cmd, code, []))
            elif steps and line.strip() and not line.startswith("```"):
                steps[-1][2].append(line)
    return steps


def _python_block(text: str) -> str:
    (block,) = _blocks(text, "tutorial:python")
    m = re.search(r"```python\n(.*?)```", block, re.DOTALL)
    assert m, "the python block has no ```python fence"
    return m.group(1)


def _pattern(line: str) -> re.Pattern[str]:
    """A shown output line as a regex: timings and wall-clock seconds match any number."""
    out = re.escape(line)
    out = re.sub(r"\\\(\d+(\\\.\d+)?\\ ms\\\)", r"\\(\\d+(\\.\\d+)?\\ ms\\)", out)
    out = re.sub(r"\d+(\\\.\d+)?\\ ms", r"\\d+(\\.\\d+)?\\ ms", out)
    out = re.sub(r"in\\ \d+(\\\.\d+)?\\ s(?=,)", r"in\\ \\d+(\\.\\d+)?\\ s", out)
    return re.compile(out)


def _bundled_scoop(dest: Path) -> None:
    for sub in ("tasks", "specs", "demos", "models", "certificates"):
        (dest / sub).mkdir()
        for f in sorted((ROOT / sub).glob("scoop*")):
            shutil.copy(f, dest / sub / f.name)


def _tli(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "tli_verify.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900, check=False)


def test_every_tutorial_page_has_commands() -> None:
    assert PAGES, f"no tutorial pages in {TUTORIAL}"
    for page in PAGES:
        assert _steps((TUTORIAL / page).read_text(encoding="utf-8")), page
    byo = _steps((TUTORIAL / "byo-task.md").read_text(encoding="utf-8"))
    assert [cmd.split()[:2] for cmd, _, _ in byo][:2] == [["tli", "init"], ["cd", "drawer-project"]]
    assert any(cmd.startswith("tli gate") for cmd, _, _ in byo)


@pytest.mark.parametrize("page", [pytest.param(p, marks=pytest.mark.slow) if p in SLOW_PAGES
                                  else p for p in PAGES])
def test_the_tutorial_runs_as_written(page: str, tmp_path: Path) -> None:
    text = (TUTORIAL / page).read_text(encoding="utf-8")
    if "<!-- tutorial:project bundled-scoop -->" in text:
        _bundled_scoop(tmp_path)
    cwd = tmp_path
    for cmd, code, shown in _steps(text):
        argv = shlex.split(cmd)
        if argv[0] == "cd":
            cwd = cwd / argv[1]
            continue
        assert argv[0] == "tli", cmd
        proc = _tli(argv[1:], cwd)
        assert proc.returncode == code, \
            f"{page}: {cmd}: exit {proc.returncode}, expected {code}\n{proc.stdout}{proc.stderr}"
        for line in shown:
            assert _pattern(line).search(proc.stdout), f"{page}: {cmd}: shows {line!r}, got\n" \
                f"{proc.stdout}"
    if page == "byo-task.md":
        assert (cwd / "certificates" / "drawer.campaign.json").is_file()


def test_the_tutorial_python_example_runs(tmp_path: Path) -> None:
    code = _python_block((TUTORIAL / "byo-task.md").read_text(encoding="utf-8"))
    assert _tli(["init", "drawer-project", "--name", "drawer", "--dim", "3"], tmp_path) \
        .returncode == 0
    project = tmp_path / "drawer-project"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=project, env=env,
                          capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (project / "certificates" / "drawer.cert.json").is_file()


def test_the_readme_shows_the_tested_example() -> None:
    readme = README.read_text(encoding="utf-8")
    code = _python_block((TUTORIAL / "byo-task.md").read_text(encoding="utf-8"))
    assert f"```python\n{code}```" in readme, "README's Python example differs from the " \
        "tutorial's (docs/tutorial/byo-task.md), which the tests run"
    byo = (TUTORIAL / "byo-task.md").read_text(encoding="utf-8")
    for cmd, _, _ in _steps(byo):
        if cmd.startswith("tli ") and "$ " + cmd in readme:
            break
    else:
        pytest.fail("the README shows none of the tutorial's tested commands")
    for cmd in re.findall(r"^\$ (tli .*)$", readme, re.MULTILINE):
        assert any(cmd == c for c, _, _ in _steps(byo)), \
            f"README shows {cmd!r}, which the tutorial test does not run"


@pytest.mark.parametrize("line", ["drawer (LTL-DS): reached the goal in 413 steps (4.13 s "
                                  "simulated, 456 ms); modes ab; 1 cut(s) added"])
def test_the_output_pattern_ignores_timings_only(line: str) -> None:
    pat = _pattern(line)
    assert pat.search(line.replace("456 ms", "12 ms"))
    assert not pat.search(line.replace("413 steps", "414 steps"))


def test_exit_annotations() -> None:
    (step,) = _steps("<!-- tutorial:begin -->\n$ tli spec check x.toml  # exit 1\nout\n"
                     "<!-- tutorial:end -->")
    assert step == ("tli spec check x.toml", 1, ["out"])
