"""The import contracts (``make lint``) catch what they forbid: each planted violation breaks
its contract, in a copy of the package, and the clean copy keeps them all.

Runs the real ``lint-imports`` on a copy (``PYTHONPATH`` puts the copy first, so the installed
package is not the one analysed).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tli_verify.io import bundled_root

ROOT = Path(__file__).resolve().parents[2]
LINT = Path(sys.executable).with_name("lint-imports")

PLANTS = {
    # module (relative to tli_verify/), import line, contract it breaks
    "layers": ("model/types.py", "import tli_verify.runtime.executive",
               "Layers follow the data flow"),
    "certificate": ("certification/exact.py", "import tli_verify.verify.oracle",
                    "The certificate layer never imports"),
    "spec side": ("logic/labels.py", "import tli_verify.ds.lpvds",
                  "The spec side never imports the demonstration side"),
    "demo side": ("ds/gmm.py", "import tli_verify.logic.spec",
                  "The demonstration side never imports the spec side"),
    "cycle": ("tasks/fields.py", "import tli_verify.tasks.taskfile",
              "No import cycles"),
    "gate": ("deploy/gate.py", "import tli_verify.sim.campaign",
             "The gate reaches campaigns and physics only through the project session"),
    "physics below the session": ("sim/loop.py", "import tli_verify.project.session",
                                  "Layers follow the data flow"),
}


def _copy(tmp: Path) -> Path:
    shutil.copytree(ROOT / "tli_verify", tmp / "tli_verify",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "assets"))
    shutil.copy(ROOT / "pyproject.toml", tmp / "pyproject.toml")
    return tmp


def _lint(where: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(where)}
    return subprocess.run([str(LINT), "--no-cache"], cwd=where, env=env, text=True,
                          capture_output=True, timeout=300, check=False)


pytestmark = pytest.mark.skipif(not LINT.exists() or not (ROOT / "pyproject.toml").is_file()
                                or Path(bundled_root()).resolve() != ROOT,
                                reason="needs the checkout and its dev tools (make lint)")


def test_the_clean_copy_keeps_every_contract(tmp_path: Path) -> None:
    res = _lint(_copy(tmp_path))
    assert res.returncode == 0, res.stdout[-2000:]
    assert "BROKEN" not in res.stdout


@pytest.mark.parametrize("plant", sorted(PLANTS))
def test_a_planted_import_breaks_its_contract(tmp_path: Path, plant: str) -> None:
    module, line, contract = PLANTS[plant]
    root = _copy(tmp_path)
    target = root / "tli_verify" / module
    text = target.read_text(encoding="utf-8")
    head, sep, rest = text.partition("from __future__ import annotations\n")
    target.write_text(head + sep + line + "\n" + rest, encoding="utf-8")
    res = _lint(root)
    assert res.returncode != 0
    broken = [ln for ln in res.stdout.splitlines() if ln.endswith("BROKEN")]
    assert any(contract in b for b in broken), broken  # (an upward import breaks the layers too)
