"""The former Python world classes (scoop, cooking, color tracing, inspection), kept only as
the reference the bundled task files are tested against (tests/unit/test_task_equivalence.py):
the tasks replaced them, and no code of the package uses them."""

from tests.support.legacy_worlds.color_tracing import ColorTracingWorld
from tests.support.legacy_worlds.cooking import CookingWorld
from tests.support.legacy_worlds.inspection import InspectionWorld
from tests.support.legacy_worlds.scoop import ScoopWorld

LEGACY = {"scoop": ScoopWorld, "cooking": CookingWorld, "color-tracing": ColorTracingWorld,
          "inspection": InspectionWorld}
