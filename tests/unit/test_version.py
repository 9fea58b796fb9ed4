"""One version source (pyproject.toml), and evidence that binds meaning, not the version.

``tli_verify.__version__`` is the distribution metadata's version (a source tree without
metadata reads ``pyproject.toml``); nothing compares it. Campaign evidence records
:data:`~tli_verify.verify.evidence.CAMPAIGN_SEMANTICS` and the gate requires that: evidence
written by another tli-verify release with the same semantics passes, other semantics block.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path
from typing import Any

import pytest

import tli_verify
from tli_verify import _version
from tli_verify.deploy.gate import run_gate
from tli_verify.io import canonical_json
from tli_verify.verify.evidence import (
    CAMPAIGN_SEMANTICS,
    EVIDENCE_SCHEMA_VERSION,
    _same_entry_point,
    check_evidence,
    evidence_digest,
)

REPO = Path(__file__).resolve().parents[2]
EVIDENCE = Path("certificates") / "scoop.campaign.json"


def pyproject_version() -> str:
    with (REPO / "pyproject.toml").open("rb") as f:
        return str(tomllib.load(f)["project"]["version"])


def forge(project: Path, **fields: Any) -> dict[str, Any]:
    """Set top-level or ``tool`` fields of the scoop evidence, digest recomputed."""
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    for key, value in fields.items():
        if key == "tool_version":
            doc["tool"]["version"] = value
        else:
            doc[key] = value
    doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))
    return doc


# --------------------------------------------------------------------------------------------
# The version: written once, in pyproject.toml
# --------------------------------------------------------------------------------------------

def test_version_is_the_distribution_metadata_and_pyproject() -> None:
    assert tli_verify.__version__ == version("tli-verify") == pyproject_version()
    assert _version.__version__ == tli_verify.__version__


def test_a_source_tree_without_metadata_reads_pyproject() -> None:
    assert _version._source_tree_version() == pyproject_version()


def test_the_version_string_is_written_only_in_pyproject() -> None:
    literal = re.compile(r"""__version__\s*(?::\s*str\s*)?=\s*["']""")
    found = [str(p.relative_to(REPO)) for p in sorted((REPO / "tli_verify").rglob("*.py"))
             if literal.search(p.read_text(encoding="utf-8"))]
    assert found == []
    setup = (REPO / "setup.py").read_text(encoding="utf-8")
    assert "version" not in setup.split('setup(', 1)[1]


def test_tli_version_prints_the_metadata_version() -> None:
    done = subprocess.run([sys.executable, "-c", "import sys; from tli_verify.cli import main; "
                           "sys.exit(main(['--version']))"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"tli-verify {version('tli-verify')}"


# --------------------------------------------------------------------------------------------
# Evidence: the campaign semantics are required, the tool version is information
# --------------------------------------------------------------------------------------------

def test_fresh_evidence_records_the_semantics_and_the_version(project: Path) -> None:
    doc = json.loads((project / EVIDENCE).read_text())
    assert doc["schema_version"] == EVIDENCE_SCHEMA_VERSION
    assert doc["campaign_semantics"] == CAMPAIGN_SEMANTICS
    assert doc["tool"] == {"name": "tli-verify", "version": tli_verify.__version__}


@pytest.mark.parametrize("other", ["0.0.1", "99.0.0", "0.1.0+local.build", "1.0.0rc1"])
def test_evidence_of_another_tool_version_with_the_same_semantics_passes(
        project: Path, other: str) -> None:
    forge(project, tool_version=other)
    check = check_evidence(project / EVIDENCE)
    assert check.ok, check.problems
    assert any(f"campaign semantics {CAMPAIGN_SEMANTICS} are this tool's (written by "
               f"tli-verify {other})" in p for p in check.passed)
    report = run_gate(project, rerun=0)
    assert report.ok, [b.message for b in report.blockers]


@pytest.mark.parametrize("semantics", [CAMPAIGN_SEMANTICS + 1, CAMPAIGN_SEMANTICS + 7])
def test_evidence_of_other_semantics_blocks_even_with_this_tool_version(
        project: Path, semantics: int) -> None:
    forge(project, campaign_semantics=semantics)
    report = run_gate(project, rerun=0)
    found = [(b.kind, b.path, b.check) for b in report.blockers]
    assert found == [("model", "models/scoop.model.json", "campaign")]
    message = report.blockers[0].message
    assert (f"campaign semantics {semantics} (written by tli-verify {tli_verify.__version__}), "
            f"this tool's are {CAMPAIGN_SEMANTICS}") in message
    assert "re-run the campaign" in message


@pytest.mark.parametrize("bad", [0, -1, "1", 1.5, None, True])
def test_a_malformed_semantics_value_is_malformed_evidence(project: Path, bad: Any) -> None:
    forge(project, campaign_semantics=bad)
    problems = check_evidence(project / EVIDENCE).problems
    assert len(problems) == 1 and "malformed campaign evidence" in problems[0], problems


def test_evidence_without_semantics_is_malformed(project: Path) -> None:
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    del doc["campaign_semantics"]
    doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))
    problems = check_evidence(path).problems
    assert len(problems) == 1 and "malformed campaign evidence" in problems[0], problems
    assert "campaign_semantics" in problems[0]


def test_schema_2_evidence_says_to_re_run_the_campaign(project: Path) -> None:
    """Evidence of the former format (tool version compared, no semantics) is refused with a
    message that says what to do, not as a schema error."""
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    doc["schema_version"] = 2
    del doc["campaign_semantics"]
    doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))
    report = run_gate(project, rerun=0)
    assert [(b.path, b.check) for b in report.blockers] == [
        ("models/scoop.model.json", "campaign")]
    message = report.blockers[0].message
    assert "evidence schema 2" in message and "re-run the campaign" in message
    assert "tli evidence" in message


# --------------------------------------------------------------------------------------------
# Entry-point tasks: tli-verify's own are bound by their source, not by the tool version
# --------------------------------------------------------------------------------------------

OWN = {"name": "franka-scoop", "distribution": "tli-verify", "version": "0.1.0",
       "source_sha256": "1" * 64}
THIRD = {"name": "drawer", "distribution": "drawer-tasks", "version": "1.2.0",
         "source_sha256": "2" * 64}


def test_own_entry_point_ignores_the_tool_version_but_not_the_source() -> None:
    assert _same_entry_point(dict(OWN), OWN)
    assert _same_entry_point({**OWN, "version": "0.2.0"}, OWN)
    assert not _same_entry_point({**OWN, "source_sha256": "3" * 64}, OWN)
    assert not _same_entry_point({**OWN, "name": "other"}, OWN)
    assert not _same_entry_point({**OWN, "distribution": "tli-verify-fork"}, OWN)
    assert not _same_entry_point(None, OWN)


def test_third_party_entry_point_binds_its_version() -> None:
    assert _same_entry_point(dict(THIRD), THIRD)
    assert not _same_entry_point({**THIRD, "version": "1.3.0"}, THIRD)
    assert not _same_entry_point({**THIRD, "source_sha256": "3" * 64}, THIRD)
