"""A user's own 4-D task as the files a user writes: the drawer of :mod:`tests.support.drawer3d`
with a wrist angle ``w`` (a 4-D ball, two 4-D boxes, a latch, a goal mode that is not a sink).
Tests write it into a temporary project with :func:`write_project`."""

from __future__ import annotations

from pathlib import Path

from tests.support.drawer3d import SPEC as SPEC3

TASK = """
name = "drawer4"
description = "Open a drawer with a wrist angle: reach the handle, pull, retract."
dt = 0.01
background = "free"
spec = "../specs/drawer4.toml"

[state]
names = ["x (m)", "y (m)", "z (m)", "w (rad)"]
lower = [0.0, 0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0, 1.0]

[regions.home]
ball = { center = [0.8, 0.5, 0.78, 0.5], radius = 0.17 }

[regions.handle]
box = { lower = [0.45, 0.45, 0.45, 0.4], upper = [0.55, 0.55, 0.55, 0.6] }

[regions.slide]
box = { lower = [0.55, 0.4, 0.4, 0.35], upper = [0.9, 0.6, 0.65, 0.65] }

[latches.pulled]
set = "slide & prev(handle)"
reset = "!(slide | home)"

[sensors]
h = "handle"
o = "pulled & slide"
r = "pulled & home"

[goal]
modes = ["d"]

[starts]
nominal = [[0.2, 0.5, 0.8, 0.2]]

[perturbations]
max_magnitude = 0.6
window = 600
max_pushes = 3

[demonstrator]
count = 3
duration = 10.0
dt = 0.05
sigma = 0.01

[[demonstrator.scripts]]
label = "open"
start = [0.2, 0.5, 0.8, 0.2]
start_jitter = 0.05
waypoints = [[0.35, 0.5, 0.55, 0.35], [0.5, 0.5, 0.5, 0.5], [0.6, 0.5, 0.5, 0.5],
             [0.8, 0.5, 0.5, 0.5], [0.8, 0.5, 0.8, 0.5]]
jitter = [1.0, 0.5, 0.5, 0.5, 0.0]
"""

SPEC = SPEC3.replace('name = "drawer"\ntask = "drawer"', 'name = "drawer4"\ntask = "drawer4"')


def write_project(root: Path) -> Path:
    """Write ``tasks/drawer4.toml`` and ``specs/drawer4.toml`` under ``root``; return ``root``."""
    (root / "tasks").mkdir(parents=True, exist_ok=True)
    (root / "specs").mkdir(parents=True, exist_ok=True)
    (root / "tasks" / "drawer4.toml").write_text(TASK)
    (root / "specs" / "drawer4.toml").write_text(SPEC)
    return root
