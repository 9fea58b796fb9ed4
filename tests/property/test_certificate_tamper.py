"""Property: any single-number edit of P, of any A_k, or of the model file is caught.

Theorem checked: for the deployed certificate C of model M, changing one number -- an entry of
a mode's P in C, or an entry of a mode's P or of any A_k in M -- makes both ``check-cert`` and the
deployment gate reject, whatever the entry and however small the change (down to one ulp).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.certification.certificate import check_certificate
from tli_verify.deploy.gate import run_gate
from tli_verify.io import canonical_json

REPO = Path(__file__).resolve().parents[2]
MODEL = json.loads((REPO / "models" / "scoop.model.json").read_text())
MODES = sorted(MODEL["modes"])


def perturb(value: float, how: str, amount: float) -> float:
    if how == "ulp":
        return math.nextafter(value, math.inf if amount > 0 else -math.inf)
    if how == "relative":
        return value * (1.0 + amount)
    if how == "absolute":
        return value + amount
    if how == "negate":
        return -value if value != 0 else 1e-3
    return 0.0 if value != 0 else amount  # "zero"


@st.composite
def edits(draw: st.DrawFn) -> tuple[str, list[Any], str, float]:
    """(file, JSON path of one number, kind of change, magnitude)."""
    target = draw(st.sampled_from(["cert-P", "model-P", "model-A"]))
    mode = draw(st.sampled_from(MODES))
    n = len(MODEL["modes"][mode]["P"])
    i, j = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
    if target == "model-A":
        k = draw(st.integers(0, len(MODEL["modes"][mode]["components"]) - 1))
        path: list[Any] = ["modes", mode, "components", k, "A", i, j]
    else:
        path = ["modes", mode, "P", i, j]
    how = draw(st.sampled_from(["ulp", "relative", "absolute", "negate", "zero"]))
    sign = draw(st.sampled_from([-1.0, 1.0]))
    amount = sign * 10.0 ** draw(st.floats(-15, 0))
    return target, path, how, amount


@settings(max_examples=60)
@given(edits())
def test_single_number_edits_are_caught(edit: tuple[str, list[Any], str, float]) -> None:
    target, path, how, amount = edit
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        for sub, name in (("models", "scoop.model.json"),
                          ("certificates", "scoop.cert.json"), ("specs", "scoop.toml")):
            (root / sub).mkdir()
            shutil.copy(REPO / sub / name, root / sub / name)
        file = root / ("certificates/scoop.cert.json" if target == "cert-P"
                       else "models/scoop.model.json")
        doc = json.loads(file.read_text())
        assert canonical_json(doc) == file.read_text()  # edits change one number only
        node = doc
        for part in path[:-1]:
            node = node[part]
        old = node[path[-1]]
        new = perturb(old, how, amount)
        if new == old or not math.isfinite(new):
            new = math.nextafter(old, math.inf)
        node[path[-1]] = new
        file.write_text(canonical_json(doc))

        check = check_certificate(root / "certificates" / "scoop.cert.json")
        assert not check.ok
        if target == "cert-P":
            assert any("digest does not match" in p for p in check.problems)
            assert any("differs from the model's P" in p for p in check.problems)
        else:
            assert any("SHA-256" in p and "differs" in p for p in check.problems)
        report = run_gate(root, rerun=0)
        assert not report.ok
        assert any(b.kind == "certificate" for b in report.blockers)
