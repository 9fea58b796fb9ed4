"""A cyclic task's goal: a goal mode *and* its sensors (inspection: ``GF(b & rel)``).

One goal for the executive (``LTLDSPolicy.done``), the runs ``tli run`` resolves (the spec's
``[goal]`` table, :func:`tli_verify.tasks.project.resolve`) and the campaign oracle
(``Oracle.goals``/``goal_inputs``), so a campaign judges an inspection episode by the goal it
runs to, not by sink modes the cyclic task does not have.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tli_verify.errors import TaskError, TliError
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.setup import check_goal
from tli_verify.tasks.project import resolve
from tli_verify.tasks.task import Goal

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def inspection() -> tuple:
    aut = synthesize(load_spec(ROOT / "specs/inspection.toml"))
    model = load_model(ROOT / "models/inspection.model.json")
    return aut, model, ROOT / "certificates/inspection.cert.json"


def _project(root: Path, shipped: str, stem: str, *, spec_text: str | None = None) -> Path:
    """A project under ``root`` holding the shipped spec, model and certificate ``shipped``
    under the name ``stem`` (the model re-bound to the renamed spec); returns the spec."""
    for sub in ("specs", "models", "certificates"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    spec = root / "specs" / f"{stem}.toml"
    spec.write_text(spec_text if spec_text is not None
                    else (ROOT / "specs" / f"{shipped}.toml").read_text())
    doc = json.loads((ROOT / "models" / f"{shipped}.model.json").read_text())
    doc["spec"] = f"../specs/{stem}.toml"
    (root / "models" / f"{stem}.model.json").write_text(json.dumps(doc))
    shutil.copy(ROOT / "certificates" / f"{shipped}.cert.json",
                root / "certificates" / f"{stem}.cert.json")
    return spec


def test_spec_names_the_cyclic_goal() -> None:
    r = resolve(spec=ROOT / "specs/inspection.toml")
    assert r.task.name == "inspection"
    assert r.goal == Goal(("b",), ("rel",))
    assert check_goal(synthesize(load_spec(r.spec)), r.goal, where=str(r.spec)) == ("b",)
    assert resolve(task="inspection").goal == Goal(("b",), ("rel",))  # the task's spec
    cc = resolve(spec=ROOT / "specs/cooking-cc.toml")
    assert cc.task.name == "cooking" and cc.goal == Goal(("d",))
    assert check_goal(synthesize(load_spec(cc.spec)), cc.goal, where=str(cc.spec)) == ("d",)


def test_goal_is_in_the_spec_file_not_in_its_name(tmp_path: Path) -> None:
    """The goal is read from the file: a renamed inspection spec keeps it, and a file that
    happens to be called ``inspection.toml`` does not get it (the old name lookup did)."""
    renamed = _project(tmp_path / "renamed", "inspection", "patrol")
    r = resolve(spec=renamed)
    assert r.spec == renamed and r.task.name == "inspection"
    assert r.goal == Goal(("b",), ("rel",))
    # the scoop spec under inspection's file name: scoop's goal (its sink mode d)
    named = _project(tmp_path / "named", "scoop", "inspection")
    s = resolve(spec=named)
    assert s.task.name == "scoop" and s.goal == Goal()
    assert check_goal(synthesize(load_spec(named)), s.goal, where=str(named)) == ("d",)
    # inspection's spec without its [goal] table, still called inspection.toml: no goal at all
    text = (ROOT / "specs/inspection.toml").read_text()
    assert "\n[goal]" in text
    bare = _project(tmp_path / "bare", "inspection", "inspection",
                    spec_text=text[:text.index("\n[goal]")] + "\n")
    b = resolve(spec=bare)
    assert b.goal == Goal() and b.goal != Goal(("b",), ("rel",))
    with pytest.raises(TaskError, match="no sink mode"):
        check_goal(synthesize(load_spec(bare)), b.goal, where=str(bare))


def test_model_names_its_task() -> None:
    assert resolve(model=ROOT / "models/cooking-cb.model.json").task.name == "cooking"
    r = resolve(model=ROOT / "models/inspection.model.json")
    assert r.task.name == "inspection" and r.goal == Goal(("b",), ("rel",))
    with pytest.raises(TaskError, match="no such model file"):
        resolve(model=ROOT / "models/unknown.model.json")


def test_done_needs_the_goal_sensors(inspection: tuple) -> None:
    aut, model, cert = inspection
    pol = LTLDSPolicy(aut, model, cert, goal_modes=("b",), goal_inputs=("rel",))
    plain = LTLDSPolicy(aut, model, cert, goal_modes=("b",))
    x = np.zeros(model.dim)
    for p in (pol, plain):
        p.reset(x, {"line": False, "rel": False})
        p.step(x, {"line": True, "rel": False})
        assert p.mode == "b"
    assert plain.done and not pol.done  # on the line, nothing released yet
    pol.step(x, {"line": True, "rel": True})
    assert pol.mode == "b" and pol.done


def test_fork_keeps_the_goal_and_the_class(inspection: tuple) -> None:
    aut, model, cert = inspection

    class Sub(LTLDSPolicy):
        __slots__ = ("tag",)

    pol = Sub(aut, model, cert, goal_modes=("b",), goal_inputs=("rel",))
    pol.tag = "kept"
    new = pol.fork()
    assert type(new) is Sub and new.tag == "kept" and new.goal_inputs == frozenset({"rel"})


def test_unknown_goal_sensor_is_refused(inspection: tuple) -> None:
    aut, model, cert = inspection
    with pytest.raises(TliError, match="goal_inputs: 'nope'"):
        LTLDSPolicy(aut, model, cert, goal_modes=("b",), goal_inputs=("nope",))


def test_oracle_goal_of_a_cyclic_task(inspection: tuple) -> None:
    from tli_verify.tasks.registry import find_task
    from tli_verify.verify.oracle import Oracle

    aut, model, cert = inspection
    task = find_task("inspection")
    sinks = Oracle.build(task, aut, model, cert, dt=0.01)
    assert sinks.goals == frozenset()  # repeated forever: no sink mode to reach
    goal = resolve(spec=ROOT / "specs/inspection.toml").goal
    shipped = Oracle.build(task, aut, model, cert, dt=0.01, goal_modes=goal.modes,
                           goal_inputs=goal.sensors)
    assert shipped.goals == frozenset({"b"}) and shipped.goal_inputs == frozenset({"rel"})
