"""Tasks no shipped file has, drawn to hit both shapes of the hand-off gap (issue 30), written
as the files a user writes. Tests and the side-by-side script write them into a temporary
project with :func:`write_project`.

* ``relay`` (3-D, four boxes): ``a`` free space, ``b`` box 1, ``c`` box 2, ``d`` the goal
  (a latch). Box 1 is entered across its top and side faces, through which its DS leaves
  again when nothing keeps it in; from starts behind the goal the free-space flow crosses the
  goal (read as free without the latch) and box 2 (a third mode) on its way to box 1.
* ``dock`` (4-D, five modes): an ellipsoid (``lens``), a rotated polytope (``dock``), a union
  of two boxes (``yard``), a box (``home``); two latches (``docked``, ``done``); the goal is a
  mode *and* a sensor (``[goal] modes = ["e"], sensors = ["h"]``). A push from ``home`` back
  into the dock or the yard keeps ``docked`` (home is in its keep set), so the spec allows
  ``a -> c | d`` (``tli task check --spec`` finds it when it does not).
"""

from __future__ import annotations

import math
from pathlib import Path

RELAY_TASK = """
name = "relay"
description = "Relay through two boxes to the goal (3-D, drawn to be awkward)."
dt = 0.01
background = "free"
spec = "../specs/relay.toml"

[state]
names = ["x0", "x1", "x2"]
lower = [-1.0, -1.0, -1.0]
upper = [1.0, 1.0, 1.0]

[regions.goal]
box = { lower = [0.6, -0.4, -0.4], upper = [1.0, 0.4, 0.4] }

[regions.box2]
box = { lower = [0.1, -0.4, -0.4], upper = [0.6, 0.4, 0.4] }

[regions.box1]
box = { lower = [-0.4, -0.4, -0.4], upper = [0.1, 0.4, 0.4] }

[latches.done]
set = "goal & prev(box2)"

[sensors]
u = "box1 & !done"
v = "box2 & !done"
g = "done"

[starts]
nominal = [[-0.8, 0.0, 0.7]]
region = "free"

[perturbations]
max_magnitude = 2.0
window = 600
max_pushes = 3

[demonstrator]
count = 3
duration = 10.0
dt = 0.05
sigma = 0.02

[[demonstrator.scripts]]
label = "relay"
start = [-0.8, 0.0, 0.7]
start_jitter = 0.1
waypoints = [[-0.2, 0.0, 0.0], [0.35, 0.0, 0.0], [0.8, 0.0, 0.0]]
jitter = [0.5, 0.3, 0.0]
"""

RELAY_SPEC = """
name = "relay"
task = "relay"
inputs = ["u", "v", "g"]
outputs = ["a", "b", "c", "d", "p"]

[modes]
a = "!u & !v & !g"
b = "u & !v & !g"
c = "!u & v & !g"
d = "!u & !v & g"

[assume]
init = "!u & !v & !g"
safety = [
  "G((!u & !v & !g) -> X !g)",
  "G((u & !v & !g) -> X !g)",
  "G(g -> X g)",
]
liveness = ["GF(!a | u | v)", "GF(!b | v)", "GF(!c | g)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b | c))",
  "G(b -> X(a | b | c))",
  "G(c -> X(a | b | c | d))",
  "G(d -> X d)",
  "G(X p <-> ((b & X a) | (c & X a) | (c & X b)))",
]
liveness = ["GF(d | p)"]
"""


def _dock_polytope() -> str:
    """A box rotated by 30 degrees in the (x2, x3) plane, as ``A x <= b``: x0 in [-0.3, 0.2],
    x1 in [-0.35, 0.35], the rotated (x2, x3) half-widths 0.35."""
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    rows = [([1, 0, 0, 0], 0.2), ([-1, 0, 0, 0], 0.3), ([0, 1, 0, 0], 0.35),
            ([0, -1, 0, 0], 0.35), ([0, 0, c, s], 0.35), ([0, 0, -c, -s], 0.35),
            ([0, 0, -s, c], 0.35), ([0, 0, s, -c], 0.35)]
    A = ", ".join("[" + ", ".join(f"{v:.12g}" for v in r) + "]" for r, _ in rows)
    b = ", ".join(f"{v:.12g}" for _, v in rows)
    return f"polytope = {{ A = [{A}], b = [{b}] }}"


DOCK_TASK = f"""
name = "dock"
description = "Through a lens into a rotated dock, across the yard, home (4-D, two latches)."
dt = 0.01
background = "free"
spec = "../specs/dock.toml"

[state]
names = ["x0", "x1", "x2", "x3"]
lower = [-1.0, -1.0, -1.0, -1.0]
upper = [1.0, 1.0, 1.0, 1.0]

[regions.home]
box = {{ lower = [0.55, -0.35, -0.35, -0.35], upper = [0.95, 0.35, 0.35, 0.35] }}

[regions.yard]
union = [{{ box = {{ lower = [0.15, -0.35, -0.35, -0.35], upper = [0.6, 0.35, 0.35, 0.35] }} }},
         {{ box = {{ lower = [-0.1, -0.2, -0.2, -0.2], upper = [0.3, 0.2, 0.2, 0.2] }} }}]

[regions.dock]
{_dock_polytope()}

[regions.lens]
ellipsoid = {{ center = [-0.45, 0.0, 0.0, 0.0], matrix = [[11.1111111111, 0, 0, 0],
  [0, 9.18273645546, 0, 0], [0, 0, 11.1111111111, 0], [0, 0, 0, 11.1111111111]] }}

[latches.docked]
set = "dock & prev(lens)"
reset = "!(dock | yard | home)"

[latches.done]
set = "home & prev(yard) & docked"

[sensors]
l = "lens & !done"
k = "dock & docked & !done"
y = "yard & docked & !done"
h = "done"

[goal]
modes = ["e"]
sensors = ["h"]

[starts]
nominal = [[-0.9, 0.5, 0.3, -0.3]]
region = "free"

[perturbations]
max_magnitude = 2.0
window = 600
max_pushes = 3

[demonstrator]
count = 3
duration = 12.0
dt = 0.05
sigma = 0.02

[[demonstrator.scripts]]
label = "dock"
start = [-0.9, 0.5, 0.3, -0.3]
start_jitter = 0.08
waypoints = [[-0.5, 0.05, 0.0, 0.0], [-0.05, 0.0, 0.0, 0.0], [0.35, 0.0, 0.0, 0.0],
             [0.78, 0.0, 0.0, 0.0]]
jitter = [0.1, 0.05, 0.05, 0.0]
"""

_A = "!l & !k & !y & !h"
_B = "l & !k & !y & !h"
_C = "!l & k & !y & !h"
_D = "!l & !k & y & !h"
_E = "!l & !k & !y & h"

DOCK_SPEC = f"""
name = "dock"
task = "dock"
inputs = ["l", "k", "y", "h"]
outputs = ["a", "b", "c", "d", "e", "p"]

[modes]
a = "{_A}"
b = "{_B}"
c = "{_C}"
d = "{_D}"
e = "{_E}"

[assume]
init = "{_A}"
safety = [
  "G(({_A}) -> X(({_A}) | ({_B}) | ({_C}) | ({_D})))",
  "G(({_B}) -> X(({_A}) | ({_B}) | ({_C})))",
  "G(({_C}) -> X(({_A}) | ({_B}) | ({_C}) | ({_D})))",
  "G(({_D}) -> X(({_A}) | ({_B}) | ({_C}) | ({_D}) | ({_E})))",
  "G(({_E}) -> X({_E}))",
]
liveness = ["GF(!a | l)", "GF(!b | k)", "GF(!c | y)", "GF(!d | h)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b | c | d))",
  "G(b -> X(a | b | c))",
  "G(c -> X(a | b | c | d))",
  "G(d -> X(a | b | c | d | e))",
  "G(e -> X e)",
  "G(X p <-> ((b & X a) | (c & X (a | b)) | (d & X (a | b | c))))",
]
liveness = ["GF(e | p)"]
"""

TASKS = {"relay": (RELAY_TASK, RELAY_SPEC), "dock": (DOCK_TASK, DOCK_SPEC)}


def write_project(root: Path, name: str) -> Path:
    """Write ``tasks/NAME.toml`` and ``specs/NAME.toml`` of one of :data:`TASKS` under
    ``root``; return ``root``."""
    task, spec = TASKS[name]
    (root / "tasks").mkdir(parents=True, exist_ok=True)
    (root / "specs").mkdir(parents=True, exist_ok=True)
    (root / "tasks" / f"{name}.toml").write_text(task)
    (root / "specs" / f"{name}.toml").write_text(spec)
    return root
