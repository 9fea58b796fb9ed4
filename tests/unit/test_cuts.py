"""The cut QCQP (paper appendix F): feasibility, global optimality, errors, the Cut type."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from tli_verify.boundary.cuts import (
    Cut,
    InvarianceFailure,
    cut_offsets,
    inside_cuts,
    solve_cut,
    solve_cut_detailed,
)
from tli_verify.errors import ModelError, SolverError

MARGIN = 1e-3


def _sphere(n: int, count: int, rng: np.random.Generator) -> np.ndarray:
    if n == 2:
        t = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
        return np.column_stack([np.cos(t), np.sin(t)])
    W = rng.standard_normal((count, n))
    return W / np.linalg.norm(W, axis=1, keepdims=True)


def _brute_force(x_star, x0, xl, xf, prev, n, rng, count):
    """Best objective over a dense sample of admissible unit normals (None if none found)."""
    W = _sphere(n, count, rng)
    C = np.array([x_star - xl, x0 - xl, *[p - xl for p in prev]])
    s = xf - xl
    ok = np.all(W @ C.T <= 0.0, axis=1) & (W @ (s / np.linalg.norm(s)) >= MARGIN)
    if not ok.any():
        return None
    return float(np.min(np.abs(W[ok] @ (x_star - xl))))


def _check_constraints(sol, x_star, x0, xl, xf, prev):
    w = sol.cut.normal
    assert abs(np.linalg.norm(w) - 1.0) < 1e-12
    np.testing.assert_array_equal(sol.cut.point, xl)
    for q in [x_star, x0, *prev]:
        assert w @ (q - xl) <= 1e-9 * (1 + np.linalg.norm(q - xl))
    s = xf - xl
    assert w @ s > 0
    assert w @ s >= MARGIN * np.linalg.norm(s) - 1e-12
    assert sol.distance == pytest.approx(abs(w @ (x_star - xl)), abs=1e-9)


@pytest.mark.parametrize("n", [2, 3])
def test_cut_is_feasible_and_globally_optimal(n: int) -> None:
    """Against a dense sample of the sphere: no admissible normal beats the solver's."""
    rng = np.random.default_rng(10 + n)
    solved = 0
    for _ in range(40):
        x_star, x0, xl = rng.standard_normal((3, n))
        xf = xl + 0.3 * rng.standard_normal(n)
        prev = list(rng.standard_normal((int(rng.integers(0, 4)), n)))
        count = 60_000 if n == 2 else 120_000
        best = _brute_force(x_star, x0, xl, xf, prev, n, rng, count)
        try:
            sol = solve_cut_detailed(InvarianceFailure(x0, xl, xf), x_star, previous=prev,
                                     margin=MARGIN)
        except SolverError:
            assert best is None, "solver found no cut but a sampled normal is admissible"
            continue
        solved += 1
        _check_constraints(sol, x_star, x0, xl, xf, prev)
        if best is not None:
            assert sol.distance <= best + 1e-9
        if sol.through_attractor:
            assert sol.distance == 0.0
    assert solved >= 15


def test_cut_through_attractor_when_possible() -> None:
    """Optimum 0: the plane holds x* and separates the failure as much as possible."""
    x_star = np.array([0.0, -1.0])
    xl = np.zeros(2)
    sol = solve_cut_detailed(InvarianceFailure(np.array([-1.0, -1.0]), xl, np.array([1.0, 0.1])),
                             x_star)
    assert sol.through_attractor
    assert abs(sol.cut.normal @ (x_star - xl)) < 1e-12
    np.testing.assert_allclose(sol.cut.normal, [1.0, 0.0], atol=1e-12)
    assert sol.cut.offset(x_star) == pytest.approx(0.0, abs=1e-12)


def test_cut_margin_binds_in_2d() -> None:
    """When the step direction limits the rotation the margin constraint is active."""
    x_star = np.array([0.0, -1.0])
    xl = np.zeros(2)
    sol = solve_cut_detailed(InvarianceFailure(np.array([-1.0, -1.0]), xl, np.array([-0.1, 1.0])),
                             x_star, margin=MARGIN)
    s_hat = np.array([-0.1, 1.0]) / np.linalg.norm([-0.1, 1.0])
    assert sol.cut.normal @ s_hat == pytest.approx(MARGIN, abs=1e-12)
    assert not sol.through_attractor
    assert sol.distance == pytest.approx(0.1005, abs=1e-3)


def test_earlier_points_and_extra_states_stay_inside() -> None:
    rng = np.random.default_rng(3)
    x_star = np.zeros(2)
    xl = np.array([3.0, 0.0])
    xf = np.array([3.1, 0.05])
    x0 = np.array([-2.0, 1.0])
    prev = [Cut(normal=np.array([0.0, 1.0]), point=np.array([1.0, 2.0]))]
    extra = rng.uniform(-2, 2.5, size=(30, 2))
    sol = solve_cut_detailed(InvarianceFailure(x0, xl, xf), x_star, previous=prev,
                             keep_inside=extra)
    w = sol.cut.normal
    assert np.all((extra - xl) @ w <= 1e-9)
    assert (prev[0].point - xl) @ w <= 1e-9
    assert inside_cuts(extra, [sol.cut]).all()


@pytest.mark.parametrize("n", [3, 4, 5])
def test_higher_dimensions(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(10):
        x_star, x0, xl = rng.standard_normal((3, n))
        xf = xl + 0.2 * rng.standard_normal(n)
        prev = list(rng.standard_normal((3, n)))
        try:
            sol = solve_cut_detailed(InvarianceFailure(x0, xl, xf), x_star, previous=prev)
        except SolverError:
            continue
        _check_constraints(sol, x_star, x0, xl, xf, prev)


def test_no_separating_cut_raises() -> None:
    xl = np.zeros(2)
    xf = np.array([1.0, 0.0])
    # the entry state lies straight beyond the failure: no plane through xl separates them
    with pytest.raises(SolverError, match="no separating cut"):
        solve_cut(InvarianceFailure(np.array([2.0, 0.0]), xl, xf), np.array([-1.0, 0.0]))
    with pytest.raises(SolverError, match="equals the last in-mode state"):
        solve_cut(InvarianceFailure(np.array([2.0, 0.0]), xl, xl), np.array([-1.0, 0.0]))


def test_attractor_at_last_state() -> None:
    xl = np.array([1.0, 1.0])
    sol = solve_cut_detailed(InvarianceFailure(np.zeros(2), xl, np.array([2.0, 1.0])), xl)
    assert sol.through_attractor
    assert sol.cut.normal @ np.array([1.0, 0.0]) > 0


def test_bad_input() -> None:
    f = InvarianceFailure(np.zeros(2), np.ones(2), np.array([2.0, 1.0]))
    with pytest.raises(ModelError):
        solve_cut(f, np.zeros(3))
    with pytest.raises(ModelError):
        solve_cut(f, np.zeros(2), margin=0.0)
    with pytest.raises(ModelError):
        InvarianceFailure(np.zeros(2), np.ones(3), np.zeros(2))
    with pytest.raises(ModelError):
        InvarianceFailure(np.zeros(2), np.array([np.nan, 1.0]), np.zeros(2))
    with pytest.raises(ModelError):
        solve_cut(f, np.zeros(2), previous=[np.zeros(3)])


def test_cut_type_validation_and_json() -> None:
    c = Cut(normal=[0.6, 0.8], point=[1.0, 2.0])
    assert isinstance(c.normal, np.ndarray) and not c.normal.flags.writeable
    assert c.dim == 2
    assert c.offset([0.0, 0.0]) == pytest.approx(0.6 + 1.6)
    back = Cut.from_dict(c.to_dict())
    np.testing.assert_array_equal(back.normal, c.normal)
    np.testing.assert_array_equal(back.point, c.point)
    with pytest.raises(ModelError, match="unit vector"):
        Cut(normal=[1.0, 1.0], point=[0.0, 0.0])
    with pytest.raises(ModelError, match="shape"):
        Cut(normal=[1.0, 0.0], point=[0.0, 0.0, 0.0])
    with pytest.raises(ModelError):
        Cut(normal=[1.0], point=[0.0])
    with pytest.raises(ModelError, match=r"modes\.a\.cuts\[0\]: missing field 'point'"):
        Cut.from_dict({"normal": [1.0, 0.0]}, where="modes.a.cuts[0]")
    with pytest.raises(ModelError, match="list of numbers"):
        Cut.from_dict({"normal": ["x", 0.0], "point": [0.0, 0.0]})
    with pytest.raises(ModelError, match="unknown field"):
        Cut.from_dict({"normal": [1.0, 0.0], "point": [0.0, 0.0], "h": 1})


def test_offsets_and_inside() -> None:
    cuts = [Cut([1.0, 0.0], [1.0, 0.0]), Cut([0.0, 1.0], [0.0, 0.0])]
    np.testing.assert_allclose(cut_offsets(cuts, [0.0, -1.0]), [1.0, 1.0])
    X = np.array([[0.0, -0.5], [2.0, -0.5], [0.0, 0.5], [1.0, 0.0]])
    np.testing.assert_array_equal(inside_cuts(X, cuts), [True, False, False, True])
    np.testing.assert_array_equal(inside_cuts(X, []), [True] * 4)


@settings(max_examples=80)
@given(data=st.data(), n=st.integers(2, 4), k=st.integers(0, 4))
def test_answer_always_rechecks(data: st.DataObject, n: int, k: int) -> None:
    """Any input: either SolverError, or a unit normal meeting every constraint."""
    pts = data.draw(hnp.arrays(np.float64, (4 + k, n), elements=st.floats(-3, 3, width=64)))
    x_star, x0, xl, xf, *prev = pts
    try:
        sol = solve_cut_detailed(InvarianceFailure(x0, xl, xf), x_star, previous=prev)
    except SolverError:
        return
    _check_constraints(sol, x_star, x0, xl, xf, prev)
    assert sol.cut.offset(x_star) >= -1e-9 * (1 + np.linalg.norm(x_star - xl))
