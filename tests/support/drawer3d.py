"""A user's own task no shipped file has, as the files a user writes: 3-D, four modes (reach
the handle, pull the drawer, retract to the home pose, done), a ball among boxes, a latch, and a
goal mode that is NOT a sink (the automaton leaves ``d`` under perturbations, so the goal is
declared). Tests write it into a temporary project with :func:`write_project`.
"""

from __future__ import annotations

from pathlib import Path

TASK = """
name = "drawer"
description = "Open a drawer: reach the handle, pull it out, retract to the home pose."
dt = 0.01
background = "free"
spec = "../specs/drawer.toml"

[state]
names = ["x (m)", "y (m)", "z (m)"]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]

[regions.home]
ball = { center = [0.8, 0.5, 0.78], radius = 0.17 }

[regions.handle]
box = { lower = [0.45, 0.45, 0.45], upper = [0.55, 0.55, 0.55] }

[regions.slide]
box = { lower = [0.55, 0.4, 0.4], upper = [0.9, 0.6, 0.65] }

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
nominal = [[0.2, 0.5, 0.8]]

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
start = [0.2, 0.5, 0.8]
start_jitter = 0.05
waypoints = [[0.35, 0.5, 0.55], [0.5, 0.5, 0.5], [0.6, 0.5, 0.5], [0.8, 0.5, 0.5],
             [0.8, 0.5, 0.8]]
jitter = [1.0, 0.5, 0.5, 0.5, 0.0]
"""

SPEC = """
name = "drawer"
task = "drawer"
inputs = ["h", "o", "r"]
outputs = ["a", "b", "c", "d", "p"]

[modes]
a = "!h & !o & !r"
b = "h & !o & !r"
c = "!h & o & !r"
d = "!h & !o & r"

[assume]
init = "!h & !o & !r"
safety = [
  "G((!h & !o & !r) -> X((!h & !o & !r) | (h & !o & !r)))",
  "G((h & !o & !r) -> X((h & !o & !r) | (!h & !o & !r) | (!h & o & !r)))",
]
liveness = ["GF(!a | h)", "GF(!b | o)", "GF(!c | r)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b))",
  "G(b -> X(a | b | c))",
  "G(X p <-> ((b & X a) | (c & X a) | (c & X b) | (d & X !d)))",
]
liveness = ["GF(d | p)"]
"""


def write_project(root: Path) -> Path:
    """Write ``tasks/drawer.toml`` and ``specs/drawer.toml`` under ``root``; return ``root``."""
    (root / "tasks").mkdir(parents=True, exist_ok=True)
    (root / "specs").mkdir(parents=True, exist_ok=True)
    (root / "tasks" / "drawer.toml").write_text(TASK)
    (root / "specs" / "drawer.toml").write_text(SPEC)
    return root
