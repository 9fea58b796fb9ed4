"""CI runs hypothesis derandomized: the ``ci`` profile and ``.ci/run`` selecting it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from hypothesis import settings

import tests.conftest  # noqa: F401  (registers the profiles)


def _loaded_profile(repo: Path, env_profile: str | None) -> str:
    """``derandomize`` of the default settings after conftest runs in a clean interpreter."""
    env = {k: v for k, v in os.environ.items() if k not in ("HYPOTHESIS_PROFILE", "CI")}
    if env_profile is not None:
        env["HYPOTHESIS_PROFILE"] = env_profile
    code = ("import tests.conftest; from hypothesis import settings; "
            "print(settings.default.derandomize, settings.default.database)")
    out = subprocess.run([sys.executable, "-c", code], cwd=repo, env=env, check=True,
                         capture_output=True, text=True)
    return out.stdout.strip()


def test_ci_profile_is_derandomized() -> None:
    ci = settings.get_profile("ci")
    assert ci.derandomize is True
    assert ci.deadline is None  # no timing-dependent failures on a loaded CI machine


def test_conftest_loads_the_profile_the_environment_names(repo: Path) -> None:
    assert _loaded_profile(repo, "ci") == "True None"
    assert _loaded_profile(repo, None).startswith("False")  # local runs: dev profile


def test_ci_run_selects_the_ci_profile_whatever_the_environment(tmp_path: Path,
                                                                repo: Path) -> None:
    """Run ``.ci/run`` with a stand-in ``make`` that records the profile it sees."""
    record = tmp_path / "make.log"
    fake = tmp_path / "bin" / "make"
    fake.parent.mkdir()
    fake.write_text(f'#!/bin/sh\necho "$HYPOTHESIS_PROFILE $*" >> {record}\n')
    fake.chmod(0o755)
    env = {**os.environ, "PATH": f"{fake.parent}{os.pathsep}{os.environ['PATH']}",
           "HYPOTHESIS_PROFILE": "dev"}
    env.pop("CI", None)
    subprocess.run(["bash", str(repo / ".ci" / "run")], env=env, check=True,
                   capture_output=True, text=True)
    assert record.read_text().splitlines() == ["ci test", "ci docs", "ci gate"]
