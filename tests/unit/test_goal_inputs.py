"""A cyclic task's goal: a goal mode *and* its sensors (inspection: ``GF(b & rel)``).

One goal for the executive (``LTLDSPolicy.done``), the bundles ``tli run`` ships and the
campaign oracle (``Oracle.goals``/``goal_inputs``), so a campaign judges an inspection episode
by the goal it runs to, not by sink modes the cyclic task does not have.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tli_verify.errors import TliError
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model import load_model
from tli_verify.runtime.bundles import bundle_for_spec, world_of_model
from tli_verify.runtime.executive import LTLDSPolicy

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def inspection() -> tuple:
    aut = synthesize(load_spec(ROOT / "specs/inspection.toml"))
    model = load_model(ROOT / "models/inspection.model.json")
    return aut, model, ROOT / "certificates/inspection.cert.json"


def test_bundle_names_the_cyclic_goal() -> None:
    b = bundle_for_spec("specs/inspection.toml")
    assert b is not None and b.goal_modes == ("b",) and b.goal_inputs == ("rel",)
    assert bundle_for_spec("elsewhere/not-shipped.toml") is None
    assert world_of_model("models/cooking-cb.model.json") == "cooking"
    assert world_of_model("models/inspection.model.json") == "inspection"
    assert world_of_model("models/unknown.model.json") is None


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
    from tli_verify.verify.oracle import Oracle
    from tli_verify.worlds import WORLDS

    aut, model, cert = inspection
    world = WORLDS["inspection"]()
    sinks = Oracle.build(world, aut, model, cert, dt=0.01)
    assert sinks.goals == frozenset()  # repeated forever: no sink mode to reach
    shipped = Oracle.build(world, aut, model, cert, dt=0.01, goal_modes=("b",),
                           goal_inputs=("rel",))
    assert shipped.goals == frozenset({"b"}) and shipped.goal_inputs == frozenset({"rel"})
