"""Replay every saved counterexample in ``tests/regressions/`` (``tli verify`` finds them; copy
its ``counterexample.json`` here).

A case found *without* modulation documents a failure of the ablation: it must still reproduce
there (the simulation, the perturbation semantics and the oracle stay deterministic), and LTL-DS
(modulation on) must satisfy every check on the same case -- the cut answers the failure (paper
Thm. 1-2). A case found *with* modulation is a bug report: once fixed it must not reproduce;
while it is known and open (an ``"open"`` note in the file) it must still reproduce (xfail),
so the note goes when the fix lands.

A case bound to files that have changed since (another task, model, spec or certificate) fails,
naming the file: re-record it with ``tli verify`` (a silent skip would retire the regression).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tli_verify.io import sha256_file
from tli_verify.verify.cases import read_case, replay_case

HERE = Path(__file__).resolve().parent
CASES = sorted(HERE.glob("*.json"))


def _stale(case: Path) -> str | None:
    doc, spec, _ = read_case(case)
    for name, path in (("spec", spec.spec), ("model", spec.model),
                       ("certificate", spec.certificate), ("task", spec.task)):
        if sha256_file(path) != doc["files"][name]["sha256"]:
            return f"{case.name}: {name} {path} changed since the case was recorded"
    return None


def test_there_are_cases() -> None:
    assert CASES, "no regression case files"


@pytest.mark.parametrize("case", CASES, ids=[c.stem for c in CASES])
def test_case_replays(case: Path) -> None:
    stale = _stale(case)
    assert stale is None, f"{stale}: re-record the case (tli verify ... --out, copy " \
                          "counterexample.json) and check it still shows what it documents"
    doc = json.loads(case.read_text())
    _, verdict, reproduced, _ = replay_case(case)
    if doc["modulation"]:
        if doc.get("open"):  # a known, open bug: it must still reproduce until fixed
            assert reproduced, f"{case.name}: no longer reproduces: the bug is fixed, " \
                               "remove its 'open' note"
            pytest.xfail(f"open: {doc['open']}")
        assert not reproduced, f"{case.name}: the bug reproduces: {verdict.violations}"
        return
    assert reproduced, f"{case.name}: expected {doc['expected']['violation']}, got " \
                       f"{sorted(k.value for k in verdict.kinds)}"
    assert verdict.oracle_modes == doc["expected"]["oracle_modes"]
    _, fixed, again, _ = replay_case(case, modulation=True)
    assert not again and fixed.ok, f"{case.name}: LTL-DS violates {fixed.violations}"
