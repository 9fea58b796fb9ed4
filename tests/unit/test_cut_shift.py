"""A failure appendix E.3's QCQP cannot cut: the plane moves along the exit step.

Found by a bisimulation campaign on the scoop world (LTL-DS, step 276 of
``tests/regressions/scoop_ltlds_cut_failed.json``): mode b's run dipped below the chord from its
entry state to x* and left the soup above it, so every plane through the last in-mode state that
keeps x^0 and x* inside also keeps the failure state inside. Without a cut the exit could repeat.
"""

from __future__ import annotations

import numpy as np
import pytest

from tli_verify.boundary.cuts import InvarianceFailure, solve_cut
from tli_verify.errors import SolverError
from tli_verify.runtime.online import SHIFTS, cut_for_failure

X_STAR = np.array([2.41060086, -4.19304486])
FAILURE = InvarianceFailure(entry=np.array([0.40279119, -4.00669014]),
                            last_inside=np.array([0.61696836, -4.03339898]),
                            outside=np.array([0.63704256, -3.99484148]))


def _side(cut, x):  # > 0 outside the cut
    return float(cut.normal @ (np.asarray(x) - cut.point))


def test_appendix_f_has_no_plane_through_the_last_state() -> None:
    with pytest.raises(SolverError):
        solve_cut(FAILURE, X_STAR)


def test_shifted_plane_separates_and_keeps_everything_inside() -> None:
    attempt = cut_for_failure(FAILURE, X_STAR, keep_inside=FAILURE.entry[None, :])
    cut = attempt.cut
    assert cut is not None and attempt.shift in SHIFTS and attempt.fallback
    assert _side(cut, FAILURE.outside) > 0
    for kept in (FAILURE.last_inside, FAILURE.entry):
        assert _side(cut, kept) < 0
    assert _side(cut, X_STAR) < 0  # strictly inside: Model.add_cut accepts it
    step = FAILURE.outside - FAILURE.last_inside
    assert np.allclose(cut.point, FAILURE.last_inside + attempt.shift * step)


def test_plain_failures_keep_the_plane_through_the_last_state() -> None:
    easy = InvarianceFailure(entry=np.array([0.0, -6.0]), last_inside=np.array([0.6, -4.02]),
                             outside=np.array([0.62, -3.98]))
    attempt = cut_for_failure(easy, X_STAR)
    assert attempt.cut is not None and attempt.shift == 0.0
    assert np.allclose(attempt.cut.point, easy.last_inside)
