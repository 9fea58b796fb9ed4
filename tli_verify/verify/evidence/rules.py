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
    "EVIDENCE_KIND",
    "EVIDENCE_SCHEMA_VERSION",
    "EVIDENCE_SUFFIX",
    "MIN_EVIDENCE_EXAMPLES",
    "MIN_MAX_PUSHES",
    "MIN_WINDOW",
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
