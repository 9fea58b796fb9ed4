"""The files ``tli init DIR`` writes: a commented task and spec for a new task, in any dimension.

The template is a three-mode reaching task that goes through every command as written:
``a`` (approach the zone), ``b`` (cross the zone to the goal), ``c`` (done, latched); a push
out of the zone before the goal is a perturbation ``b -> a`` the automaton replans from. The
task's regions are boxes in ``[-1, 1]^n``; edit them, the sensors and the spec for your task.
"""

from __future__ import annotations

__all__ = ["scaffold"]


_SENSING = """# Latches remember history: value = set | (prev(value) & !reset).
[latches.done]               # the goal counts only when entered from the zone; then it stays
set = "goal & prev(zone)"
reset = "false"

# Sensors: the spec's inputs, boolean formulas over regions (now, or prev(...)) and latches.
[sensors]
z = "zone & !done"
g = "done"
"""
"""The latch and the sensors both templates share (the spec reads ``z`` and ``g``)."""


def _vec(values: list[float]) -> str:
    return "[" + ", ".join(f"{v:g}" if v != int(v) else f"{v:.1f}" for v in values) + "]"


def task_text(name: str, dim: int, *, pose: bool = False) -> str:
    """The commented task file of the template (``pose``: ``dim`` position coordinates and
    the tool's orientation, :mod:`tli_verify.tasks.orientation`)."""
    if pose:
        return _pose_task_text(name, dim)
    rest = [0.0] * (dim - 1)
    lo_rest, hi_rest = [-0.3] * (dim - 1), [0.3] * (dim - 1)
    names = ", ".join(f'"x{i}"' for i in range(dim))
    return f'''# Task "{name}": what the environment is (../specs/{name}.toml says what to do).
# Reference: tli_verify.tasks.taskfile (format), tli_verify.tasks.formula (sensor formulas).
name = "{name}"
description = "A reaching task: approach the zone, cross it to the goal, stay done."
lag = 0                      # sensor lag in control steps
dt = 0.01                    # control period (s): certify the model at this period
background = "free"          # the region of every state no listed region holds
spec = "../specs/{name}.toml"    # the default spec of `tli run --task tasks/{name}.toml`

[state]                      # the state space: n = {dim}; the workspace box
names = [{names}]
lower = {_vec([-1.0] * dim)}
upper = {_vec([1.0] * dim)}

# Regions, in priority order: a state lies in the FIRST listed region holding it. Shapes: box,
# polytope (A x <= b), ball, ellipsoid, union / intersection / difference of regions.
[regions.goal]
box = {{ lower = {_vec([0.6, *lo_rest])}, upper = {_vec([1.0, *hi_rest])} }}
color = "#9ed99b"

[regions.zone]
box = {{ lower = {_vec([0.2, *lo_rest])}, upper = {_vec([0.6, *hi_rest])} }}
color = "#f7e27a"

{_SENSING}
[goal]                       # what completes an episode ("sinks": the automaton's sink modes)
modes = "sinks"

[starts]
nominal = [{_vec([-0.6, *rest])}]       # the default start of `tli verify`
region = "free"              # random starts are drawn here

[perturbations]              # the defaults of `tli verify` (paper Asm. 2: finitely many)
max_magnitude = 2.0
window = 700
max_pushes = 3

[demonstrator]               # `tli demos tasks/{name}.toml` writes these demonstrations
count = 3
duration = 8.0
dt = 0.05
sigma = 0.05

[[demonstrator.scripts]]
label = "approach, cross, done"
start = {_vec([-0.6, *rest])}
start_jitter = 0.1
waypoints = [{_vec([0.0, *rest])}, {_vec([0.4, *rest])}, {_vec([0.8, *rest])}]
jitter = [1.0, 0.5, 0.0]
'''


def _pose_task_text(name: str, dim: int) -> str:
    """The pose template: the reach template with the tool's orientation in the state; the
    zone counts only with the tool upright (a cone)."""
    rest = [0.0] * (dim - 1)
    lo_rest, hi_rest = [-0.3] * (dim - 1), [0.3] * (dim - 1)
    inf3 = ", ".join(["-inf"] * 3)
    pinf3 = ", ".join(["inf"] * 3)
    names = ", ".join([*(f'"x{i}"' for i in range(dim)), '"rx"', '"ry"', '"rz"'])

    def box(lo: float, hi: float) -> str:
        return (f"{{ lower = {_vec([lo, *lo_rest])[:-1]}, {inf3}], upper = "
                f"{_vec([hi, *hi_rest])[:-1]}, {pinf3}] }}")

    def pose_vec(x: float, r: list[float]) -> str:
        return _vec([x, *rest, *r])

    return f'''# Task "{name}": what the environment is (../specs/{name}.toml says what to do).
# Reference: tli_verify.tasks.taskfile (format), tli_verify.tasks.orientation (pose tasks).
name = "{name}"
description = "A reaching task with the tool's orientation: cross the zone upright to the goal."
lag = 0                      # sensor lag in control steps
dt = 0.01                    # control period (s): certify the model at this period
background = "free"          # the region of every state no listed region holds
spec = "../specs/{name}.toml"    # the default spec of `tli run --task tasks/{name}.toml`

[state]                      # position (n = {dim}), then the tool's orientation: rotation vector
names = [{names}]
lower = {_vec([-1.0] * dim + [-1.2] * 3)}
upper = {_vec([1.0] * dim + [1.2] * 3)}
orientation = {{ start = {dim}, reference = [1, 0, 0, 0] }}   # unit quaternion (w, x, y, z)

# Regions, in priority order. A cone is a region on the orientation: the tool axis `axis`
# turned by the state's orientation within `within` degrees of the world direction `toward`.
[regions.goal]
box = {box(0.6, 1.0)}
color = "#9ed99b"

[regions.zone]               # the zone, with the tool upright
intersection = [
  {{ box = {box(0.2, 0.6)} }},
  {{ cone = {{ axis = [0, 0, 1], toward = [0, 0, 1], within = 20 }} }},
]
color = "#f7e27a"

{_SENSING}
[goal]
modes = "sinks"

[starts]
nominal = [{pose_vec(-0.6, [0.5, 0.0, 0.0])}]   # tilted: 0.5 rad about x
region = "free"

[perturbations]
max_magnitude = 1.0
window = 700
max_pushes = 3

[demonstrator]               # `tli demos tasks/{name}.toml` (or your own: --from-pose)
count = 3
duration = 8.0
dt = 0.05
sigma = 0.02

[[demonstrator.scripts]]
label = "approach turning upright, cross, done"
start = {pose_vec(-0.6, [0.5, 0.0, 0.0])}
start_jitter = 0.05
waypoints = [
  {pose_vec(0.0, [0.1, 0.0, 0.0])},
  {pose_vec(0.4, [0.0, 0.0, 0.0])},
  {pose_vec(0.8, [0.0, 0.0, 0.0])},
]
jitter = [1.0, 0.5, 0.0]
'''


def spec_text(name: str) -> str:
    """The commented GR(1) spec of the template."""
    return f'''# Spec "{name}": GR(1), sensors (inputs) from ../tasks/{name}.toml. Check it with
#   tli spec check specs/{name}.toml
name = "{name}"
task = "{name}"              # the task whose sensors the inputs are (tasks/{name}.toml)
inputs = ["z", "g"]          # z: in the zone (not done), g: done
outputs = ["a", "b", "c", "p"]   # modes, and p: "the last mode change was a perturbation"

[modes]                      # the sensor reading that labels each mode
a = "!z & !g"                # approach the zone
b = "z & !g"                 # cross the zone to the goal
c = "g"                      # done

[assume]                     # what the environment can do
init = "!z & !g"
safety = [
  "G((!z & !g) -> X !g)",    # the goal is entered from the zone only (the latch's set)
  "G(g -> X g)",             # done stays done
]
liveness = [
  "GF(!a | z)",              # approaching, the zone is eventually reached
  "GF(!b | g)",              # crossing, the goal is eventually reached
]

[guarantee]                  # what the robot must do
init = "a & !p"
safety = [
  "G(a -> X(a | b))",
  "G(b -> X(a | b | c))",    # b -> a: pushed out of the zone; replan
  "G(c -> X c)",
  "G(X p <-> (b & X a))",    # mark the unexpected change (paper Asm. 2: finitely many)
]
liveness = ["GF(c | p)"]     # done, unless perturbed forever
'''


def readme_text(name: str) -> str:
    """The project README: the commands from demonstrations to the gate."""
    return f'''# {name}: a tli-verify project

Layout (the project rules of `tli_verify.tasks.project`):

    tasks/{name}.toml          the task: state space, regions, sensors, goal, starts
    specs/{name}.toml          the GR(1) spec; `task = "{name}"` names its task
    demos/                     demonstrations (CSV)
    models/                    learned models (each names its spec)
    certificates/              certificates and campaign evidence, by model name
    ci/tli-gate.yml            a CI job that runs the deployment gate

From demonstrations to a gated policy:

    tli task check tasks/{name}.toml --picture out/{name}-task.png
    tli spec check specs/{name}.toml
    tli demos tasks/{name}.toml                    # or record your own demos/*.csv
    tli learn demos/{name}_*.csv --spec specs/{name}.toml -o models/{name}.model.json
    tli certify models/{name}.model.json           # -> certificates/{name}.cert.json
    tli run --spec specs/{name}.toml --perturb random:2
    tli verify --spec specs/{name}.toml --examples 1000 --evidence
    tli gate .
'''


def ci_text() -> str:
    """A GitHub Actions job that installs tli-verify and runs the gate."""
    return '''# Deployment gate: blocks models that are uncertified, untested or tampered with.
# Copy to .github/workflows/tli-gate.yml (GitHub Actions); other CIs run the same commands.
name: tli-gate
on: [push, pull_request]
jobs:
  gate:
    runs-on: ubuntu-latest
    steps:
      - uses: actions/checkout@v4
      - uses: actions/setup-python@v5
        with:
          python-version: "3.11"
      - run: python -m pip install tli-verify
      - run: tli gate .
'''


def scaffold(name: str, dim: int, *, pose: bool = False) -> dict[str, tuple[str, str]]:
    """The files of a new project: relative path -> (what it is, text); ``pose``: ``dim``
    position coordinates and the tool's orientation."""
    return {
        f"tasks/{name}.toml": ("task file", task_text(name, dim, pose=pose)),
        f"specs/{name}.toml": ("spec", spec_text(name)),
        "README.md": ("project README", readme_text(name)),
        "ci/tli-gate.yml": ("CI snippet", ci_text()),
    }
