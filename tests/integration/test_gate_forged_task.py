"""Issue 31, class 2: the gate re-runs from starts it draws itself, never the recorded one.

The attack, built through the CLI on a copy of the bundled scoop project: the task is edited so
a zone moves (the soup layer, ``regions.yellow``, now only right of ``x1 = 1``: reaching from
the task's start no longer touches the soup), the task's hash in the evidence and the evidence's
digest are recomputed, and ``campaign.settings.start`` is set to a point from which the edited
task happens to work. Before issue 31 the gate's re-run started where the evidence said and
found nothing there; now the recorded start is refused unless it is the task's own first
nominal start, and when the attacker edits that too, half the re-run starts in the task's start
region (the gate's own seed) and finds the moved zone's reachability violations.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest

from tests.support.cli import run

REPO = Path(__file__).resolve().parents[2]
SOUP = "box = { lower = [-inf, -inf], upper = [inf, -4.0] }"
MOVED = "box = { lower = [1.0, -inf], upper = [inf, -4.0] }"  # the soup layer, moved right
WORKS_FROM = [7.0, 0.0]  # reaching from here meets the moved soup layer: the task succeeds
NOMINAL = "nominal = [[-5.0, 4.5]]"


@pytest.fixture
def project(tmp_path: Path) -> Path:
    root = tmp_path / "p"
    for rel in ("tasks/scoop.toml", "specs/scoop.toml", "models/scoop.model.json",
                "certificates/scoop.cert.json", "certificates/scoop.campaign.json"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, root / rel)
    return root


def _forge(root: Path, *, nominal_too: bool, **settings: Any) -> None:
    """Move the zone, then make the evidence agree: the task's hash, the recorded settings,
    the digest (what anyone holding the files can recompute)."""
    from tli_verify.tasks.taskfile import load_task
    from tli_verify.verify.evidence import evidence_digest, task_block

    task = root / "tasks" / "scoop.toml"
    text = task.read_text()
    assert SOUP in text and NOMINAL in text
    text = text.replace(SOUP, MOVED, 1)
    if nominal_too:
        text = text.replace(NOMINAL, f"nominal = [{WORKS_FROM}]", 1)
    task.write_text(text)
    path = root / "certificates" / "scoop.campaign.json"
    doc = json.loads(path.read_text())
    doc["task"] = task_block(load_task(task), path.parent)
    doc["campaign"]["settings"].update(settings)
    doc["digest"] = evidence_digest(doc)
    path.write_text(json.dumps(doc, indent=1))


def _gate(capsys: pytest.CaptureFixture[str], root: Path) -> tuple[int, list[dict[str, Any]]]:
    code, out, err = run(capsys, "gate", str(root), "--rerun", "20", "--json")
    assert "internal error" not in err and "Traceback" not in err, err
    items = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    return code, items


def _blocked(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [i for i in items if i.get("ok") is False]


def test_the_edited_task_works_only_from_the_forged_start(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The premise, through ``tli run``: after the edit the task fails from its own start and
    works from the forged one (so a re-run from the forged start alone finds nothing)."""
    _forge(project, nominal_too=False)
    model = str(project / "models" / "scoop.model.json")
    code, _, _ = run(capsys, "run", "--model", model, "--out", str(project / "o1"))
    assert code == 1  # from the task's nominal start: never touches the moved soup
    code, _, _ = run(capsys, "run", "--model", model, "--start=7.0,0.0",
                     "--out", str(project / "o2"))
    assert code == 0


def test_a_forged_start_with_a_consistent_digest_blocks_the_gate(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The issue's attack: task hash and digest recomputed, ``settings.start`` moved to where
    the edited task works. The evidence check itself passes (hashes and digest agree); the
    gate blocks on the start no ``tli verify`` option could record."""
    code, items = _gate(capsys, project)
    assert code == 0, _blocked(items)  # the honest copy passes
    _forge(project, nominal_too=False, start=WORKS_FROM)
    code, items = _gate(capsys, project)
    assert code == 1, items
    blocked = _blocked(items)
    assert not any(b["check"] == "campaign" and "digest" in b["message"] for b in blocked)
    assert any("campaign.settings.start" in b["message"] and "[7.0, 0.0]" in b["message"]
               for b in blocked), blocked


def test_a_forged_task_start_is_caught_by_the_gates_own_starts(
        project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The attacker moves the task's nominal start too, so the recorded start is the task's
    first nominal start and every recorded setting is one the CLI writes: nothing is left but
    the re-run. It draws half its starts in the task's start region and blocks on the moved
    zone's reachability violations."""
    _forge(project, nominal_too=True, start=WORKS_FROM)
    code, items = _gate(capsys, project)
    assert code == 1, items
    blocked = _blocked(items)
    assert [b["check"] for b in blocked] == ["rerun"], blocked
    message = blocked[0]["message"]
    assert "10 from starts drawn in the task's start region" in message, message
    assert "reachability" in message, message
