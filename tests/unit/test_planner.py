"""One planner (``TaskAutomaton.planned_keys``) for the executive and the deployment gate."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.certification.certificate import issue_certificate, write_certificate
from tli_verify.deploy.gate import run_gate
from tli_verify.errors import ModelError
from tli_verify.logic.automaton import PlannedStep, TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model
from tli_verify.runtime.executive import LTLDSPolicy

_SCOOP: list[TaskAutomaton] = []


def _scoop(specs_dir: Path) -> TaskAutomaton:
    if not _SCOOP:
        _SCOOP.append(synthesize(load_spec(specs_dir / "scoop.toml")))
    return _SCOOP[0]


def _edit(project: Path, edit: Any) -> tuple[Path, Path]:
    """Edit the deployed scoop model and re-certify it (at the certified dt = 1/100)."""
    path = project / "models" / "scoop.model.json"
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    cert = project / "certificates" / "scoop.cert.json"
    write_certificate(issue_certificate(path, cert_path=cert, dt="1/100"), cert)
    return path, cert


def test_never_runs_a_per_transition_ds_towards_a_mode_the_state_cannot_reach(
        project: Path) -> None:
    """The diverging choice of the two former planners: plain DS 'a' whose demonstrated next
    mode is c, and a per-transition DS 'a->c'. No state of a can move to c (only to b). The old
    gate accepted the model (a has a plain DS); the old executive's planner took a's next mode
    c and ran 'a->c', a DS towards a mode the automaton cannot enter from there."""

    def diverge(doc: dict[str, Any]) -> None:
        doc["modes"]["a"]["next_mode"] = "c"
        doc["modes"]["a->c"] = dict(doc["modes"]["a"], mode="a", next_mode="c")

    mpath, cert = _edit(project, diverge)
    # every check passes but the campaign evidence, which the re-certified model outdated
    blockers = run_gate(project, rerun=0).blockers
    assert blockers and {b.check for b in blockers} == {"campaign"}
    aut = synthesize(load_spec(project / "specs" / "scoop.toml"))
    pol = LTLDSPolicy(aut, load_model(mpath), cert)
    for sid, s in enumerate(aut.states):
        if s.mode != "a":
            continue
        pol._enter(sid)
        assert (pol.planned, pol.key) == ("b", "a")  # the plain DS, towards b
    steps = aut.planned_keys({k: (m.mode, m.next_mode) for k, m in pol.model.modes.items()})
    assert all(st.key != "a->c" for st in steps)


def test_the_gate_and_the_executive_consult_the_same_planner(
        project: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A deliberately diverging planner (no DS in the first state of mode b) is seen by both:
    the gate blocks and the executive refuses, on the same state."""
    mpath = project / "models" / "scoop.model.json"
    cert = project / "certificates" / "scoop.cert.json"
    aut = synthesize(load_spec(project / "specs" / "scoop.toml"))
    assert run_gate(project, rerun=0).ok
    LTLDSPolicy(aut, load_model(mpath), cert)
    real = TaskAutomaton.planned_keys

    def diverging(self: TaskAutomaton, ds: Any, goal_modes: Any = None
                  ) -> tuple[PlannedStep, ...]:
        steps = list(real(self, ds, goal_modes))
        i = next(k for k, st in enumerate(steps) if st.mode == "b")
        steps[i] = PlannedStep(steps[i].state, "b", steps[i].next_mode, None, steps[i].moves)
        return tuple(steps)

    monkeypatch.setattr(TaskAutomaton, "planned_keys", diverging)
    sid = next(s.id for s in aut.states if s.mode == "b")
    blockers = [b.message for b in run_gate(project, rerun=0).blockers]
    assert len(blockers) == 1 and f"no DS to run in automaton state {sid} (mode 'b')" \
        in blockers[0]
    with pytest.raises(ModelError, match=f"no DS to run in automaton state {sid} "):
        LTLDSPolicy(aut, load_model(mpath), cert)


MODES = ("a", "b", "c", "d")
KEYS = [m for m in MODES] + [f"{m}->{n}" for m in MODES for n in MODES if m != n]


@given(st.sets(st.sampled_from(KEYS)), st.lists(st.sampled_from(MODES), max_size=2))
def test_planner_contract(specs_dir: Path, chosen: set[str], demo: list[str]) -> None:
    """For any set of DS keys: a key is planned iff the mode has a plain DS or one towards a
    mode the state can move to; a per-transition key always goes where the state can move,
    and is the one of the planned next mode; the next mode is one the state can move to."""
    aut = _scoop(specs_dir)
    ds: dict[str, tuple[str, str | None]] = {}
    for k in chosen:
        if "->" in k:
            m, n = k.split("->")
            ds[k] = (m, n)
        else:
            ds[k] = (k, demo[0] if demo and demo[0] != k else None)
    for step in aut.planned_keys(ds):
        per = {ds[k][1] for k in ds if k != ds[k][0] and ds[k][0] == step.mode}
        runnable = step.mode in ds or bool(per & set(step.moves))
        assert (step.key is not None) == runnable
        assert step.next_mode is None or step.next_mode in step.moves
        if step.key is not None and step.key != step.mode:
            assert step.key == f"{step.mode}->{step.next_mode}"
        if per & set(step.moves):
            assert step.key is not None and step.key != step.mode  # a transition DS first
        if step.mode == "d":  # the goal: nothing planned
            assert step.next_mode is None
