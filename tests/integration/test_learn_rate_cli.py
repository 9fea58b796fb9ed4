"""`tli learn --rate / --control-dt`: the contracting default and the old margin-only learner."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.support.cli import run
from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.ds.lyapunov import decay_rate, sampled_growth
from tli_verify.logic.spec import load_spec
from tli_verify.tasks.registry import find_task


def _rates(path: Path) -> dict[str, tuple[float, float, float | None]]:
    """key -> (certified decay rate, growth per 1 ms step, fit rate) of a model file."""
    out = {}
    for key, entry in json.loads(path.read_text())["modes"].items():
        P = np.array(entry["P"])
        A = np.array([c["A"] for c in entry["components"]])
        out[key] = (decay_rate(P, A), sampled_growth(P, A, 1e-3), entry["fit"].get("rate"))
    return out


def test_default_contracts_and_rate_zero_is_the_old_learner(
        repo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    demos = [str(p) for p in sorted((repo / "demos").glob("scoop_*.csv"))]
    spec = str(repo / "specs" / "scoop.toml")
    new, old = tmp_path / "new.model.json", tmp_path / "old.model.json"
    assert run(capsys, "learn", *demos, "--spec", spec, "-o", str(new))[0] == 0
    assert run(capsys, "learn", *demos, "--spec", spec, "-o", str(old), "--rate", "0")[0] == 0
    # a spec that names no task: the same demos and spec without its `task = "scoop"` line
    text = (repo / "specs" / "scoop.toml").read_text()
    taskless = tmp_path / "scoop-taskless.toml"
    taskless.write_text(text.replace('\ntask = "scoop"', "\n# (no task)", 1))
    assert load_spec(taskless).task is None and load_spec(spec).task == "scoop"
    unnamed = tmp_path / "unnamed.model.json"
    assert run(capsys, "learn", *demos, "--spec", str(taskless), "-o", str(unnamed))[0] == 0
    # --control-dt defaults to the control period of the spec's task (scoop: 0.01), else the
    # one default (tli_verify.project.control_period)
    task_dt = find_task("scoop").dt
    assert task_dt == 0.01
    plain = _rates(old)
    for path, control_dt in ((new, task_dt), (unnamed, DEFAULT_DT_FLOAT)):
        for key, (rate, growth, fit_rate) in _rates(path).items():
            assert fit_rate is not None and rate >= fit_rate * (1 - 1e-4) > 0.05, key
            assert growth < 0, key
            assert json.loads(path.read_text())["modes"][key]["fit"]["control_dt"] == control_dt
    for key, (rate, _, fit_rate) in plain.items():
        assert fit_rate == 0.0
        assert "control_dt" not in json.loads(old.read_text())["modes"][key]["fit"]
        assert rate >= 1e-3 * (1 - 1e-3), key  # the margin eps = 1e-3 is all it guarantees
    # ... and on the bundled demos it leaves DS barely contracting (a, b, c at about eps; the
    # goal mode d's fit happens to contract fast by itself), which the default never does
    barely = sorted(k for k, (rate, _, _) in plain.items() if rate < 0.01)
    assert barely and set(barely) >= {"a", "b", "c"}, plain


def test_rate_and_control_dt_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "learn", "x.csv", "-o", "m.json", "--rate", "-0.5")
    assert code == 2
    assert "must be 0 or between 1e-06 and 10000 1/s" in err and "Traceback" not in err
    code, _, err = run(capsys, "learn", "x.csv", "-o", "m.json", "--control-dt", "0")
    assert code == 2
    assert "must be " in err
