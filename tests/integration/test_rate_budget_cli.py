"""`tli learn --rate-budget` on a user's own 3-D task, then `tli certify` and `tli check-cert`:
the certificate proves (at least) the decay rate the learner chose per DS."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from tests.support.cli import run
from tli_verify.ds.lyapunov import rate_candidates


def write_spiral_demos(root: Path) -> list[str]:
    """Three 3-D demonstrations spiralling into the origin; sensor ``g``: within 0.3 of it
    (two DS: ``!g`` heading into ``g``, and ``g`` staying)."""
    rng = np.random.default_rng(1)
    paths = []
    for i in range(3):
        t = np.linspace(0.0, 4.0, 41)
        s = np.array([1.0, 0.6, -0.4]) + 0.05 * rng.normal(size=3)
        c, si = np.cos(2.0 * t), np.sin(2.0 * t)
        X = np.exp(-t)[:, None] * np.column_stack([s[0] * c - s[1] * si, s[0] * si + s[1] * c,
                                                   np.full_like(t, s[2])])
        X += 0.003 * rng.normal(size=X.shape)
        g = (np.linalg.norm(X, axis=1) < 0.3).astype(int)
        path = root / "demos" / f"spiral_{i + 1}.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("t,x0,x1,x2,g\n" + "".join(
            f"{ti:.3f},{x[0]:.6f},{x[1]:.6f},{x[2]:.6f},{gi}\n" for ti, x, gi in zip(t, X, g,
                                                                                     strict=True)))
        paths.append(str(path))
    return paths


def test_learn_with_a_budget_then_certify_proves_the_chosen_rates(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    demos = write_spiral_demos(tmp_path)
    model = tmp_path / "models" / "spiral.model.json"
    cert = tmp_path / "certificates" / "spiral.cert.json"
    code, out, err = run(capsys, "learn", *demos, "-o", str(model), "--rate-budget", "0.05")
    assert code == 0, err
    lines = [ln for ln in out.splitlines() if ": K=" in ln]
    assert [ln.split(":")[0] for ln in lines] == ["!g", "g"]
    doc = json.loads(model.read_text())
    assert len(doc["state_names"]) == 3
    for key, line in zip(("!g", "g"), lines, strict=True):
        fit = doc["modes"][key]["fit"]
        assert fit["rate_budget"] == 0.05 and fit["rate_within_budget"] is True
        assert fit["rate"] > 0 and fit["rate"] in rate_candidates(fit["data_rate"])
        assert fit["rate_rmse"] <= 1.05 * fit["rate_reference_rmse"] * (1 + 1e-6)
        cost = fit["rate_rmse"] / fit["rate_reference_rmse"] - 1
        assert line.endswith(f"decay rate {fit['rate']:.3g}/s (RMSE {cost:+.1%} vs rate 0)"), line

    code, out, err = run(capsys, "certify", str(model), "-o", str(cert))
    assert code == 0, err
    assert out.count("exact: yes") == 2
    code, out, err = run(capsys, "check-cert", str(cert))
    assert code == 0, err
    assert out.strip().endswith(f"valid (re-checked exactly against {model})")
    stated = json.loads(cert.read_text())["modes"]
    for key, entry in doc["modes"].items():
        # exact decimals: the certificate's rational against the model's 3-digit rate
        assert Fraction(stated[key]["decay_rate"]) >= Fraction(repr(entry["fit"]["rate"])), key


def test_rate_and_rate_budget_are_exclusive_and_checked(
        capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "learn", "x.csv", "-o", "m.json", "--rate", "0.5",
                       "--rate-budget", "0.05")
    assert code == 2 and "--rate-budget: not allowed with argument --rate" in err
    for bad in ("-0.1", "nan", "inf"):
        code, _, err = run(capsys, "learn", "x.csv", "-o", "m.json", "--rate-budget", bad)
        assert code == 2 and ("must be a finite number" in err
                              or "must be 0 or between 1e-06 and 100" in err), (bad, err)
        assert "Traceback" not in err
