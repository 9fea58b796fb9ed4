"""The scene's solver settings (:class:`PhysicsOptions`), without loading the simulator.

The scene (:mod:`tli_verify.sim.scene`) applies them; the physical campaign's evidence records
the default it ran with (``physics.scene``) and the gate compares it with the current default
(:mod:`tli_verify.sim.physics_checks`, which loads no simulator).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from tli_verify.errors import TliError

__all__ = ["DEFAULT_PHYSICS", "SOLVERS", "PhysicsOptions"]


SOLVERS = ("newton", "cg")
"""The constraint solvers :class:`PhysicsOptions` may pick (MuJoCo's Newton and CG)."""


@dataclass(frozen=True, slots=True)
class PhysicsOptions:
    """The solver settings of the scene that trade speed against fidelity.

    The default is the measured setting every trial and piece of evidence uses (module doc).
    The others exist to be measured (``benchmarks/bench_franka_scene.py``: speed, and whether the
    30 evidence trials keep their outcomes) before one becomes a default. Island sleeping became
    the default on 2026-12-04: it kept every outcome of the 30 evidence trials and ran the Panda
    at 6.8x real time against 3.9x awake (nominal trial), 7.7x against 3.3x (10 perturbed
    trials). The demonstrations were recorded awake; ``sleep=False`` is the awake scene (the
    benchmark's bare-replay baseline: ``mj_setState`` wakes every body).

    Attributes
    ----------
    sleep : bool
        MuJoCo's island sleeping (``mjENBL_SLEEP``): bodies at rest (the beads in the soup
        bowl) leave the constraint solver until something touches them (default on).
    sleep_tolerance : float
        Velocity below which a body may sleep (MuJoCo ``sleep_tolerance``).
    solver : str
        ``"newton"`` (default) or ``"cg"``.
    impratio : float
        Frictional-to-normal impedance ratio of the elliptic cones (10: beads grip the tray).
    """

    sleep: bool = True
    sleep_tolerance: float = 0.01
    solver: str = "newton"
    impratio: float = 10.0

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise TliError(f"physics: solver {self.solver!r}: one of {', '.join(SOLVERS)}")
        if not (math.isfinite(self.sleep_tolerance) and math.isfinite(self.impratio)
                and self.sleep_tolerance > 0 and self.impratio >= 1):
            raise TliError(f"physics: need sleep_tolerance > 0 and impratio >= 1, got "
                           f"{self.sleep_tolerance}, {self.impratio}")

    def to_dict(self) -> dict[str, Any]:
        """The JSON record (the evidence's ``physics.scene``)."""
        return {"sleep": bool(self.sleep), "sleep_tolerance": float(self.sleep_tolerance),
                "solver": str(self.solver), "impratio": float(self.impratio)}


DEFAULT_PHYSICS = PhysicsOptions()
"""The scene's measured settings."""
