"""2D benchmark worlds: the single convex mode of the paper's single-mode study (Sec. 7.1), and
the multi-modal task worlds (scooping, cooking, color tracing, inspection; :mod:`.base`)."""

from __future__ import annotations

from tli_verify.worlds.base import WorldBase
from tli_verify.worlds.scoop import ScoopWorld

__all__ = ["WORLDS", "ScoopWorld", "WorldBase"]

WORLDS: dict[str, type[WorldBase]] = {
    "scoop": ScoopWorld,
}
"""The task worlds by name (``scripts/make_demos.py --world NAME``)."""
