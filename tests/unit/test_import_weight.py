"""What importing a command loads: ``tli`` starts without numpy, and no command module imports
MuJoCo before it runs (``tli sim`` checks that MuJoCo loads, with the user's ``MUJOCO_GL``,
before anything imports it: a module-level import of a physics module turned a bad
``MUJOCO_GL`` into an internal error). Measured in fresh interpreters."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tli_verify.io import package_file

COMMANDS = sorted(p.stem for p in package_file("commands").iterdir()
                  if p.suffix == ".py" and p.stem != "__init__")

PROBE = """
import importlib, json, sys
importlib.import_module(sys.argv[1])
print(json.dumps(sorted({m.split(".")[0] for m in sys.modules})))
"""


def _loads(module: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", PROBE, module], capture_output=True, text=True,
                         timeout=120, check=True)
    return set(json.loads(out.stdout))


def test_the_cli_starts_without_numpy() -> None:
    assert not _loads("tli_verify.cli") & {"numpy", "mujoco", "matplotlib", "cvxpy"}


@pytest.mark.parametrize("name", COMMANDS)
def test_no_command_module_imports_mujoco(name: str) -> None:
    assert "mujoco" not in _loads(f"tli_verify.commands.{name}")
