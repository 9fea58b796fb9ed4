"""Hypothesis drives the C evaluator and the Python runtime with the same perturbation
sequences (pushes at chosen steps, of chosen sizes and directions, reported to both) on the
written task in 2-D to 4-D and on the bundled scoop task: the same modes, DS keys and
invariance failures, the same velocities (bit for bit without cuts, within 1e-12 relative with
cuts learned online)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.cpolicy import CPolicy, build, compiler, library, run_side_by_side
from tests.support.ndtask import NDSensors, write_nd
from tli_verify.deploy.export import build_artifact, write_artifact
from tli_verify.runtime.executive import LTLDSPolicy

REL = 1e-12
CAPACITY = 60
"""Online cuts the written task's artifacts hold."""
NO_SOURCES: dict[str, Any] = {k: None for k in ("spec", "model", "certificate", "task",
                                                 "evidence")}

pytestmark = pytest.mark.skipif(compiler() is None, reason="no system C compiler (cc/gcc)")


class _Setups(dict[str, Any]):
    """The module's built setups, with a short repr: hypothesis prints a failing example's
    arguments, and the full models made a 95 kB repr (a warning that hid the failure)."""

    def __repr__(self) -> str:
        return f"<setups {sorted(self)}>"


@pytest.fixture(scope="module")
def setups(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    lib = library(build(tmp_path_factory.mktemp("cbuild")))
    out: dict[str, Any] = _Setups(lib=lib)
    for n in (2, 3, 4):
        root = tmp_path_factory.mktemp(f"nd{n}")
        nd = write_nd(root, n, K=3, seed=10 + n)
        art = build_artifact(nd.setup, goal_modes=("d",), goal_inputs=(), sources=NO_SOURCES,
                             max_online_cuts=CAPACITY)
        nd.exported = write_artifact(art, root / "nd.tli.json")
        out[str(n)] = nd
    return out


pushes = st.lists(
    st.tuples(st.integers(1, 300), st.floats(0.05, 1.5), st.integers(0, 2**31 - 1)),
    max_size=4)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=st.sampled_from([2, 3, 4]), start=st.floats(0.0, 0.95), seq=pushes)
def test_same_perturbations_same_policy(setups: dict[str, Any], n: int, start: float,
                                        seq: list[tuple[int, float, int]]) -> None:
    nd = setups[str(n)]
    plan = []
    for step, size, seed in seq:
        d = np.random.default_rng(seed).normal(size=n)
        plan.append((step, size * d / np.linalg.norm(d)))
    pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01)
    c = CPolicy(setups["lib"], nd.exported.text_path)
    x0 = np.r_[start, np.zeros(n - 1)]
    tr = run_side_by_side(pol, c, nd.exported.artifact, NDSensors(n), x0, 350,
                          np.random.default_rng(0), pushes=plan)
    # the C side's storage holds CAPACITY online cuts and refuses the next one (its documented
    # contract; lock step ends there): never earlier. Sliding along a face of the tube, online
    # cuts alone can exceed it (test_online_cuts_alone_chatter_along_a_face)
    assert tr.refused == 0 or tr.cuts_added == CAPACITY
    assert tr.modes_c == tr.modes_py and tr.keys_c == tr.keys_py
    assert tr.failures_c == tr.failures_py
    for a, b, cut in zip(tr.v_py, tr.v_c, tr.cut_steps, strict=True):
        if cut:
            assert np.max(np.abs(a - b)) <= REL * max(1.0, float(np.max(np.abs(a))))
        else:
            assert np.array_equal(a, b)


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seq=pushes, x0=st.tuples(st.floats(-7.5, 7.5), st.floats(-7.5, 7.5)))
def test_same_perturbations_scoop(setups: dict[str, Any], repo: Path,
                                  tmp_path_factory: pytest.TempPathFactory,
                                  seq: list[tuple[int, float, int]],
                                  x0: tuple[float, float]) -> None:
    from tli_verify.loaded import load_project
    from tli_verify.runtime.setup import check_goal, make_policy
    from tli_verify.runtime.task_sensors import TaskSensors

    if "scoop" not in setups:
        project = load_project(model=repo / "models" / "scoop.model.json")
        setup = project.setup
        art = build_artifact(setup, goal_modes=check_goal(setup.automaton, project.goal,
                                                          where="scoop"),
                             goal_inputs=(), sources=NO_SOURCES, max_online_cuts=60)
        setups["scoop"] = (setup, write_artifact(art, tmp_path_factory.mktemp("scoop")
                                                 / "scoop.tli.json"))
    setup, ex = setups["scoop"]
    plan = []
    for step, size, seed in seq:
        d = np.random.default_rng(seed).normal(size=2)
        plan.append((step, 4.0 * size * d / np.linalg.norm(d)))
    pol = make_policy(setup, "LTL-DS")
    c = CPolicy(setups["lib"], ex.text_path)
    tr = run_side_by_side(pol, c, ex.artifact, TaskSensors(setup.task), np.array(x0), 400,
                          np.random.default_rng(0), pushes=plan)
    assert tr.modes_c == tr.modes_py and tr.keys_c == tr.keys_py
    assert tr.failures_c == tr.failures_py
    for a, b, cut in zip(tr.v_py, tr.v_c, tr.cut_steps, strict=True):
        if cut:
            assert np.max(np.abs(a - b)) <= REL * max(1.0, float(np.max(np.abs(a))))
        else:
            assert np.array_equal(a, b)
