"""The settings of a physical campaign of the Franka policy (:class:`PhysicsConfig`).

A campaign is seeded perturbed trials: the robot (:data:`ROBOTS`), the policy variant, the step
budget, the pushes and tilts per trial, and the project whose model and certificate the policy
runs behind. The settings are validated when the configuration is made, and
:meth:`PhysicsConfig.settings` gives the ones a re-run needs besides seed and trials.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (30 perturbed trials on the Panda).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tli_verify.errors import CampaignError, TliError
from tli_verify.sim import TRIAL_DURATION
from tli_verify.sim.franka_files import MODEL_NAME
from tli_verify.sim.franka_project import VARIANTS
from tli_verify.sim.loop import ROBOTS, SENSOR_KINDS

__all__ = [
    "BACKENDS",
    "MAX_WORKERS",
    "ROBOTS",
    "PhysicsConfig",
]

BACKENDS = ("serial", "process", "dask")
"""Where a physical campaign's chunks run (:func:`tli_verify.verify.backends.make_backend`)."""

MAX_WORKERS = 256
"""Most chunks (workers) of a physical campaign, as for the 2-D campaigns."""


@dataclass(frozen=True, slots=True)
class PhysicsConfig:
    """A physical campaign: seeded perturbed trials of the Franka policy.

    Attributes
    ----------
    root : str
        The project (``specs/``, ``models/franka-scoop.model.json``,
        ``certificates/franka-scoop.cert.json``).
    seed : int
        Seed of the first trial; trial ``k`` has seed ``seed + k`` (bead placement and
        :func:`~tli_verify.sim.perturbations.draw`).
    trials : int
    robot : str
        ``"panda"`` or ``"free-tool"`` (:func:`tli_verify.sim.loop.run_trial`).
    variant : str
        ``"LTL-DS"`` (the deployed policy) or an ablation.
    duration : float
        Step budget per trial, simulated seconds.
    pushes, tilts : int
        Perturbations per trial (:func:`~tli_verify.sim.perturbations.draw`).
    retry : bool
        The stall rule on (:mod:`tli_verify.runtime.stall`).
    sensors : str
        ``"franka"`` (default: the robot's own) or ``"ideal"``
        (:mod:`tli_verify.sim.franka_sensors`).
    controller : str
        ``"measured"`` (default: the paper's, the DS at the measured pose integrated to the
        impedance law's target), ``"passive"`` (the Panda only, :mod:`tli_verify.sim.passive`)
        or ``"tracking"`` (the DS on its own target) (:func:`tli_verify.sim.loop.run_trial`).
    certificates : str or None
        The directory of ``franka-scoop.cert.json`` (default ``<root>/certificates``: where the
        gate looks; ``tli sim franka --certificates DIR`` runs with ``root`` = DIR's parent).
    workers : int
        The trials run in ``workers`` contiguous chunks of seeds, one executive each, whose
        cuts carry over between the trials of its chunk
        (:func:`tli_verify.sim.campaign.chunk_seeds`). Default 1: one executive for every
        trial. It changes which cuts a trial inherits, so it is a setting of the campaign,
        recorded in its evidence, not a property of the machine.
    backend : str
        ``"serial"`` (default: in this process, chunk after chunk), ``"process"`` (local
        worker processes) or ``"dask"``: where the chunks run. The results do not depend on it.
    """

    root: str
    seed: int = 0
    trials: int = 30
    robot: str = "panda"
    variant: str = "LTL-DS"
    duration: float = TRIAL_DURATION
    pushes: int = 1
    tilts: int = 1
    certificates: str | None = None
    retry: bool = True
    sensors: str = "franka"
    workers: int = 1
    backend: str = "serial"
    controller: str = "measured"

    def __post_init__(self) -> None:
        if self.robot not in ROBOTS:
            raise TliError(f"robot {self.robot!r}: one of {', '.join(ROBOTS)}"
                           + (" ('hand' is now 'free-tool')" if self.robot == "hand" else ""))
        if self.sensors not in SENSOR_KINDS:
            raise TliError(f"sensors {self.sensors!r}: one of {', '.join(SENSOR_KINDS)}")
        if self.controller not in ("measured", "passive", "tracking"):
            raise TliError(f"controller {self.controller!r}: one of measured, passive, "
                           "tracking")
        if self.robot == "free-tool" and self.controller == "passive":
            raise TliError("controller 'passive' runs on the Panda only (the free tool: "
                           "measured or tracking)")
        if self.variant not in VARIANTS:
            raise TliError(f"variant {self.variant!r}: one of {', '.join(VARIANTS)}")
        if self.seed < 0 or self.trials < 1:
            raise TliError(f"seed {self.seed} and trials {self.trials}: need seed >= 0 and "
                           "trials >= 1 (evidence: every seed below 2^32)")
        if not (0.5 <= self.duration <= 600):
            raise TliError(f"duration must be between 0.5 and 600 s, got {self.duration}")
        if self.pushes < 0 or self.tilts < 0:
            raise TliError("pushes and tilts must be >= 0")
        if not isinstance(self.workers, int) or isinstance(self.workers, bool) or \
                not 1 <= self.workers <= MAX_WORKERS:
            raise CampaignError(f"workers: expected an integer in [1, {MAX_WORKERS}], got "
                                f"{self.workers!r}")
        if self.backend not in BACKENDS:
            raise CampaignError(f"backend: one of {', '.join(BACKENDS)}, got {self.backend!r}")

    @property
    def cert_dir(self) -> Path:
        """``certificates``, default ``<root>/certificates``."""
        return Path(self.certificates) if self.certificates is not None else \
            Path(self.root) / "certificates"

    @property
    def certificate(self) -> Path:
        """``<cert_dir>/franka-scoop.cert.json``."""
        return self.cert_dir / f"{MODEL_NAME}.cert.json"

    @property
    def model(self) -> Path:
        """``<root>/models/franka-scoop.model.json``."""
        return Path(self.root) / "models" / f"{MODEL_NAME}.model.json"

    def settings(self) -> dict[str, Any]:
        """The evidence's ``physics`` settings (what a re-run needs besides seed and trials;
        the control law is recorded in ``physics.controller``, with its gains)."""
        return {"robot": self.robot, "variant": self.variant, "duration": float(self.duration),
                "pushes": int(self.pushes), "tilts": int(self.tilts), "retry": self.retry,
                "sensors": self.sensors}
