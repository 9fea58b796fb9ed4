"""2D benchmark worlds: the single convex mode of the paper's single-mode study (Sec. 7.1), and
the multi-modal task worlds of the paper's experiments (:mod:`.base`): soup scooping, cooking
(generalization), color tracing and the inspection line."""

from __future__ import annotations

from tli_verify.worlds.base import World, WorldBase, plot_world, write_demos
from tli_verify.worlds.color_tracing import ColorTracingWorld
from tli_verify.worlds.cooking import CookingWorld
from tli_verify.worlds.inspection import InspectionWorld
from tli_verify.worlds.scoop import ScoopWorld

__all__ = ["WORLDS", "ColorTracingWorld", "CookingWorld", "InspectionWorld", "ScoopWorld",
           "World", "WorldBase", "plot_world",
           "write_demos"]

WORLDS: dict[str, type[WorldBase]] = {
    "scoop": ScoopWorld,
    "cooking": CookingWorld,
    "color-tracing": ColorTracingWorld,
    "inspection": InspectionWorld,
}
"""The task worlds by name (``scripts/make_demos.py --world NAME``)."""
