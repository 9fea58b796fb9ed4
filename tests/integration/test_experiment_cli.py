"""``tli experiment single-mode``: the quick study end to end, JSON contract, bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _tli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "tli_verify.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=300, check=False)


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str],
                                                             Path]:
    out = tmp_path_factory.mktemp("single-mode")
    return _tli("experiment", "single-mode", "--quick", "--json", "--out", str(out),
                cwd=REPO), out


def test_quick_json_contract(quick: tuple[subprocess.CompletedProcess[str], Path]) -> None:
    proc, out = quick
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert set(data["success"]) == {"BC", "BC+mod", "DS", "DS+mod"}
    for row in data["success"].values():
        assert set(row) == {"0", "5", "30"}
        assert all(0.0 <= v <= 1.0 for v in row.values())
    assert set(data["cuts"]) == {"BC+mod", "DS+mod"}
    assert data["trials_run"] == 3
    s = data["success"]
    # the stable policy with cuts is never worse than without, and near-perfect
    for k in ("0", "5", "30"):
        assert s["DS+mod"][k] >= s["DS"][k]
        assert s["DS+mod"][k] >= 0.95
    assert s["DS"]["0"] == 1.0
    # with the corner guard the modulated DS never leaves the mode (Thm. 1, sampled data)
    assert all(data["failures"]["DS+mod"][k]["invariance"] == 0 for k in ("0", "5", "30"))
    assert data["expected_shape"]["DS+mod never leaves the mode (0 invariance failures)"]
    for name in ("single_mode.json", "single_mode.md", "single_mode_cuts.png",
                 "single_mode_rollouts.png"):
        assert (out / name).stat().st_size > 0
    assert json.loads((out / "single_mode.json").read_text())["success"] == s
    assert "trials" in proc.stderr  # the progress bar goes to stderr


@pytest.mark.parametrize(("args", "needle"), [
    (["--trials", "0"], "argument --trials: must be between 1 and 100000, got 0"),
    (["--seed", "-3"], "argument --seed: must be between 0 and 4294967295, got -3"),
    (["--workers", "0"], "argument --workers: must be between 1 and 256, got 0"),
    (["--trials", "two"], "argument --trials: expected an integer, got 'two'"),
    (["--ds-eps", "0"], "argument --ds-eps: must be between 1e-09 and 1000, got '0'"),
    (["--ds-eps", "nan"], "argument --ds-eps: must be a finite number, got 'nan'"),
])
def test_bad_input_exits_2(args: list[str], needle: str, tmp_path: Path) -> None:
    proc = _tli("experiment", "single-mode", *args, "--out", str(tmp_path / "o"), cwd=REPO)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0]
    assert proc.stdout == ""
