"""Commands do what the user asked, and say so when they cannot (issue 32, part 3), from the
user's side: the command line, and a user's own pytest run.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.cli import run
from tli_verify.tasks.registry import find_task

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("task", ["scoop"])  # the bundled task with a nominal start
def test_run_without_start_uses_the_task_s_nominal_start(task: str, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    nominal = find_task(task).starts.nominal
    assert nominal
    for seed in ("0", "7"):  # the seed no longer moves the start
        code, out, err = run(capsys, "run", "--task", task, "--seed", seed, "--steps", "20",
                             "--json", "--out", str(tmp_path / seed))
        assert code in (0, 1), err
        assert json.loads(out)["start"] == pytest.approx(list(nominal[0]))
    code, out, _ = run(capsys, "run", "--task", task, "--seed", "7", "--random-start",
                       "--steps", "20", "--json", "--out", str(tmp_path / "r"))
    assert json.loads(out)["start"] != pytest.approx(list(nominal[0]))


@pytest.mark.parametrize(("argv", "hint"), [
    (["run", "--task", "scoop", "--start", "-0.9,0"], "--start=-0.9,0"),
    (["run", "--task", "scoop", "--start", "-5,4.5"], "--start=-5,4.5"),
    (["run", "--task", "scoop", "--perturb", "-3:1,1"], "--perturb=-3:1,1"),
    (["run", "--task", "scoop", "--steps", "5", "--start", "-.5,0"], "--start=-.5,0"),
])
def test_a_negative_value_without_equals_gets_a_hint(argv: list[str], hint: str,
                                                     capsys: pytest.CaptureFixture[str]
                                                     ) -> None:
    code, _, err = run(capsys, *argv)
    assert code == 2 and err.count("\n") == 1
    assert "expected one argument" in err and f"needs '=': {hint}" in err, err


def test_a_failed_episode_title_reads_as_english() -> None:
    from tli_verify.runtime.loop import EpisodeResult
    from tli_verify.viz.episodes import episode_title

    res = EpisodeResult(success=False, steps=146, states=None, modes=("a", "b"),  # type: ignore
                        automaton_states=(0, 0), events=(), cuts_added=1, model=None)  # type: ignore
    for goal in ("the goal", "d"):
        title = episode_title(res, goal_label=goal)
        assert f"does not reach {goal} in 146 steps" in title
        assert "no the" not in title


def test_a_user_s_pytest_run_shows_no_swig_warning(tmp_path: Path) -> None:
    """A user's own test, with DeprecationWarnings as errors (their project has no filter for
    Spot's SWIG bindings): it passes, and no warning is reported."""
    (tmp_path / "test_mine.py").write_text(
        "import tli_verify as tli\n\n"
        "def test_my_spec():\n"
        f"    spec = tli.load_spec({str(REPO / 'specs' / 'scoop.toml')!r})\n"
        "    assert tli.check_spec(spec).realizable\n")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           "-W", "error::DeprecationWarning", "test_mine.py"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "Swig" not in done.stdout and "swigvarlink" not in done.stdout
    assert "1 passed" in done.stdout and "warning" not in done.stdout


@pytest.fixture(scope="module")
def drawer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A user's 3-D project with a learned, certified model (the CLI's own steps)."""
    from tests.support.drawer3d import write_project
    from tli_verify.cli import main

    root = write_project(tmp_path_factory.mktemp("drawer-evidence"))
    cwd = Path.cwd()
    try:
        import os

        os.chdir(root)
        assert main(["demos", "tasks/drawer.toml"]) == 0
        assert main(["learn", "demos/drawer_1.csv", "demos/drawer_2.csv", "demos/drawer_3.csv",
                     "--spec", "specs/drawer.toml", "-o", "models/drawer.model.json"]) == 0
        assert main(["certify", "models/drawer.model.json"]) == 0
    finally:
        os.chdir(cwd)
    return root


def _evidence(drawer: Path) -> dict:
    return json.loads((drawer / "certificates" / "drawer.campaign.json").read_text())


def test_evidence_random_starts_and_no_silent_weakening(drawer: Path,
                                                         capsys: pytest.CaptureFixture[str]
                                                         ) -> None:
    target = drawer / "certificates" / "drawer.campaign.json"
    code, out, err = run(capsys, "evidence", str(drawer), "--examples", "20", "--workers", "2",
                         "--random-starts")
    assert code == 0, err
    assert "random starts" in out
    assert _evidence(drawer)["campaign"]["settings"]["random_starts"] is True
    before = target.read_bytes()
    for weaker, why in ((["--examples", "20"], "random starts, this one a nominal start"),
                        (["--examples", "10", "--random-starts"], "20 examples, this one 10")):
        code, out, err = run(capsys, "evidence", str(drawer), "--workers", "2", *weaker)
        assert code == 2 and err.count("\n") == 1 and out == "", err
        assert "holds evidence of a stronger campaign" in err and why in err
        assert "--force" in err
        assert target.read_bytes() == before  # kept, and nothing ran
    code, _, err = run(capsys, "verify", "--spec", str(drawer / "specs" / "drawer.toml"),
                       "--examples", "5", "--evidence", "--out", str(drawer / "out"))
    assert code == 2 and "stronger campaign" in err and target.read_bytes() == before
    code, out, err = run(capsys, "evidence", str(drawer), "--examples", "10", "--workers", "2",
                         "--force")
    assert code == 0, err
    assert "note:" in err and "replacing evidence of a stronger campaign" in err
    assert _evidence(drawer)["campaign"]["examples"] == 10


def test_a_task_file_can_make_random_starts_the_default(drawer: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    task = drawer / "tasks" / "drawer.toml"
    text = task.read_text()
    assert "[starts]\nnominal = [[0.2, 0.5, 0.8]]\n" in text
    task.write_text(text.replace("[starts]\nnominal = [[0.2, 0.5, 0.8]]\n",
                                 "[starts]\nnominal = [[0.2, 0.5, 0.8]]\nrandom = true\n"))
    try:
        code, out, err = run(capsys, "evidence", str(drawer), "--examples", "12",
                             "--workers", "2", "--force")
        assert code == 0, err
        assert _evidence(drawer)["campaign"]["settings"]["random_starts"] is True
        # the nominal start stays the start of tli run
        code, out, err = run(capsys, "run", "--spec", str(drawer / "specs" / "drawer.toml"),
                             "--steps", "5", "--json", "--out", str(drawer / "out" / "r"))
        assert json.loads(out)["start"] == pytest.approx([0.2, 0.5, 0.8])
        code, _, err = run(capsys, "task", "check", str(task))
        assert code == 0, err
    finally:
        task.write_text(text)


def test_task_list_shows_the_project_s_own_tasks(drawer: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(drawer)
    code, out, _ = run(capsys, "task", "list")
    assert code == 0
    rows = dict(line.split("\t", 1) for line in out.splitlines())
    assert rows["drawer"] == str(Path("tasks") / "drawer.toml") + " (this project)"
    assert "scoop" in rows  # the bundled ones too
    monkeypatch.chdir(drawer.parent)
    code, out, _ = run(capsys, "task", "list", "--project", str(drawer))
    assert "drawer\t" in out
