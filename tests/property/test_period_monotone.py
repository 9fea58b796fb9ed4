"""A certificate at a control period covers every faster loop (tli_verify.project.period).

``(I + s A)^T P (I + s A) - P = s (M + s N)`` with ``M = A^T P + P A``, ``N = A^T P A >= 0``:
negative definite at ``dt`` implies negative definite at every ``0 < s <= dt``. Checked with
the exact decision procedure on random systems, with the period drawn at the edge: the largest
of a grid that certifies, and every smaller one of the grid.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.certification.exact import check_lyapunov

PERIODS = [Fraction(1, d) for d in (2, 3, 5, 8, 13, 21, 34, 55, 89, 144)]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), k=st.integers(1, 3))
def test_a_certificate_at_dt_covers_every_shorter_period(seed: int, n: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(n, n))
    P = L @ L.T + 0.5 * np.eye(n)
    A = []
    for _ in range(k):  # A = -(P^-1)(S + c I) + P^-1 W, W skew: A^T P + P A < 0
        S = rng.normal(size=(n, n))
        W = rng.normal(size=(n, n))
        A.append(np.linalg.solve(P, -(S @ S.T + rng.uniform(0.5, 20) * np.eye(n))
                                 + 3 * (W - W.T)))
    A_arr = np.array(A)
    assert check_lyapunov(P, A_arr).ok  # continuous time holds by construction
    verdicts = [check_lyapunov(P, A_arr, dt=dt).ok for dt in PERIODS]  # longest first
    first = next((i for i, ok in enumerate(verdicts) if ok), None)
    if first is not None:
        assert all(verdicts[first:]), verdicts


def test_the_grid_separates_periods() -> None:
    """The grid is fine enough to matter: A = -50 I certifies exactly below 1/25 s."""
    verdicts = [check_lyapunov(np.eye(2), np.array([-50 * np.eye(2)]), dt=dt).ok
                for dt in PERIODS]
    assert verdicts == [dt < Fraction(1, 25) for dt in PERIODS]
