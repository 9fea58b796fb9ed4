"""The MuJoCo Franka loop: Panda model files, torque-actuated robot, controller.

Submodules (import them directly; ``mujoco`` is imported only by :mod:`~tli_verify.sim.robot`
and :mod:`~tli_verify.sim.controller`, so this package imports without the ``sim`` extra):

- :mod:`tli_verify.sim.assets`: fetch and verify the Menagerie Panda files (pinned sha256).
- :mod:`tli_verify.sim.robot`: the Panda with torque motors, gravity/Coriolis compensation,
  frames and forward kinematics.
- :mod:`tli_verify.sim.controller`: Cartesian impedance (operational-space) pose control with
  null-space posture control; the DS state map of the full pose (position + rotation vector).
"""

from __future__ import annotations

__all__ = ["TRIAL_DURATION"]

TRIAL_DURATION = 40.0
"""Default step budget of a Franka trial (simulated seconds): room for two re-scoops after
spills (one scoop-carry-pour cycle takes about 10 s; with 20 s most spilled trials ran out of
time). Here, not in :mod:`~tli_verify.sim.loop`, so the CLI reads it without importing
MuJoCo (its OpenGL backend is chosen before that import)."""
