"""The evidence rules: the schema and semantics versions, the thresholds a campaign must meet to
count as evidence (examples, window, pushes), the physical worlds' requirements, the run
settings the CLI can produce. One module, shared by the campaign writers and the gate.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    pass

__all__ = [
    "BACKENDS",
    "CAMPAIGN_SEMANTICS",
    "DEFAULT_RERUN_EXAMPLES",
    "DEFAULT_RERUN_TRIALS",
    "EVIDENCE_KIND",
    "EVIDENCE_SCHEMA_VERSION",
    "EVIDENCE_SUFFIX",
    "HANDOFF_RETEST",
    "MIN_EVIDENCE_EXAMPLES",
    "MIN_MAX_PUSHES",
    "MIN_PHYSICS_TRIALS",
    "MIN_WINDOW",
    "REQUIRED_ROBOT",
    "PhysicalWorld",
]

EVIDENCE_SCHEMA_VERSION = 3
CAMPAIGN_SEMANTICS = 3
EVIDENCE_KIND = "tli-verify/campaign-evidence"
EVIDENCE_SUFFIX = ".campaign.json"
MIN_EVIDENCE_EXAMPLES = 500
MIN_WINDOW = 100
MIN_MAX_PUSHES = 2


@dataclass(frozen=True, slots=True)
class PhysicalWorld:
    """A kind of physical campaign the evidence check accepts; its checks live with its
    simulator (the MuJoCo Franka's: :data:`tli_verify.sim.physics_checks.FRANKA_PHYSICS`).

    Attributes
    ----------
    name : str
        The evidence's ``world`` (e.g. ``"franka-physics"``).
    min_trials : int
        Fewest decided trials that count as evidence.
    check : callable
        ``check(doc, shown, passed) -> problems`` on the evidence document (its ``physics``
        block present), appending what passed to ``passed``.
    """

    name: str
    min_trials: int
    check: Callable[[Mapping[str, Any], str, list[str]], list[str]]


BACKENDS = ("process", "dask", "serial")


# The gate's own re-run and re-test sizes, and the physical worlds' thresholds: with the
# campaign thresholds above, every number evidence must meet lives here.


DEFAULT_RERUN_EXAMPLES = 50
"""Examples the gate re-runs by default per deployed model with kinematic evidence (~4 s
per model on one core): a hash proves the evidence's integrity, not its honesty, so the gate
runs a sample of the campaign itself, on seeds it derives
(:func:`tli_verify.deploy.gate.rerun_seed`)."""
DEFAULT_RERUN_TRIALS = 1
"""Physical trials the gate re-runs by default per model with physical evidence (10-40 s each
on one core)."""
HANDOFF_RETEST = 100
"""Fresh states per DS the gate draws (twice: drawn, then from the hand-offs) to re-test a
*sampled* hand-off claim on its own seed (from the model file's SHA-256)."""
REQUIRED_ROBOT = "panda"
"""The rig the Franka project's physical evidence must be made on: the arm, not the free tool."""
MIN_PHYSICS_TRIALS = 30
"""Fewest perturbed physical trials a ``franka-physics`` campaign needs to count as evidence:
the paper's robot experiment (30 perturbed trials, 30 successes). With 30 successes the
failure probability per perturbed trial is below 10% at 95% confidence (rule of three): weaker
than the kinematic campaigns' bound, and the gate's line says so."""
