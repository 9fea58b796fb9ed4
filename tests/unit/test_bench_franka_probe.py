"""The scene benchmark's baseline (benchmarks/bench_franka_scene.py): the physics steps taken
after a rig's construction are recorded, none of the construction's, and replaying bare
``mj_step`` from the recorded states reproduces the closed loop's trajectory exactly -- the
"same physical situation" the closed loop is compared with."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sim
mujoco = pytest.importorskip("mujoco")


def test_probe_records_the_loop_and_the_replay_reproduces_it() -> None:
    from benchmarks.bench_franka_scene import Probe, _replay, probed
    from tli_verify.sim.demos import MocapRig
    from tli_verify.sim.scene import PhysicsOptions

    originals = (mujoco.mj_step, mujoco.mj_step1, mujoco.mj_step2, MocapRig.__init__)
    probe = Probe(record=True, timing=True)
    with probed(probe):
        # awake: replaying a sleeping scene is not its physics (mj_setState wakes every body)
        rig = MocapRig(3, physics=PhysicsOptions(sleep=False))  # settling is not recorded
        assert probe.states is None and probe.build_cpu > 0.0
        rig.command(rig.pose() + np.array([0.0, -0.02, -0.02, 0.0, 0.2, 0.0]))
        rig.step(40)
        rig.push[:] = (5.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # an applied wrench is part of the state
        rig.step(20)
    assert (mujoco.mj_step, mujoco.mj_step1, mujoco.mj_step2, MocapRig.__init__) == originals
    assert probe.states is not None and len(probe.states) == 60
    assert probe.calls == 60 and probe.in_step > 0.0
    rate, worst = _replay(probe.model, probe.states, repeats=1)
    assert worst == 0.0 and rate > 0.0
    # a replay from states that are not the trial's is caught
    states = list(probe.states)
    states[30] = (states[30][0] + 1e-6, 1)
    assert _replay(probe.model, states, repeats=1)[1] > 0.0
