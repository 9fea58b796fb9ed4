"""A physical campaign in chunks, one executive each, with the trials stated, not simulated:
``run_physics_campaign`` with a stand-in for ``run_trial`` that records which executive ran
each trial and how many cuts it had learned before (the real trials on the serial and process
backends: ``tests/integration/test_physics_backends.py``); the evidence records the partition
and the evidence check recomputes it.
"""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mujoco")

from tests.support.cli import run
from tli_verify.errors import CampaignError
from tli_verify.io import bundled_dir
from tli_verify.sim import campaign as campaign_module
from tli_verify.sim import franka_project
from tli_verify.sim.campaign import PhysicsResult, run_physics_campaign
from tli_verify.sim.loop import TrialResult
from tli_verify.sim.physics_checks import check_physics_block
from tli_verify.sim.physics_config import PhysicsConfig
from tli_verify.sim.physics_evidence import write_physics_evidence
from tli_verify.sim.trial_oracle import TrialVerdict

pytestmark = pytest.mark.sim

FRANKA = str(bundled_dir("sim") / "franka")


class Executive:
    """Stands in for an LTL-DS executive: numbered as made, it learns one cut per trial."""

    made = 0

    def __init__(self) -> None:
        Executive.made += 1
        self.number = Executive.made
        self.cuts = 0
        self.automaton = None
        self.goal_modes = ("d",)


def fake_trial(policy: Executive, seed: int, **_: Any) -> TrialResult:
    before, policy.cuts = policy.cuts, policy.cuts + 1
    return TrialResult(seed=seed, variant="LTL-DS", success=True, delivered=2, modes=("a", "d"),
                       cuts_added=1, sim_time=1.0, wall_time=0.0, perturbations=(),
                       applied=(), events=(f"executive {policy.number}", f"{before} cut(s)"))


@pytest.fixture
def stated(monkeypatch: pytest.MonkeyPatch) -> None:
    """Trials stated, not simulated; a fresh executive per ``load_policy``."""
    Executive.made = 0
    for where in (campaign_module, franka_project):  # the campaign's and tli sim's
        monkeypatch.setattr(where, "load_policy", lambda *a, **k: Executive())
    monkeypatch.setattr(campaign_module, "run_trial", fake_trial)
    monkeypatch.setattr(campaign_module, "check_trial",
                        lambda res, automaton, goal_modes: TrialVerdict(seed=res.seed))


def campaign(workers: int, **kw: Any) -> tuple[PhysicsResult, list[int]]:
    seen: list[int] = []
    config = PhysicsConfig(root=FRANKA, seed=10, trials=7, duration=2.0, workers=workers)
    result = run_physics_campaign(config, on_trial=lambda k, r, v: seen.append(k), **kw)
    return result, seen


def who(result: PhysicsResult) -> list[tuple[str, ...]]:
    return [r.events for r in result.results]


@pytest.mark.usefixtures("stated")
def test_one_worker_is_one_executive_for_every_trial() -> None:
    result, seen = campaign(1)
    assert result.chunks == ((10, 7),) and seen == list(range(7))
    assert [r.seed for r in result.results] == list(range(10, 17))
    assert who(result) == [("executive 1", f"{k} cut(s)") for k in range(7)]
    assert result.cuts_added == 7


@pytest.mark.usefixtures("stated")
def test_each_chunk_has_its_own_executive_and_its_cuts_carry_over_within_it() -> None:
    result, seen = campaign(3)
    assert result.chunks == ((10, 3), (13, 2), (15, 2)) and seen == list(range(7))
    assert [r.seed for r in result.results] == list(range(10, 17))
    assert who(result) == [("executive 1", "0 cut(s)"), ("executive 1", "1 cut(s)"),
                           ("executive 1", "2 cut(s)"), ("executive 2", "0 cut(s)"),
                           ("executive 2", "1 cut(s)"), ("executive 3", "0 cut(s)"),
                           ("executive 3", "1 cut(s)")]


@pytest.mark.usefixtures("stated")
def test_a_given_executive_runs_the_first_chunk_on_the_serial_backend_only() -> None:
    mine = Executive()
    result, _ = campaign(2, policy=mine)
    assert mine.cuts == 4 and who(result)[:4] == [(f"executive {mine.number}", f"{k} cut(s)")
                                                  for k in range(4)]
    config = PhysicsConfig(root=FRANKA, trials=2, workers=2, backend="process")
    with pytest.raises(CampaignError, match="need the serial backend"):
        run_physics_campaign(config, policy=mine)


@pytest.mark.parametrize(("field", "value", "said"), [
    ("workers", 0, "workers: expected an integer in"), ("workers", 257, "in \\[1, 256\\]"),
    ("workers", True, "workers"), ("backend", "threads", "backend: one of serial, process")])
def test_bad_partition_settings_are_refused(field: str, value: object, said: str) -> None:
    with pytest.raises(CampaignError, match=said):
        PhysicsConfig(root=FRANKA, **{field: value})  # type: ignore[arg-type]


@pytest.mark.usefixtures("stated")
def test_the_evidence_records_the_partition_and_the_check_recomputes_it(tmp_path: Path) -> None:
    result, _ = campaign(3)
    _, doc = write_physics_evidence(result, tmp_path / "franka-scoop.campaign.json")
    assert doc["physics"]["workers"] == doc["campaign"]["workers"] == 3
    assert doc["physics"]["chunks"] == [[10, 3], [13, 2], [15, 2]]
    assert doc["campaign"]["backend"] == "serial"
    passed: list[str] = []
    assert check_physics_block(doc, "e.json", passed) == []
    assert "7 perturbed physical trial(s) in 3 chunks of seeds, one executive each" in passed[0]
    doc["physics"]["chunks"] = [[10, 4], [14, 3]]  # not what 3 workers give
    assert check_physics_block(doc, "e.json", []) == [
        "e.json: physics.chunks is not the contiguous partition of the seeds into 3 chunk(s) "
        "(expected [10, 3], [13, 2], [15, 2])"]
    doc["physics"]["workers"] = 2
    assert "physics.workers 2 differs from campaign.workers 3" in \
        check_physics_block(doc, "e.json", [])[0]
    one, _ = campaign(1)
    _, doc = write_physics_evidence(one, tmp_path / "one.campaign.json")
    assert (doc["physics"]["workers"], doc["physics"]["chunks"]) == (1, [[10, 7]])
    passed = []
    assert check_physics_block(doc, "e.json", passed) == [] and "chunks" not in passed[0]


@pytest.mark.usefixtures("stated")
def test_ctrl_c_in_a_later_chunk_writes_no_evidence(monkeypatch: pytest.MonkeyPatch,
                                                    tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C in the second chunk: exit 130, and no evidence file, not even a partial one (an
    existing one is kept as it was)."""
    for sub, name in (("specs", "franka-scoop.toml"), ("tasks", "franka-scoop.toml"),
                      ("models", "franka-scoop.model.json"),
                      ("certificates", "franka-scoop.cert.json")):
        (tmp_path / sub).mkdir()
        shutil.copy(Path(FRANKA) / sub / name, tmp_path / sub / name)

    def interrupted(policy: Executive, seed: int, **kw: Any) -> TrialResult:
        if seed == 2:
            raise KeyboardInterrupt
        return fake_trial(policy, seed, **kw)

    monkeypatch.setattr(campaign_module, "run_trial", interrupted)
    code, out, err = run(capsys, "sim", "franka", "--certificates",
                         str(tmp_path / "certificates"), "--trials", "4", "--workers", "2",
                         "--evidence")
    assert code == 130 and err == "error: interrupted\n", err
    assert out.count("trial ") == 2  # the first chunk's trials were reported
    assert sorted(p.name for p in (tmp_path / "certificates").iterdir()) == \
        ["franka-scoop.cert.json"]
