"""The per-DS decay-rate choice under an accuracy budget:
:func:`tli_verify.ds.lyapunov.choose_rate` and its use by the learner."""

from __future__ import annotations

import inspect
import itertools
import json
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tli_verify.certification.exact import certified_decay_rate, check_lyapunov
from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.ds.lpvds import learn_lpvds
from tli_verify.ds.lyapunov import (
    RATE_BUDGET,
    RATE_FACTOR,
    RATE_GRID,
    RATE_PAD,
    choose_rate,
    data_rate,
    decay_rate,
    fit_a,
    rate_candidates,
    velocity_rmse,
)
from tli_verify.errors import ModelError, SolverError

DT = 1e-3


def _flow(x: np.ndarray) -> np.ndarray:
    """A nonlinear 2-D flow to the origin: a rotation that slows away from it, and contraction
    (its best LPV fits contract slower than the data's own rate, so the budget binds)."""
    r2 = np.sum(x**2, axis=1, keepdims=True)
    rot = np.column_stack([-x[:, 1], x[:, 0]])
    return np.asarray(-0.6 * x + 1.5 * rot / (1 + r2) + 0.2 * x * r2 / (1 + r2))


@pytest.fixture(scope="module")
def small() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """X, dX, gamma (2 soft components), attractor, P = I: 120 samples, cheap fits."""
    rng = np.random.default_rng(0)
    runs = []
    for start in ([2.0, 1.0], [-1.5, 2.0], [0.5, -2.2]):
        x = np.array([start])
        for _ in range(40):
            runs.append(x[0].copy())
            x = x + 0.1 * _flow(x)
    X = np.array(runs)
    V = _flow(X) + 0.01 * rng.normal(size=X.shape)
    w = 1.0 / (1.0 + np.exp(-3.0 * X[:, 0]))
    return X, V, np.column_stack([w, 1.0 - w]), np.zeros(2), np.eye(2)


def _brute_force(data: tuple[np.ndarray, ...]) -> tuple[float, list[tuple[float, float]]]:
    """Reference RMSE and (rate, RMSE) of the learner's fit at every candidate of the grid."""
    X, V, G, xs, P = data
    A0, _ = fit_a(X, V, G, xs, P, eps=1e-3)
    out = []
    for r in rate_candidates(data_rate(X, V, xs)):
        A, _ = fit_a(X, V, G, xs, P, eps=1e-3, rate=r * (1 + RATE_PAD), dt=DT)
        out.append((r, velocity_rmse(X, V, G, xs, A)))
    return velocity_rmse(X, V, G, xs, A0), out


def test_bisection_matches_a_brute_force_over_the_whole_grid(small: tuple[np.ndarray, ...]
                                                             ) -> None:
    X, V, G, xs, P = small
    e0, every = _brute_force(small)
    errors = [e for _, e in every]
    assert len(every) == len(RATE_GRID) == 13
    # the monotonicity the bisection relies on holds here (up to solver accuracy) ...
    assert all(b <= a * (1 + 1e-7) for a, b in itertools.pairwise(errors)), errors
    # ... and the budgets below land at different places of the grid, ends included
    rms = float(np.sqrt(np.mean(np.sum(V**2, axis=1))))
    chosen = set()
    for budget in (0.0, 0.03, 0.5):
        choice = choose_rate(X, V, G, xs, P, eps=1e-3, dt=DT, budget=budget)
        limit = (1 + budget) * e0 + 1e-6 * rms
        inside = [j for j, e in enumerate(errors) if e <= limit]
        assert inside, budget  # the smallest rate costs < 1e-6 rms here: always within
        j = min(inside)  # the largest rate within budget
        assert choice.rate == every[j][0], (budget, choice.tried)
        assert choice.within_budget
        assert choice.rmse <= limit and choice.rmse == pytest.approx(every[j][1], rel=1e-6)
        assert j == 0 or errors[j - 1] > limit  # the next larger grid rate is outside
        assert choice.reference_rmse == pytest.approx(e0, rel=1e-9)
        assert len(choice.tried) <= 4  # ceil(log2(13 + 1)) candidate solves
        assert choice.budget == budget and choice.data_rate == data_rate(X, V, xs)
        chosen.add(j)
        # the fit kept is the one at the chosen rate: it contracts at least that fast
        assert decay_rate(P, choice.A) >= choice.rate
    assert 0 in chosen and len(chosen) == 3, chosen


def test_the_result_is_locally_maximal_even_when_the_errors_are_not_monotone(
        small: tuple[np.ndarray, ...], monkeypatch: pytest.MonkeyPatch) -> None:
    """Whatever the RMSE profile, the choice is within budget and its next larger candidate
    was solved and is not (the bisection's invariant, without the monotonicity)."""
    import tli_verify.ds.lyapunov as lyap

    X, V, G, xs, P = small
    rates = rate_candidates(data_rate(X, V, xs))
    real = lyap.velocity_rmse
    e0 = real(X, V, G, xs, fit_a(X, V, G, xs, P, eps=1e-3)[0])
    # a made-up, non-monotone profile: within, outside, within, ... by candidate index
    profile = {r: (0.0 if j % 3 == 2 else 1.0) for j, r in enumerate(rates)}
    calls: list[float] = []

    def fake_fit_a(*args: Any, **kw: Any) -> Any:
        calls.append(float(kw.get("rate", 0.0)))
        return fit_a(*args, **kw)

    def fake_rmse(*args: Any) -> float:
        r = calls[-1] / (1 + RATE_PAD)
        if calls[-1] == 0.0:
            return e0
        match = min(rates, key=lambda c: abs(c - r))
        return e0 * (1 + profile[match])

    monkeypatch.setattr(lyap, "fit_a", fake_fit_a)
    monkeypatch.setattr(lyap, "velocity_rmse", fake_rmse)
    choice = choose_rate(X, V, G, xs, P, eps=1e-3, dt=DT, budget=0.03)
    j = rates.index(choice.rate)
    assert choice.within_budget and profile[choice.rate] == 0.0
    assert j > 0 and (rates[j - 1], e0 * 2) in choice.tried  # solved, and outside


def test_budget_zero_keeps_only_what_the_fit_does_not_feel() -> None:
    # an exact, fast-contracting linear system: small rates cost nothing (up to solver noise)
    A_true = np.array([[-2.0, 1.0], [-1.0, -2.0]])
    t = np.linspace(0.0, 2.0, 30)
    X = np.concatenate([np.array([np.exp(-2 * ti) * np.array([[np.cos(ti), np.sin(ti)],
                                                               [-np.sin(ti), np.cos(ti)]]) @ s
                                  for ti in t]) for s in ([1.0, 0.5], [-0.5, 1.0])])
    V = X @ A_true.T
    G = np.ones((len(X), 1))
    choice = choose_rate(X, V, G, np.zeros(2), np.eye(2), eps=1e-3, dt=DT, budget=0.0)
    assert choice.within_budget and choice.rate > 0
    assert choice.reference_rmse < 1e-5 and choice.rmse < 1e-5
    # the true A contracts P = I at rate 2: every candidate up to the data's rate is free
    assert choice.rate == rate_candidates(data_rate(X, V, np.zeros(2)))[0]


def test_budget_zero_on_a_rotation_keeps_the_smallest_rate_and_says_so() -> None:
    # a pure rotation does not contract: every positive rate costs accuracy
    t = np.linspace(0.0, 6.0, 60)
    X = 2.0 * np.column_stack([np.cos(t), np.sin(t)])
    V = np.column_stack([-X[:, 1], X[:, 0]])
    G = np.ones((len(X), 1))
    choice = choose_rate(X, V, G, np.zeros(2), np.eye(2), eps=1e-3, dt=DT, budget=0.0)
    rates = rate_candidates(data_rate(X, V, np.zeros(2)))
    assert not choice.within_budget
    assert choice.rate == rates[-1] > 0  # the learner keeps a positive certified rate
    assert choice.rmse > choice.reference_rmse
    assert decay_rate(np.eye(2), choice.A) >= choice.rate


@pytest.mark.parametrize("case", ["still", "on the attractor"])
def test_data_that_do_not_move_choose_rate_zero(case: str) -> None:
    rng = np.random.default_rng(1)
    if case == "still":
        X, V = rng.normal(size=(40, 2)), np.zeros((40, 2))
    else:
        X, V = np.zeros((20, 2)), rng.normal(size=(20, 2))
    assert data_rate(X, V, np.zeros(2)) == 0.0 and rate_candidates(0.0) == ()
    choice = choose_rate(X, V, np.ones((len(X), 1)), np.zeros(2), np.eye(2), dt=DT)
    assert choice.rate == 0.0 and choice.tried == () and choice.within_budget
    assert choice.rmse == choice.reference_rmse
    assert check_lyapunov(np.eye(2), choice.A).ok  # the plain eps margin still holds


def test_still_data_learn_a_rate_zero_model() -> None:
    """The whole learner on demonstrations that do not move: the margin-only DS, recorded as a
    choice of rate 0 without a control period (fit_a's objective scale used to make Clarabel
    report 'infeasible' on them)."""
    X = np.random.default_rng(2).normal(size=(40, 2))
    ds, info = learn_lpvds(X, np.zeros_like(X), np.zeros(2), seed=0, rate_budget=RATE_BUDGET)
    assert info.rate == 0.0 and info.control_dt is None and info.data_rate == 0.0
    assert info.rate_within_budget is True and info.status == "optimal"
    assert check_lyapunov(ds.P, ds.A).ok


def test_rate_candidates_round_down_to_three_digits() -> None:
    for rate in (1.0, 0.7874960075113568, 1000.0, 999.95, 1e-7, 3.3333333333333335e5):
        cands = rate_candidates(rate)
        assert list(cands) == sorted(set(cands), reverse=True)
        assert len(cands) == len(RATE_GRID)
        for f, c in zip(RATE_GRID, cands, strict=True):
            exact = Fraction(repr(c))  # the decimal the model file records
            assert exact <= Fraction(f * rate)
            assert len(str(exact.numerator).rstrip("0")) <= 3, (rate, c)
            assert Fraction(f * rate) - exact < Fraction(f * rate) * Fraction(1, 99)
    assert rate_candidates(1.0)[0] == 1.0 and rate_candidates(1000.0)[0] == 1000.0
    assert rate_candidates(0.7874960075113568)[:3] == (0.787, 0.556, 0.393)


def test_the_certificate_states_at_least_the_chosen_rate_even_with_a_tiny_eps(
        small: tuple[np.ndarray, ...]) -> None:
    """The certificate rounds the fit's best rate times (1 - 1e-5) down to 4 digits; the pad
    keeps that >= the recorded 3-digit rate when eps is too small to (here eps = 1e-6: without
    the pad the certificate would state 1 unit of the 4th digit less)."""
    X, V, G, xs, P = small
    for eps in (1e-3, 1e-6):
        choice = choose_rate(X, V, G, xs, P, eps=eps, dt=DT, budget=0.5)
        assert choice.rate == rate_candidates(data_rate(X, V, xs))[0]
        assert certified_decay_rate(P, choice.A) >= Fraction(repr(choice.rate)), eps


def test_bad_budgets_and_margins_are_refused(small: tuple[np.ndarray, ...]) -> None:
    X, V, G, xs, P = small
    for budget in (-0.01, float("nan"), float("inf")):
        with pytest.raises(SolverError, match="rate budget must be a finite number >= 0"):
            choose_rate(X, V, G, xs, P, budget=budget)
        with pytest.raises(ModelError, match="rate budget must be finite and >= 0"):
            learn_lpvds(X, V, xs, rate_budget=budget)
    with pytest.raises(SolverError, match="needs a positive margin eps"):
        choose_rate(X, V, G, xs, P, eps=0.0)
    with pytest.raises(ModelError, match="the rate choice needs eps > 0"):
        learn_lpvds(X, V, xs, eps=0.0, rate_budget=0.03)
    # a forced rate does not need the reference fit: eps = 0 with a rate is the plain program
    _, info = learn_lpvds(X, V, xs, eps=0.0, rate=0.1, rate_budget=0.03)
    assert info.rate == 0.1 and info.rate_budget is None


def test_a_forced_rate_wins_over_the_budget(small: tuple[np.ndarray, ...]) -> None:
    X, V, _, xs, _ = small
    ds, info = learn_lpvds(X, V, xs, seed=0, rate=0.05, rate_budget=0.03)
    assert info.rate == 0.05 and info.control_dt == DEFAULT_DT_FLOAT
    assert info.rate_budget is info.reference_rmse is info.rate_rmse is info.data_rate is None
    assert info.rate_within_budget is None
    assert decay_rate(ds.P, ds.A) >= 0.05
    # without either, learn_lpvds keeps the fixed factor (learn_model and `tli learn` choose)
    _, fixed = learn_lpvds(X, V, xs, seed=0)
    assert fixed.rate == pytest.approx(RATE_FACTOR * data_rate(X, V, xs)) and not fixed.rate_budget


def _write_demo(path: Path, starts: list[list[float]]) -> list[Path]:
    out = []
    t = np.linspace(0.0, 3.0, 31)
    for i, s in enumerate(starts):
        x = np.array([s])
        rows = []
        for ti in t:
            rows.append(f"{ti:.2f},{x[0, 0]:.6f},{x[0, 1]:.6f}")
            x = x + 0.1 * _flow(x)
        p = path / f"flow_{i + 1}.csv"
        p.write_text("t,x0,x1\n" + "\n".join(rows) + "\n")
        out.append(p)
    return out


def test_the_model_records_the_choice(tmp_path: Path) -> None:
    from tli_verify.model.learn import learn_model
    from tli_verify.model.serialize import load_model, save_model

    assert inspect.signature(learn_model).parameters["rate_budget"].default == RATE_BUDGET
    demos = _write_demo(tmp_path, [[2.0, 1.0], [-1.5, 2.0]])
    out = tmp_path / "flow.model.json"
    model = learn_model(demos, out_path=out, seed=0, control_dt=DT)
    (key, mm), = model.modes.items()
    fit = dict(mm.fit or {})
    assert fit["rate_budget"] == RATE_BUDGET and fit["rate_within_budget"] is True
    assert fit["rate"] in rate_candidates(fit["data_rate"]) and fit["control_dt"] == DT
    assert fit["rate_rmse"] <= (1 + RATE_BUDGET) * fit["rate_reference_rmse"] * (1 + 1e-6)
    assert decay_rate(mm.ds.P, mm.ds.A) >= fit["rate"]
    save_model(model, out)  # the schema accepts the new keys, and they read back
    doc = json.loads(out.read_text())
    assert doc["modes"][key]["fit"]["rate_within_budget"] is True
    assert dict(load_model(out).modes[key].fit or {}) == fit
    # the fixed factor (rate_budget=None) and a forced rate record no choice
    for options in ({"rate_budget": None}, {"rate": 0.0}):
        other = learn_model(demos, out_path=tmp_path / "o.model.json", seed=0, **options)
        ofit = dict(next(iter(other.modes.values())).fit or {})
        assert not {"rate_budget", "rate_within_budget", "data_rate"} & set(ofit), options
