"""The executive's ``learn_transitions`` refusals and its bounded entry-state record.

A toy project: two sensors ``u``, ``v``; modes ``a`` (neither), ``b`` (u), ``c`` (v); a
hand-built certified model (stable linear DS, ``P = I``). The closed-loop success case (scoop,
growing to paper Fig. 3(a)) is ``tests/integration/test_grow_closed_loop.py``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.certification.certificate import issue_certificate, write_certificate
from tli_verify.errors import TliError
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.spec import parse_spec
from tli_verify.model.serialize import load_model, model_from_dict, save_model
from tli_verify.model.types import Model
from tli_verify.runtime.events import (
    AssumptionViolationEvent,
    TransitionLearned,
    TransitionRefused,
)
from tli_verify.runtime.executive import MAX_ENTRY_STATES, LTLDSPolicy

MODES = '''
[modes]
a = "!u & !v"
b = "u & !v"
c = "!u & v"
'''

NO_MARKER = '''
name = "chain-no-marker"
inputs = ["u", "v"]
outputs = ["a", "b", "c"]
''' + MODES + '''
[assume]
init = "!u & !v"
safety = [
  "G((!u & !v) -> X((!u & !v) | (u & !v)))",
  "G((u & !v) -> X((u & !v) | (!u & v)))",
  "G((!u & v) -> X(!u & v))",
]
liveness = ["GF(!a | u)", "GF(!b | v)"]
[guarantee]
init = "a"
safety = ["G(a -> X(a | b))", "G(b -> X(b | c))", "G(c -> X c)"]
liveness = ["GF c"]
'''
"""a -> b -> c with no perturbation marker: adding b -> a lets the world loop a, b, a, b
while meeting both fairness assumptions, so the goal GF c is lost (unrealizable)."""

C_UNSEEN = '''
name = "c-unseen"
inputs = ["u", "v"]
outputs = ["a", "b", "c", "p"]
''' + MODES + '''
[assume]
init = "!u & !v"
safety = [
  "G((!u & !v) -> X((!u & !v) | (u & !v)))",
  "G((u & !v) -> X(u & !v))",
  "G((!u & v) -> X(!u & v))",
]
liveness = ["GF(!a | u)"]
[guarantee]
init = "a & !p"
safety = ["G(a -> X(a | b))", "G(b -> X b)", "G(c -> X c)", "G(X p <-> false)"]
liveness = ["GF(b | c | p)"]
'''
"""Mode c is known (labelled) but the assumptions never show it: the automaton runs a and b
only, so a model with DS for a and b is covered -- until a -> c is learned."""

I2 = [[1.0, 0.0], [0.0, 1.0]]
STABLE = [[-1.0, 0.0], [0.0, -1.0]]


def _ds(mode: str, nxt: str | None, att: list[float]) -> dict[str, Any]:
    return {"mode": mode, "next_mode": nxt, "attractor": att, "P": I2,
            "components": [{"prior": 1.0, "mean": att, "cov": I2, "A": STABLE}], "cuts": []}


def _project(root: Path, spec_text: str, modes: dict[str, dict[str, Any]]
             ) -> tuple[Any, Model, Path]:
    for d in ("specs", "models", "certificates"):
        (root / d).mkdir(parents=True, exist_ok=True)
    (root / "specs" / "toy.toml").write_text(spec_text)
    doc = {"schema_version": 1, "state_names": ["x0", "x1"], "spec": "../specs/toy.toml",
           "modes": modes}
    mpath = root / "models" / "toy.model.json"
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = root / "certificates" / "toy.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    return parse_spec(spec_text), load_model(mpath), cpath


def _policy(root: Path, spec_text: str, modes: dict[str, dict[str, Any]]) -> LTLDSPolicy:
    spec, model, cert = _project(root, spec_text, modes)
    return LTLDSPolicy(synthesize(spec), model, cert, spec=spec, learn_transitions=True)


ABC = {"a": _ds("a", "b", [1.0, 0.0]), "b": _ds("b", "c", [2.0, 0.0]),
       "c": _ds("c", None, [3.0, 0.0])}


def test_an_edge_that_makes_the_spec_unrealizable_is_refused(tmp_path: Path) -> None:
    assert check_spec(parse_spec(NO_MARKER)).realizable
    pol = _policy(tmp_path, NO_MARKER, ABC)
    before = pol.automaton
    x = np.zeros(2)
    pol.reset(x, {})
    pol.decide(x, {"u": True})
    assert pol.mode == "b"
    pol.decide(x, {}, perturbed=True)  # knocked back: b -> a, which the spec lacks
    refused = [e for e in pol.events if isinstance(e, TransitionRefused)]
    assert [(e.from_mode, e.to_mode, e.reading) for e in refused] == [("b", "a", ())]
    assert "unrealizable" in refused[0].reason and "old spec is kept" in refused[0].reason
    assert not any(isinstance(e, TransitionLearned) for e in pol.events)
    # the old spec and automaton are kept; the reading is an assumption violation, resynced
    assert pol.automaton is before and pol.learned == ()
    assert pol.spec is not None and check_spec(pol.spec).realizable
    viol = [e for e in pol.events if isinstance(e, AssumptionViolationEvent)]
    assert len(viol) == 1 and viol[0].resynced is not None and pol.mode == "a"
    # the refusal is remembered: the same change is not re-synthesized again
    pol.decide(x, {"u": True})
    pol.decide(x, {}, perturbed=True)
    assert len([e for e in pol.events if isinstance(e, TransitionRefused)]) == 1


def test_a_grown_automaton_the_model_does_not_cover_is_refused(tmp_path: Path) -> None:
    modes = {"a": _ds("a", "b", [1.0, 0.0]), "b": _ds("b", None, [2.0, 0.0])}
    pol = _policy(tmp_path, C_UNSEEN, modes)  # covered: the automaton runs a and b only
    assert sorted({s.mode for s in pol.automaton.states}) == ["a", "b"]
    x = np.zeros(2)
    pol.reset(x, {})
    pol.decide(x, {"v": True}, perturbed=True)  # a -> c: realizable, but no DS for c
    refused = [e for e in pol.events if isinstance(e, TransitionRefused)]
    assert [(e.from_mode, e.to_mode) for e in refused] == [("a", "c")]
    assert "no DS for mode 'c'" in refused[0].reason
    assert pol.learned == () and "c" not in {s.mode for s in pol.automaton.states}
    assert pol.mode != "c"  # it never runs a mode the certified model has no DS for
    # with a DS for c (a certified model that covers it) the same change is learned
    modes["c"] = _ds("c", None, [3.0, 0.0])
    pol = _policy(tmp_path / "covered", C_UNSEEN, modes)
    pol.reset(x, {})
    pol.decide(x, {"v": True}, perturbed=True)
    learned = [e for e in pol.events if isinstance(e, TransitionLearned)]
    assert [(e.from_mode, e.to_mode, e.perturbed) for e in learned] == [("a", "c", True)]
    assert pol.learned == (("a", "c"),) and pol.mode == "c"
    assert not any(isinstance(e, AssumptionViolationEvent) for e in pol.events)


def test_a_reading_no_mode_label_covers_is_not_learned(tmp_path: Path) -> None:
    pol = _policy(tmp_path, C_UNSEEN, {"a": _ds("a", "b", [1.0, 0.0]),
                                       "b": _ds("b", None, [2.0, 0.0])})
    x = np.zeros(2)
    pol.reset(x, {})
    pol.decide(x, {"u": True, "v": True}, perturbed=True)  # no label holds (Asm. 3)
    refused = [e for e in pol.events if isinstance(e, TransitionRefused)]
    assert [(e.from_mode, e.to_mode) for e in refused] == [("a", None)]
    assert "Asm. 3" in refused[0].reason
    assert pol.holding and pol.learned == ()


def test_learning_needs_the_matching_spec(tmp_path: Path) -> None:
    spec, model, cert = _project(tmp_path, C_UNSEEN, {"a": _ds("a", "b", [1.0, 0.0]),
                                                      "b": _ds("b", None, [2.0, 0.0])})
    with pytest.raises(TliError, match="needs the spec"):
        LTLDSPolicy(synthesize(spec), model, cert, learn_transitions=True)
    other = parse_spec(C_UNSEEN.replace('inputs = ["u", "v"]', 'inputs = ["u", "v", "w"]'))
    with pytest.raises(TliError, match="not the spec of the automaton"):
        LTLDSPolicy(synthesize(spec), model, cert, spec=other, learn_transitions=True)


def test_entry_states_stay_bounded_and_keep_their_spread(tmp_path: Path) -> None:
    pol = _policy(tmp_path, NO_MARKER, ABC)
    far = np.array([-50.0, 40.0])
    pol.reset(far, {})  # one isolated entry state first
    rng = np.random.default_rng(0)
    for _ in range(5 * MAX_ENTRY_STATES):  # then many entries in a small cluster
        pol.reset(rng.normal(scale=0.1, size=2), {})
    kept = pol._entries["a"]
    assert len(kept) == MAX_ENTRY_STATES
    # a first-in-first-out record would have dropped it long ago
    assert any(np.array_equal(k, far) for k in kept)


@settings(max_examples=25)
@given(st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), min_size=1, max_size=200))
def test_entry_record_never_exceeds_its_bound(points: list[tuple[float, float]]) -> None:
    pol = object.__new__(LTLDSPolicy)
    pol._entries = {}
    for p in points:
        pol._record_entry("a", np.array(p))
    kept = pol._entries["a"]
    assert len(kept) == min(len(points), MAX_ENTRY_STATES)
    assert any(np.array_equal(k, np.array(points[-1])) for k in kept)  # the newest is kept
