"""Unbounded work, late checks, silent caps and messages that do not name the culprit.

Every limit is checked before any work (a campaign never runs to be refused at the end); a
count the tool cannot honour is refused, never silently capped; every refusal is exit 2 and one
``error:`` line naming the option or field and why. Numbers are drawn by hypothesis from the
hostile ones (0, negative, 2^32, 10^9, 10^20, inf, nan, text).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.cli import run

HOSTILE = st.sampled_from(["0", "-1", "4294967296", "1000000000", "100000000000000000000",
                           "inf", "nan", "1e308", "x", "1.5"])

SEED = 2**32 - 1
OPTIONS = [  # (argv before the value, option, valid range; float: a real number is valid)
    (["run", "--task", "scoop", "--steps"], "--steps", (1, 100_000)),
    (["run", "--task", "scoop", "--seed"], "--seed", (0, SEED)),
    (["verify", "--task", "scoop", "--examples"], "--examples", (1, 10_000_000)),
    (["verify", "--task", "scoop", "--batch-size"], "--batch-size", (1, 10_000)),
    (["verify", "--task", "scoop", "--seed"], "--seed", (0, SEED)),
    (["verify", "--task", "scoop", "--window"], "--window", (1, 100_000)),
    (["verify", "--task", "scoop", "--target"], "--target", (0, 10_000_000)),
    (["experiment", "scoop", "--quick", "--steps"], "--steps", (1, 100_000)),
    (["experiment", "scoop", "--quick", "--episodes"], "--episodes", (1, 100_000)),
    (["experiment", "scoop", "--quick", "--experiments"], "--experiments", (1, 1000)),
    (["experiment", "single-mode", "--quick", "--trials"], "--trials", (1, 100_000)),
    (["experiment", "single-mode", "--quick", "--ds-eps"], "--ds-eps", (1e-9, 1e3)),
    (["evidence", ".", "--examples"], "--examples", (1, 10_000_000)),
    (["sim", "franka", "--seed"], "--seed", (0, SEED)),
    (["sim", "franka", "--workers"], "--workers", (1, 256)),
]


def _valid(value: str, bounds: tuple[int, int] | tuple[float, float]) -> bool:
    try:
        v = float(value)
    except ValueError:
        return False
    lo, hi = bounds
    if isinstance(lo, float):  # a float option: its physical bounds
        return lo <= v <= hi
    return value.lstrip("-").isdigit() and lo <= int(value) <= hi


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(option=st.sampled_from(OPTIONS), value=HOSTILE)
def test_hostile_numbers_are_refused_before_any_work(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str],
                                                     option: tuple[list[str], str, Any],
                                                     value: str) -> None:
    argv, name, bounds = option
    if _valid(value, bounds):
        return  # 1.5 as --ds-eps is fine; 0 as a seed is fine
    t0 = time.perf_counter()
    code, _out, err = run(capsys, *argv, value, "--out", str(tmp_path / "o")) \
        if argv[0] not in ("evidence", "sim") else run(capsys, *argv, value)
    assert code == 2, (argv, value, code, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and name in err, err
    assert time.perf_counter() - t0 < 20  # refused, not run
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("argv", "message"), [
    (["run", "--task", "scoop", "--perturb", "random:100000000000000000000"],
     "random:N needs a count N in [0, 100]"),
    (["run", "--task", "scoop", "--steps", "100", "--perturb", "5000:1,1"],
     "step 5000 is beyond the step budget (--steps 100)"),
    (["run", "--task", "scoop", "--perturb", "5:1,1,1"], "expected 2 comma-separated"),
    (["run", "--task", "scoop", "--start", "1e400,0"], "finite numbers"),
    (["experiment", "single-mode", "--ds-eps", "inf"], "--ds-eps: must be a finite number"),
])
def test_counts_and_values_the_tool_cannot_honour_are_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str],
        message: str) -> None:
    code, _, err = run(capsys, *argv, "--out", str(tmp_path / "o"))
    assert code == 2 and err.count("\n") == 1 and message in err, err


def test_video_and_fig9_on_one_path_name_both_outputs(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    pytest.importorskip("mujoco")
    target = tmp_path / "x.png"
    code, _, err = run(capsys, "sim", "franka", "--video", str(target), "--fig9", str(target))
    assert code == 2 and err.count("\n") == 1
    assert "the Fig. 11 plot and the video would be the same file" in err or \
        "the video and the Fig. 11 plot would be the same file" in err, err
    assert "input" not in err
