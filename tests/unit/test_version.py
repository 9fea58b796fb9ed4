"""One version source (pyproject.toml), and evidence that binds meaning, not the version.

``tli_verify.__version__`` is the distribution metadata's version (a source tree without
metadata reads ``pyproject.toml``); nothing compares it. Campaign evidence records
:data:`~tli_verify.verify.evidence.CAMPAIGN_SEMANTICS` and the gate requires that: evidence
written by another tli-verify release with the same semantics passes, other semantics block.
"""

from __future__ import annotations

import json
import re
import shutil
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
    check_evidence,
    evidence_digest,
)
from tli_verify.verify.evidence.check import _same_entry_point

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


def test_a_source_tree_without_metadata_reads_pyproject(tmp_path: Path) -> None:
    assert _version._source_tree_version() == pyproject_version()
    # A bare source tree (the package and pyproject.toml, no egg-info) and no site-packages
    # (``python -S``): no distribution metadata anywhere.
    shutil.copytree(REPO / "tli_verify", tmp_path / "tli_verify",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    done = subprocess.run([sys.executable, "-S", "-c",
                           f"import sys; sys.path.insert(0, {str(tmp_path)!r}); "
                           "import importlib.metadata as md, tli_verify\n"
                           "try:\n md.version('tli-verify'); print('metadata')\n"
                           "except md.PackageNotFoundError: print(tli_verify.__version__)"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == pyproject_version()


def test_the_version_string_is_written_only_in_pyproject() -> None:
    literal = re.compile(r"""__version__\s*(?::\s*str\s*)?=\s*["']""")
    found = [str(p.relative_to(REPO)) for p in sorted((REPO / "tli_verify").rglob("*.py"))
             if literal.search(p.read_text(encoding="utf-8"))]
    assert found == []
    setup = (REPO / "setup.py").read_text(encoding="utf-8")
    assert "version" not in setup.split('setup(', 1)[1]
    # Nor in the docs configuration, the schemas, the sdist manifest or the build hook.
    written = re.compile(rf"(?<![0-9.]){re.escape(pyproject_version())}(?![0-9])")
    others = [REPO / "setup.py", REPO / "MANIFEST.in", REPO / "docs" / "conf.py",
              *sorted((REPO / "tli_verify" / "schemas").glob("*.json"))]
    assert [str(p.relative_to(REPO)) for p in others
            if p.is_file() and written.search(p.read_text(encoding="utf-8"))] == []


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
    """A forgery only the semantics rule catches: this tool's version, the files' hashes, the
    settings and a recomputed digest all match; only ``campaign_semantics`` differs."""
    doc = forge(project, campaign_semantics=semantics)
    assert doc["tool"]["version"] == tli_verify.__version__
    problems = check_evidence(project / EVIDENCE).problems
    assert len(problems) == 1 and "this tool's are" in problems[0], problems
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


@pytest.mark.parametrize("schema", [2, 1])
def test_earlier_schema_evidence_says_to_re_run_the_campaign(project: Path, schema: int) -> None:
    """Evidence of a former format (2 compared the tool version, 1 bound no task; neither
    recorded semantics) is refused with a message that says what to do, not as a schema
    error."""
    path = project / EVIDENCE
    doc = json.loads(path.read_text())
    doc["schema_version"] = schema
    del doc["campaign_semantics"]
    doc["digest"] = evidence_digest(doc)
    path.write_text(canonical_json(doc))
    report = run_gate(project, rerun=0)
    assert [(b.path, b.check) for b in report.blockers] == [
        ("models/scoop.model.json", "campaign")]
    message = report.blockers[0].message
    assert f"evidence schema {schema}" in message and "re-run the campaign" in message
    assert "tli evidence" in message and "malformed" not in message


@pytest.mark.parametrize("schema", [EVIDENCE_SCHEMA_VERSION + 1, 0, True, "2"])
def test_an_unknown_schema_version_is_malformed_evidence(project: Path, schema: Any) -> None:
    forge(project, schema_version=schema)
    problems = check_evidence(project / EVIDENCE).problems
    assert len(problems) == 1 and "malformed campaign evidence" in problems[0], problems


# --------------------------------------------------------------------------------------------
# Entry-point tasks: tli-verify's own are bound by their source, not by the tool version
# --------------------------------------------------------------------------------------------

OWN = {"name": "franka-scoop", "distribution": "tli-verify", "version": tli_verify.__version__,
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


# --------------------------------------------------------------------------------------------
# Dependencies: each one of [project.dependencies] has a job at run time
# --------------------------------------------------------------------------------------------

INDIRECT: dict[str, tuple[str, str]] = {}
"""Run-time dependencies used without an import (none since issue 35: clarabel, the SDP solver,
is imported by the A-fit, ``tli_verify/ds/lyapunov.py``, and named to cvxpy elsewhere)."""
PLUGIN_ONLY = {"pytest": "tli_verify/testing/plugin.py"}
"""Imported only by the pytest plugin (a ``pytest11`` entry point: loaded by pytest itself)."""


def _canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _requirements(extra: str | None) -> set[str]:
    from importlib.metadata import requires

    out = set()
    for req in requires("tli-verify") or []:
        name, _, marker = req.partition(";")
        if (extra is None) == ("extra ==" not in marker) and (
                extra is None or f'extra == "{extra}"' in marker):
            out.add(_canonical(re.split(r"[<>=!~\[ (]", name.strip(), maxsplit=1)[0]))
    return out - {"tli-verify"}


def _imports_by_file() -> dict[str, set[str]]:
    import ast

    out: dict[str, set[str]] = {}
    for path in sorted((REPO / "tli_verify").rglob("*.py")):
        names: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
        out[str(path.relative_to(REPO))] = names
    return out


def _modules_of() -> dict[str, set[str]]:
    from importlib.metadata import packages_distributions

    out: dict[str, set[str]] = {}
    for module, dists in packages_distributions().items():
        for dist in dists:
            out.setdefault(_canonical(dist), set()).add(module)
    return out


def test_every_runtime_dependency_is_used_by_the_package() -> None:
    runtime = _requirements(None)
    assert {"numpy", "scipy", "spottl", "cvxpy", "jsonschema"} <= runtime
    imported = set().union(*_imports_by_file().values())
    modules = _modules_of()
    unused = []
    for dist in sorted(runtime):
        if dist in INDIRECT:
            where, token = INDIRECT[dist]
            assert token in (REPO / where).read_text(encoding="utf-8"), (dist, where)
        elif not modules.get(dist, set()) & imported:
            unused.append(dist)
    assert unused == [], "in [project.dependencies] but never imported by tli_verify"


def test_test_only_packages_are_not_imported_at_run_time() -> None:
    """What only [dev] installs (sympy, omega, pydot, ... the tests' cross-checks) is never
    imported by the package: a user's ``pip install tli-verify`` would miss it."""
    dev_only = _requirements("dev") - _requirements(None) - _requirements("sim") \
        - _requirements("cluster") - _requirements("docs")
    assert {"sympy", "omega", "pytest"} <= dev_only
    modules = _modules_of()
    found = []
    for path, names in _imports_by_file().items():
        for dist in sorted(dev_only):
            if modules.get(dist, set()) & names and PLUGIN_ONLY.get(dist) != path:
                found.append((path, dist))
    assert found == []
