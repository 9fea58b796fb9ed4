"""The gate passes no claim it has not checked (issue class: the gate trusts evidence).

Each test is a forgery that binds the right files with a correct digest, so only the check
under test can catch it: duplicate JSON keys (the last one wins in ``json`` -- a second
``"total"`` before the real one), evidence whose runs were all undecided, evidence from settings
too weak to test anything, physical evidence for a kinematic model, and recorded settings that
would crash or hang the re-run.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.evidence import attach_evidence
from tli_verify.commands import exit_code
from tli_verify.deploy.gate import run_gate
from tli_verify.errors import TliError
from tli_verify.io import parse_json, read_json
from tli_verify.verify.evidence import (
    MIN_EVIDENCE_EXAMPLES,
    MIN_MAX_PUSHES,
    MIN_WINDOW,
    check_evidence,
    evidence_digest,
)

EVIDENCE = Path("certificates") / "scoop.campaign.json"


def _forge(project: Path, edit: Any) -> dict[str, Any]:
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    edit(doc)
    doc["digest"] = evidence_digest(doc)
    path.write_text(json.dumps(doc, indent=2))
    return doc


def _blockers(project: Path, **kw: Any) -> list[str]:
    return [f"{b.check}: {b.message}" for b in run_gate(project, **kw).blockers]


def test_duplicate_keys_are_refused_by_every_json_reader(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="duplicate key 'total'"):
        parse_json('{"violations": {"total": 7, "total": 0}}')
    for what, text in (("certificate", '{"a": 1, "a": 1}'),
                       ("model", '{"modes": {"a": {}, "a": {}}}'),
                       ("campaign evidence", '[{"x": 1}, {"y": 2, "y": 3}]')):
        p = tmp_path / "f.json"
        p.write_text(text)
        with pytest.raises(TliError, match="duplicate key") as err:
            read_json(p, what=what, error=TliError)
        assert str(p) in str(err.value)


def test_a_second_total_before_the_real_one_blocks(project: Path) -> None:
    """Insert ``"total": 7,`` before ``"total": 0`` (the digest is computed over the parsed
    document, so without the duplicate-key rule the evidence would read 0 and pass)."""
    attach_evidence(project, violations={"invariance": 7})
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    assert doc["violations"]["total"] == 7
    doc["violations"] = {"by_kind": {"invariance": 0}, "total": 0}
    doc["digest"] = evidence_digest(doc)
    text = json.dumps(doc, indent=2).replace('"total": 0', '"total": 7, "total": 0')
    path.write_text(text)
    check = check_evidence(path)
    assert not check.ok and "duplicate key 'total'" in check.problems[0]
    assert any("duplicate key 'total'" in b for b in _blockers(project, rerun=0))


def test_evidence_whose_runs_were_all_undecided_blocks(project: Path) -> None:
    attach_evidence(project, inconclusive=MIN_EVIDENCE_EXAMPLES)
    found = _blockers(project, rerun=0)
    assert len(found) == 1 and "0 decided example(s)" in found[0]
    attach_evidence(project, inconclusive=1)  # one undecided of the minimum: one too few
    assert any(f"{MIN_EVIDENCE_EXAMPLES - 1} decided" in b for b in _blockers(project, rerun=0))
    attach_evidence(project, examples=MIN_EVIDENCE_EXAMPLES + 1,
                    runs=MIN_EVIDENCE_EXAMPLES + 1, inconclusive=1)
    assert run_gate(project, rerun=0).ok


@pytest.mark.parametrize(("settings_", "message"), [
    ({"window": 1, "max_pushes": 3}, f"at least {MIN_WINDOW} steps (MIN_WINDOW)"),
    ({"window": 700, "max_pushes": 1}, f"at least {MIN_MAX_PUSHES} perturbations"),
    ({"window": 700, "max_pushes": 0}, "MIN_MAX_PUSHES"),
    ({"max_pushes": 3}, "perturbation window None"),
])
def test_evidence_from_settings_too_weak_to_test_anything_blocks(project: Path,
                                                                 settings_: dict[str, Any],
                                                                 message: str) -> None:
    attach_evidence(project, settings=settings_)
    found = _blockers(project, rerun=0)
    assert len(found) == 1 and message in found[0], found


def test_physical_evidence_for_a_kinematic_model_blocks(project: Path) -> None:
    """The 2-D scoop model with a world ``franka-physics`` and a 30-trial physics block (the
    minimum would drop from 500 runs to 30): the kind of evidence must match the task."""
    from tests.unit.test_physics_evidence import physics_block

    attach_evidence(project, world="franka-physics", examples=30, runs=30,
                    physics=physics_block(), settings=None, inconclusive=None)
    found = _blockers(project, rerun=0)
    assert any("a physical campaign, but the deployed task 'scoop' is kinematic" in b
               for b in found), found


@settings(max_examples=200, deadline=None)
@given(key=st.sampled_from(["batch_size", "window", "max_pushes", "lag", "levels", "start",
                            "random_starts", "max_cycles", "target_examples"]),
       value=st.one_of(st.text(max_size=3), st.floats(allow_nan=True), st.just(10**12),
                       st.just(-1), st.just([1, "x"]), st.just(True), st.just(700.5)))
def test_forged_settings_are_refused_naming_the_field(key: str, value: Any) -> None:
    """Recorded settings are validated like the CLI's options before any re-run (the gate
    builds its re-run config through the same checks): a forged one is one error naming it,
    never a TypeError or a campaign of 10^12 runs per batch."""
    from tli_verify.verify.config import CampaignConfig
    from tli_verify.verify.evidence import settings_for_config

    recorded = {"window": 700, "max_pushes": 3, "batch_size": 100, key: value}
    kwargs = settings_for_config(recorded, CampaignConfig)
    try:
        CampaignConfig(task="scoop", examples=3, **kwargs)
    except TliError as exc:
        assert str(exc).startswith(key) and exit_code(exc) == 2, str(exc)
    else:  # accepted only if the forged value is a valid one
        assert (key, value) == ("random_starts", True), (key, value)


def test_a_forged_batch_size_blocks_the_re_run_with_one_line(project: Path) -> None:
    attach_evidence(project, settings={"window": 700, "max_pushes": 3, "batch_size": "x"})
    blockers = run_gate(project, rerun=3).blockers
    # refused before any re-run: by the evidence check (every recorded setting is validated)
    # or with the other settings no command line records (issue 31), in one line
    assert [b.check for b in blockers] == ["campaign"]
    assert blockers[0].message.count("\n") == 0
    assert "batch_size" in blockers[0].message and "'x'" in blockers[0].message
    assert "[1, 10000]" in blockers[0].message
