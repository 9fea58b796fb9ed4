"""Physical perturbation campaigns of the Franka soup-scooping policy: run and judge the trials.

The 2-D worlds are verified by bisimulation campaigns (:mod:`tli_verify.verify.campaign`); the
Franka policy runs in MuJoCo, where a trial costs seconds, so its campaign is a few dozen
perturbed physical trials (the paper's 30). :func:`run_physics_campaign` runs the seeded trials
``seed, seed + 1, ...`` of a :class:`~tli_verify.sim.physics_config.PhysicsConfig` with one
executive, as ``tli sim franka --trials N --seed S`` runs them, each with the perturbations
:func:`tli_verify.sim.perturbations.draw` gives its seed, and judges each with the physics
oracle (:func:`tli_verify.sim.trial_oracle.check_trial`); the :class:`PhysicsResult` becomes
campaign evidence through :func:`tli_verify.sim.physics_evidence.write_physics_evidence`.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (30 perturbed trials on the Panda, all
successful) and Sec. 4.4 (perturbation campaigns, Asm. 2: finitely many perturbations).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tli_verify.sim.franka_files import hash_files
from tli_verify.sim.loop import TrialResult
from tli_verify.sim.perturbations import draw
from tli_verify.sim.physics_config import PhysicsConfig
from tli_verify.sim.trial_oracle import VIOLATION_KINDS, TrialVerdict, check_trial

__all__ = [
    "PhysicsResult",
    "run_physics_campaign",
]


@dataclass(frozen=True, slots=True)
class PhysicsResult:
    """A finished physical campaign.

    Attributes
    ----------
    config : PhysicsConfig
    results : tuple of TrialResult
    verdicts : tuple of TrialVerdict
        The oracle's, one per trial.
    files : tuple of (str, str, str)
        ``(name, path, SHA-256)`` of the spec, model and certificate when the campaign started
        (a file changed during it is refused when the evidence is written).
    wall_time : float
        Seconds.
    cuts_added : int
        Cuts the executive learned over the campaign (they carry over between trials).
    """

    config: PhysicsConfig
    results: tuple[TrialResult, ...]
    verdicts: tuple[TrialVerdict, ...]
    files: tuple[tuple[str, str, str], ...]
    wall_time: float
    cuts_added: int = 0

    @property
    def successes(self) -> int:
        """Trials that delivered soup."""
        return sum(r.success for r in self.results)

    @property
    def violations(self) -> dict[str, int]:
        """Trials with each violation kind."""
        return {k: sum(k in v.violations for v in self.verdicts) for k in VIOLATION_KINDS}

    @property
    def ok(self) -> bool:
        """True iff every trial passed the oracle."""
        return all(v.ok for v in self.verdicts)


def run_physics_campaign(config: PhysicsConfig, *, policy: Any = None,
                         on_trial: Callable[[int, TrialResult, TrialVerdict], None] | None = None,
                         frame: Callable[[Any], None] | None = None) -> PhysicsResult:
    """Run ``config.trials`` seeded, perturbed trials with one executive and judge each.

    Parameters
    ----------
    config : PhysicsConfig
    policy : LTLDSPolicy, optional
        The executive, already loaded behind the certificate (default:
        :func:`tli_verify.sim.loop.load_policy` of ``config.variant`` for ``config.root``);
        its cuts carry over between the trials.
    on_trial : callable, optional
        ``(k, result, verdict)`` after each trial (progress, streaming output).
    frame : callable, optional
        Called with the rig at every control step of the first trial (video frames).

    Returns
    -------
    PhysicsResult

    Raises
    ------
    CertificateError
        (exit 1) The certificate is missing, does not re-check, or does not cover the model
        (:func:`tli_verify.sim.loop.load_policy`): nothing moves.
    """
    from tli_verify.sim.loop import load_policy, run_trial

    files = hash_files(config.root, config.cert_dir)
    if policy is None:
        policy = load_policy(config.variant, root=config.root,
                             certificates=config.cert_dir)
    t0 = time.perf_counter()
    results: list[TrialResult] = []
    verdicts: list[TrialVerdict] = []
    for k in range(config.trials):
        seed = config.seed + k
        res = run_trial(policy, seed, variant=config.variant,
                        perturbations=draw(seed, pushes=config.pushes, tilts=config.tilts),
                        duration=config.duration, robot=config.robot, retry=config.retry,
                        sensors=config.sensors,
                        frame=frame if k == 0 else None)
        verdict = check_trial(res, policy.automaton)
        results.append(res)
        verdicts.append(verdict)
        if on_trial is not None:
            on_trial(k, res, verdict)
    return PhysicsResult(config=config, results=tuple(results), verdicts=tuple(verdicts),
                         files=files, wall_time=time.perf_counter() - t0,
                         cuts_added=sum(r.cuts_added for r in results))
