"""The stall rule on a task no shipped file has: the 3-D ``tli init`` reach template, written,
learned and certified by the test. A DS converged in b without b's reading re-enters b from a
(its predecessor: a -> b and b -> a are both transitions); a perturbation reported during
the re-entry does not end it; a's DS converging brings the executive back to b."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import tli_verify as tli
from tli_verify.runtime.events import Reentered, Stall
from tli_verify.runtime.stall import StallRule
from tli_verify.tasks.scaffold import scaffold


def _policy(root: Path) -> tli.LTLDSPolicy:
    for rel, (_, text) in scaffold("reach", 3).items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    spec = root / "specs" / "reach.toml"
    task = tli.load_task(root / "tasks" / "reach.toml")
    out = root / "models" / "reach.model.json"
    tli.learn(task.demonstrate(seed=0, n_demos=2), spec=spec, out=out, handoff=False)
    cert = tli.certify(out, out=root / "certificates" / "reach.cert.json")
    policy = tli.make_policy(spec, out, cert)
    policy.stall_rule = StallRule(radius=0.1, dwell=0.2)  # the task spans 0.8
    return policy


def test_the_stall_rule_reenters_from_the_predecessor_through_perturbations(
        tmp_path: Path) -> None:
    policy = _policy(tmp_path)
    modes = policy.model.modes
    a = next(k for k, m in modes.items() if m.mode == "a")
    b = next(k for k, m in modes.items() if m.mode == "b")
    xa, xb = modes[a].ds.attractor, modes[b].ds.attractor.copy()
    policy.reset(xa, {})
    policy.step(xa, {"z"})
    assert policy.mode == "b"
    for _ in range(round(0.2 / policy.dt)):  # at b's attractor, b's reading: converged
        policy.step(xb, {"z"})
    (stall,) = [e for e in policy.events if isinstance(e, Stall)]
    assert (stall.mode, stall.via, policy.mode) == ("b", "a", "a")
    away = xb + 0.25 * (xa - xb)  # on the way back, not converged to a's attractor
    for _ in range(5):  # pressed against something, read as a push: the re-entry goes on
        v = policy.step(away, {"z"}, perturbed=True)
        assert policy.mode == "a"
        np.testing.assert_allclose(v, modes[a].velocity(away, dt=policy.dt))
    assert not any(isinstance(e, Reentered) for e in policy.events)
    policy.step(xa, {"z"})  # a's DS converged: back to b, whose automaton state was kept
    (back,) = [e for e in policy.events if isinstance(e, Reentered)]
    assert back.converged and policy.mode == "b"
    policy.step(xa, {"g"})
    assert policy.mode == "c"
