"""Shared pytest configuration: the hypothesis CI profile and common fixtures."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "ci",
    derandomize=True,
    deadline=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
# Local runs keep failing examples in the example database (.hypothesis/), shrunk; CI runs
# are derandomized so that a green CI is reproducible.
settings.register_profile("dev", deadline=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "dev"))

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository root."""
    return REPO


@pytest.fixture(scope="session")
def specs_dir() -> Path:
    """The shipped ``specs/`` directory."""
    return REPO / "specs"


@pytest.fixture
def project(tmp_path: Path, repo: Path) -> Path:
    """A copy of the deployed scoop model, its certificate and spec (a project the gate sees),
    with binding-only campaign evidence (tests/support/evidence.py)."""
    from tests.support.evidence import attach_evidence

    for sub, name in (("models", "scoop.model.json"), ("certificates", "scoop.cert.json"),
                      ("specs", "scoop.toml")):
        (tmp_path / sub).mkdir()
        shutil.copy(repo / sub / name, tmp_path / sub / name)
    attach_evidence(tmp_path)
    return tmp_path
