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
