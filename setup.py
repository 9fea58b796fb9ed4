"""Build hook of tli-verify: the bundled project becomes package data of the wheel.

Everything else about the distribution (name, version, dependencies, packages) is in
``pyproject.toml``. This file only replaces ``build_py`` so that a wheel (built from the source
tree or from the sdist, whose ``MANIFEST.in`` carries the same folders) contains the bundled
project under ``tli_verify/data/``:

* ``tasks/``, ``specs/``, ``demos/``, ``models/``, ``certificates/`` (the repository root's
  deployed project, gate-clean);
* ``sim/franka/{tasks,specs,demos,models,certificates}`` and ``sim/PROVENANCE.md`` (the MuJoCo
  Franka project).

``sim/assets/`` (the MuJoCo Menagerie Panda, fetched at run time by
``python -m tli_verify.sim.assets fetch``) is never packaged. In a checkout or an editable
install nothing is copied: :func:`tli_verify.io.bundled_dir` finds the folders at the top of
the source tree, where they stay.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
#: The bundled project, relative to the repository root (and to ``tli_verify/data/``).
BUNDLED_DIRS = (
    "tasks", "specs", "demos", "models", "certificates",
    "sim/franka/tasks", "sim/franka/specs", "sim/franka/demos", "sim/franka/models",
    "sim/franka/certificates",
)
BUNDLED_FILES = ("sim/PROVENANCE.md",)
_IGNORE = shutil.ignore_patterns("__pycache__", "*.py[cod]", ".*")


class BuildPyWithData(build_py):
    """``build_py`` that also copies the bundled project into ``<build_lib>/tli_verify/data``."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):  # pip install -e .: read from the tree
            return
        data = Path(self.build_lib) / "tli_verify" / "data"
        shutil.rmtree(data, ignore_errors=True)  # never ship a stale copy of an earlier build
        missing = [rel for rel in (*BUNDLED_DIRS, *BUNDLED_FILES) if not (ROOT / rel).exists()]
        if missing:
            raise SystemExit(f"tli-verify build: bundled files missing from {ROOT}: "
                             f"{', '.join(missing)}")
        for rel in BUNDLED_DIRS:
            shutil.copytree(ROOT / rel, data / rel, ignore=_IGNORE)
        for rel in BUNDLED_FILES:
            (data / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / rel, data / rel)


setup(cmdclass={"build_py": BuildPyWithData})
