"""The runtime engine and online work on a model: rollouts, cuts on a model, the modulator
cache, pickling, saving learned cuts as a certified model."""

from __future__ import annotations

import json
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.boundary.cuts import Cut, inside_cuts
from tli_verify.boundary.modulation import modulate
from tli_verify.certification.certificate import check_certificate
from tli_verify.errors import CertificateError, ModelError
from tli_verify.model.serialize import load_model, model_from_dict
from tli_verify.model.types import Model
from tli_verify.runtime.online import cut_for_failure, learn_cuts
from tli_verify.runtime.persist import save_certified
from tli_verify.runtime.rollout import EulerProtocol, cap_speed, failures, rollout

I2 = [[1.0, 0.0], [0.0, 1.0]]
SPIRAL = np.array([[-0.4, 2.0], [-2.0, -0.4]])
GOAL = np.array([5.0, 1.5])


def _square(X: np.ndarray) -> np.ndarray:
    return np.all((X >= 0.0) & (X <= 10.0), axis=1)


def _spiral(X: np.ndarray) -> np.ndarray:
    return (np.atleast_2d(X) - GOAL) @ SPIRAL.T


def _doc(A: list[list[float]] | None = None) -> dict[str, Any]:
    def ds(mode: str, nxt: str | None, att: list[float]) -> dict[str, Any]:
        return {"mode": mode, "next_mode": nxt, "attractor": att, "P": I2,
                "components": [{"prior": 1.0, "mean": att, "cov": I2,
                                "A": A or [[-1.0, -2.0], [2.0, -1.0]]}], "cuts": []}
    return {"schema_version": 1, "state_names": ["x0", "x1"], "spec": None,
            "modes": {"a->b": ds("a", "b", [3.0, 0.0]), "a->c": ds("a", "c", [0.0, 3.0]),
                      "b": ds("b", None, [9.0, 9.0])}}


def _model(tmp_path: Path, A: list[list[float]] | None = None) -> Model:
    path = tmp_path / "m.model.json"
    path.write_text(json.dumps(_doc(A)))
    return load_model(path)


# ------------------------------------------------------------------------------- rollouts

def _loop_rollout(policy: Any, starts: np.ndarray, p: EulerProtocol) -> list[tuple[bool, int]]:
    """The per-start, per-step Python loop the batched engine replaces."""
    out = []
    for x0 in starts:
        x = x0.copy()
        result = (False, -1)
        for t in range(1, p.steps + 1):
            v = cap_speed(policy(x[None, :]), p.speed_cap)[0]
            x_new = x + p.dt * v
            if not _square(x_new[None, :])[0]:
                result = (False, t)
                break
            x = x_new
            if np.linalg.norm(x - GOAL) <= p.goal_tolerance:
                result = (True, -1)
                break
        out.append(result)
    return out


def test_batched_rollout_matches_a_per_step_loop() -> None:
    rng = np.random.default_rng(3)
    starts = rng.uniform(0.5, 9.5, (25, 2))
    p = EulerProtocol(dt=0.01, steps=400)
    res = rollout(_spiral, starts, _square, GOAL, dt=p.dt, steps=p.steps,
                  speed_cap=p.speed_cap, goal_tolerance=p.goal_tolerance)
    ref = _loop_rollout(_spiral, starts, p)
    assert [bool(r) for r in res.reached] == [r[0] for r in ref]
    assert [int(s) if left else -1 for s, left in zip(res.exit_step, res.left, strict=True)] \
        == [r[1] for r in ref]
    assert res.left.any() and res.reached.any()  # both outcomes are exercised
    fails = failures(res)
    assert len(fails) == int(res.left.sum())
    for f in fails:
        assert _square(f.last_inside[None, :])[0] and not _square(f.outside[None, :])[0]


def test_learned_cuts_stop_every_exit() -> None:
    rng = np.random.default_rng(0)
    starts = rng.uniform(1.0, 9.0, (30, 2))
    out = learn_cuts(_spiral, starts, _square, GOAL, np.random.default_rng(1),
                     protocol=EulerProtocol(dt=0.01, steps=500), max_cuts=10)
    assert out.curve[0] < 1.0 and out.converged and out.cuts
    assert not out.final.left.any()
    assert inside_cuts(starts, out.cuts, tol=1e-9).all()


def test_cut_for_failure_falls_back_to_the_papers_constraints() -> None:
    res = rollout(_spiral, np.array([[1.0, 9.0]]), _square, GOAL, steps=500)
    (f,) = failures(res)
    beyond = f.outside + 5.0 * (f.outside - f.last_inside)  # cannot stay inside any cut
    attempt = cut_for_failure(f, GOAL, keep_inside=beyond[None, :])
    assert attempt.cut is not None and attempt.fallback
    assert cut_for_failure(f, GOAL).fallback is False


# ------------------------------------------------------------------------------- add_cut

def test_add_cut_returns_a_new_model_shared_by_the_modes_ds(tmp_path: Path) -> None:
    model = _model(tmp_path)
    cut = Cut(normal=np.array([0.0, -1.0]), point=np.array([0.0, -1.0]))
    new = model.add_cut("a->b", cut)
    assert [len(new.modes[k].cuts) for k in ("a->b", "a->c", "b")] == [1, 1, 0]
    assert all(len(m.cuts) == 0 for m in model.modes.values())  # the old model is unchanged
    assert new.region_cuts("a") == (cut,)
    assert len(new.add_cut("a", Cut(normal=np.array([-1.0, 0.0]),
                                    point=np.array([-1.0, 0.0]))).region_cuts("a")) == 2


def test_add_cut_validates(tmp_path: Path) -> None:
    model = _model(tmp_path)
    with pytest.raises(ModelError, match="dimension 3"):
        model.add_cut("a", Cut(normal=np.array([0.0, 0.0, 1.0]), point=np.zeros(3)))
    # x* of a->c, (0, 3), lies beyond this plane although a->b's x* is inside
    with pytest.raises(ModelError, match="'a->c' on or outside"):
        model.add_cut("a", Cut(normal=np.array([0.0, 1.0]), point=np.array([0.0, 1.0])))
    # the plane holds x* of a->b: not strictly inside
    with pytest.raises(ModelError, match="strictly inside"):
        model.add_cut("a", Cut(normal=np.array([1.0, 0.0]), point=np.array([3.0, 7.0])))
    with pytest.raises(ModelError, match="no DS or mode 'z'"):
        model.add_cut("z", Cut(normal=np.array([1.0, 0.0]), point=np.array([5.0, 0.0])))
    forged = Cut(normal=np.array([1.0, 0.0]), point=np.array([5.0, 0.0]))
    object.__setattr__(forged, "normal", np.array([2.0, 0.0]))  # bypasses Cut's own check
    with pytest.raises(ModelError, match="unit vector"):
        model.add_cut("a", forged)
    with pytest.raises(ModelError, match="must be a Cut"):
        model.add_cut("a", {"normal": [1.0, 0.0], "point": [5.0, 0.0]})  # type: ignore[arg-type]


@given(angle=st.floats(0.0, 2 * np.pi), depth=st.floats(0.1, 5.0))
def test_add_cut_accepts_any_plane_with_x_star_inside(angle: float, depth: float) -> None:
    model = model_from_dict(_doc())
    w = np.array([np.cos(angle), np.sin(angle)])
    x_star = model.modes["b"].ds.attractor
    new = model.add_cut("b", Cut(normal=w, point=x_star + depth * w))
    assert inside_cuts(x_star[None, :], new.modes["b"].cuts).all()
    X = x_star + np.random.default_rng(0).normal(size=(5, 2))
    np.testing.assert_allclose(
        new.velocity(X, "b", dt=0.01),
        modulate(X, new.modes["b"].ds.velocity(X), new.modes["b"].cuts, x_star,
                 lyapunov=new.modes["b"].ds.P, dt=0.01), rtol=1e-12, atol=1e-12)


def test_modulator_built_once_per_cut_set(tmp_path: Path) -> None:
    model = _model(tmp_path).add_cut("b", Cut(normal=np.array([1.0, 0.0]),
                                              point=np.array([9.5, 0.0])))
    mm = model.modes["b"]
    built = mm.modulator
    assert built is not None and _model(tmp_path).modes["b"].modulator is None
    x = np.array([9.4, 1.0])
    v1 = model.velocity(x, "b", dt=0.01)
    v2 = model.velocity(x[None, :], "b", dt=0.01)[0]
    assert mm.modulator is built  # the same object after calls
    ref = modulate(x[None, :], mm.ds.velocity(x[None, :]), mm.cuts, mm.ds.attractor,
                   lyapunov=mm.ds.P, dt=0.01)[0]
    np.testing.assert_allclose(v1, ref, rtol=1e-12)
    np.testing.assert_array_equal(v1, v2)
    assert mm.ds.velocity(x)[0] > 0 and v1[0] <= 0.1 / 0.01 + 1e-9  # no step past the cut


# ------------------------------------------------------------------------------- pickling

def test_models_pickle_and_agree(repo: Path, tmp_path: Path) -> None:
    shipped = load_model(repo / "models" / "scoop.model.json")
    key = next(iter(shipped.modes))
    x_star = shipped.modes[key].ds.attractor
    cut = Cut(normal=np.array([1.0, 0.0]), point=x_star + np.array([0.5, 0.0]))
    for model in (shipped, shipped.add_cut(key, cut), _model(tmp_path)):
        again = pickle.loads(pickle.dumps(model))
        assert again.path == model.path and set(again.modes) == set(model.modes)
        assert type(again.modes).__name__ == "mappingproxy"
        X = np.random.default_rng(1).normal(size=(9, model.dim)) * 3
        for k, mm in model.modes.items():
            np.testing.assert_array_equal(again.velocity(X, k, dt=0.001),
                                          model.velocity(X, k, dt=0.001))
            assert len(again.modes[k].cuts) == len(mm.cuts)
            if mm.fit is not None:
                assert dict(again.modes[k].fit or {}) == dict(mm.fit)


# ------------------------------------------------------------------------------- saving

def test_save_certified_writes_nothing_for_a_model_that_does_not_certify(
        tmp_path: Path) -> None:
    # (I + dt A)^T (I + dt A) < I fails at dt = 1/2 for this fast spiral
    model = _model(tmp_path, A=[[-1.0, -5.0], [5.0, -1.0]])
    out, cert = tmp_path / "out" / "m.model.json", tmp_path / "out" / "m.cert.json"
    with pytest.raises(CertificateError):
        save_certified(model, out, cert, dt="1/2")
    assert not out.exists() and not cert.exists()
    assert not [p for p in (tmp_path / "out").iterdir()]  # no temporary file left
    cut = Cut(normal=np.array([1.0, 0.0]), point=np.array([9.5, 9.0]))
    save_certified(model.add_cut("b", cut), out, cert, dt="1/100")
    assert check_certificate(cert).ok
    assert len(load_model(out).modes["b"].cuts) == 1
