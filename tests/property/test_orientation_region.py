"""The orientation certificate's claim as a property (issue 35): every start inside the certified
region ``V(xi) < c`` (``c = region_V_below``) lies in the tangent chart ``|xi| < pi``, and the
1 ms controller from it decreases ``V`` at every step and never leaves the chart (a wrap across
the half turn would show as a jump of ``V`` recomputed from the quaternion)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm, sqrtm

from tli_verify.certification.orientation import issue_orientation_certificate
from tli_verify.ds.quaternion import (
    QuaternionDS,
    learn_quaternion_ds,
    quat_exp,
    quat_log,
    write_orientation_model,
)

Q_STAR = np.array([0.5, 0.5, -0.5, 0.5])
A_TRUE = np.array([[-0.9, 0.8, 0.1], [-0.8, -0.9, 0.0], [0.0, 0.3, -1.4]])


@pytest.fixture(scope="module")
def certified(tmp_path_factory: pytest.TempPathFactory) -> tuple[QuaternionDS, Fraction]:
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 8.0, 160)
    times, quats = [], []
    for _ in range(4):
        xi0 = rng.normal(size=3)
        xi0 *= rng.uniform(1.0, 2.5) / np.linalg.norm(xi0)
        times.append(t)
        quats.append(quat_exp(np.array([expm(A_TRUE * s) @ xi0 for s in t]), Q_STAR))
    ds, _ = learn_quaternion_ds(times, quats, Q_STAR, seed=1)
    root = tmp_path_factory.mktemp("region")
    write_orientation_model(ds, root / "o.json")
    doc = issue_orientation_certificate(root / "o.json", root / "o.cert.json")
    return ds, Fraction(doc["exact"]["region_V_below"])


@settings(max_examples=25, deadline=None)
@given(direction=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       depth=st.floats(0.05, 0.999))
def test_starts_in_the_certified_region_stay_in_the_chart_and_converge(
        certified: tuple[QuaternionDS, Fraction], direction: list[float], depth: float) -> None:
    ds, c = certified
    u = np.array(direction)
    if np.linalg.norm(u) < 1e-3:
        u = np.array([1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    # xi0 on the ellipsoid V = depth * c
    xi0 = math.sqrt(depth * float(c)) * np.real(np.linalg.inv(sqrtm(ds.P))) @ u
    assert float(xi0 @ ds.P @ xi0) < float(c)
    assert np.linalg.norm(xi0) < math.pi  # the region lies in the chart
    run = ds.rollout(quat_exp(xi0, ds.attractor), dt=1e-3, steps=3000)
    xi = quat_log(run, ds.attractor)
    assert np.all(np.linalg.norm(xi, axis=1) < math.pi)
    V = np.einsum("ni,ij,nj->n", xi, ds.P, xi)
    assert np.all(np.diff(V) < 0.0)
    assert V[-1] < 0.9 * V[0]
