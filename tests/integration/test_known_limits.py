"""Known limits of the policy, found by campaigns and kept in view: each test states what a
correct policy would do and is expected to fail (``xfail(strict=True)``: the day it passes,
the suite says so and the limit is lifted from the docs).

Online cuts alone (no offline hand-off step: paper appendix E.3's cut per invariance failure)
on a flow that slides along a flat face of its mode's region: each failure's cut leaves the
flow a sliver further along the face, and the next step leaves again. Found by the C parity
property test (its artifact's 60-cut storage filled in 3.5 s).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.support.ndtask import DT, NDSensors, write_nd
from tli_verify.runtime.events import CutAdded
from tli_verify.runtime.executive import LTLDSPolicy


@pytest.mark.xfail(strict=True, reason="online cuts chatter along a face the flow slides on: "
                   "64 cuts in 350 steps from 3 pushes (one cut per failure, each a sliver)")
def test_online_cuts_alone_chatter_along_a_face(tmp_path: Path) -> None:
    n = 3
    nd = write_nd(tmp_path, n, K=3, seed=10 + n)
    plan = {}
    for step, size, seed in [(1, 0.25, 180705025), (129, 0.25, 397), (217, 0.125, 439)]:
        d = np.random.default_rng(seed).normal(size=n)
        plan[step] = size * d / np.linalg.norm(d)
    pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=DT)
    sensors = NDSensors(n)
    x = np.r_[0.46875, np.zeros(n - 1)]

    def reading(x: np.ndarray) -> frozenset[str]:
        return frozenset(k for k, v in sensors.read(x).items() if v)

    pol.reset(x, reading(x))
    for t in range(1, 351):
        if t in plan:
            x = x + plan[t]
        v = pol.step(x, reading(x), perturbed=t in plan)
        x = x + DT * np.asarray(v)
    cuts = sum(isinstance(e, CutAdded) for e in pol.events)
    # a policy whose cuts converge: a few per push, not one every other step
    assert cuts <= 4 * len(plan), f"{cuts} cuts in 350 steps from {len(plan)} pushes"
