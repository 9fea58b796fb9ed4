"""A physical campaign on the backends of the 2-D campaigns: the same seed, trials and workers
give the same trials and verdicts in this process and in worker processes.

Two real trials of 2 s (plus the 1 s of settling; they reach mode b) per run, on a copy of the
current ``sim/franka`` project: ``tli sim franka --workers 2 --backend process --evidence`` against
:func:`~tli_verify.sim.campaign.run_physics_campaign` with ``workers=2`` on the serial backend
(each chunk a fresh executive in both). Slow: about 4 trials of MuJoCo.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("mujoco")

from tests.support.cli import json_records, run
from tests.support.sim import copy_franka_project
from tli_verify.sim.campaign import run_physics_campaign
from tli_verify.sim.physics_config import PhysicsConfig

pytestmark = [pytest.mark.sim, pytest.mark.slow]

SAME = ("seed", "success", "delivered", "mode_trace", "mode_sequence", "cuts_added", "events",
        "retries", "stopped", "perturbed_steps", "limit_ratios", "perturbations")


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """A copy of the Franka project's spec, task, model and certificate."""
    copy_franka_project(tmp_path)
    return tmp_path


def test_process_and_serial_backends_give_the_same_trials(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    certs = project / "certificates"
    code, out, _ = run(capsys, "sim", "franka", "--certificates", str(certs), "--trials", "2",
                       "--duration", "2", "--workers", "2", "--backend", "process",
                       "--json", "--evidence")
    *trials, summary = json_records(out)
    assert code == (0 if summary["passed"] == 2 else 1)
    assert (summary["workers"], summary["backend"], summary["chunks"]) == \
        (2, "process", [[0, 1], [1, 1]])
    by_seed = sorted(trials, key=lambda t: t["seed"])  # chunks complete in any order
    doc = json.loads((certs / "franka-scoop.campaign.json").read_text())
    assert (doc["physics"]["workers"], doc["physics"]["chunks"]) == (2, [[0, 1], [1, 1]])
    assert (doc["campaign"]["backend"], doc["campaign"]["workers"]) == ("process", 2)
    assert [o["seed"] for o in doc["physics"]["outcomes"]] == [0, 1]  # in seed order

    serial = run_physics_campaign(PhysicsConfig(root=str(project), seed=0, trials=2,
                                                duration=2.0, workers=2))
    assert serial.chunks == ((0, 1), (1, 1))
    mine = [dict(r.to_dict(), violations=list(v.violations))
            for r, v in zip(serial.results, serial.verdicts, strict=True)]
    assert all(" " in t["mode_sequence"] for t in mine)  # a mode change to compare
    for key in (*SAME, "violations"):
        assert [t[key] for t in mine] == [t[key] for t in by_seed], key
    assert [o["delivered"] for o in doc["physics"]["outcomes"]] == \
        [r.delivered for r in serial.results]
