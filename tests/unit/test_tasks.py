"""Task files: the format, its errors, regions, sensor formulas and latches, the registry.

Every task here is written by the test itself (other dimensions, other region shapes, a goal
that is not a sink); the bundled files are checked against the published schema.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.errors import TaskError
from tli_verify.io import validate_schema
from tli_verify.tasks import formula as fml
from tli_verify.tasks.registry import bundled_tasks, find_task, task_names
from tli_verify.tasks.taskfile import load_task, parse_task

ROOT = Path(__file__).resolve().parents[2]

BOX3 = """
name = "t3"
[state]
lower = [0, 0, 0]
upper = [1, 1, 1]
"""


def box3(top: str = "", rest: str = "") -> str:
    """The 3-D unit-box task with top-level keys ``top`` and tables ``rest``."""
    return f'name = "t3"\n{top}\n[state]\nlower = [0, 0, 0]\nupper = [1, 1, 1]\n{rest}'


def _task(text: str, tmp_path: Path | None = None, name: str = "t.toml"):
    if tmp_path is None:
        return parse_task(text)
    p = tmp_path / name
    p.write_text(text)
    return load_task(p)


def test_bundled_tasks_validate_against_the_schema() -> None:
    import tomllib

    names = bundled_tasks()
    assert set(names) >= {"scoop", "cooking", "color-tracing", "inspection"}
    for path in names.values():
        validate_schema(tomllib.loads(path.read_text()), "task.schema.json", where=str(path),
                        error=TaskError)
        task = find_task(path.stem)
        assert task.source.sha256 is not None and task.spec_path is not None
        assert task.spec_path.is_file()
    schema = json.loads((ROOT / "tli_verify/schemas/task.schema.json").read_text())
    assert schema["required"] == ["name", "state"]


def test_a_3d_task_with_every_region_shape(tmp_path: Path) -> None:
    text = box3('background = "air"', """
[regions.slab]
polytope = { A = [[1, 1, 0], [-1, 0, 0]], b = [0.5, 0] }
[regions.orb]
ball = { center = [0.8, 0.8, 0.5], radius = 0.1 }
[regions.egg]
ellipsoid = { center = [0.5, 0.2, 0.8], matrix = [[100, 0, 0], [0, 25, 0], [0, 0, 400]] }
[regions.ring]
difference = [
  { box = { lower = [0.6, 0, 0], upper = [1, 0.4, 1] } },
  { ball = { center = [0.8, 0.2, 0.5], radius = 0.1 } },
]
[regions.both]
union = ["orb", { box = { lower = [0, 0.9, 0.9], upper = [0.1, 1, 1] } }]
layer = true
[sensors]
s = "slab"
o = "orb | both"
e = "egg & !slab"
r = "ring"
""")
    task = _task(text, tmp_path)
    assert task.dim == 3 and task.region_names == ("slab", "orb", "egg", "ring", "air")
    X = np.array([[0.1, 0.1, 0.5],     # slab (x + y <= 0.5, x >= 0)
                  [0.8, 0.8, 0.5],     # orb
                  [0.5, 0.2, 0.8],     # egg (not slab: 0.7 > 0.5)
                  [0.9, 0.05, 0.5],    # ring
                  [0.8, 0.2, 0.5],     # the ring's hole: air
                  [0.05, 0.95, 0.95]]) # the layer 'both' only (air cell)
    assert list(task.true_mode(X)) == ["slab", "orb", "egg", "ring", "air", "air"]
    R = task.sensors(X[:, None, :])[:, 0]
    np.testing.assert_array_equal(R, [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1],
                                      [0, 0, 0, 0], [0, 1, 0, 0]])
    # the closed loop's key: cell and layers, in plain Python
    assert task.reading_key_one([0.05, 0.95, 0.95]) != task.reading_key_one([0.5, 0.5, 0.5])
    assert task.region_one([0.8, 0.8, 0.5]) == task.region_names.index("orb")


def test_latches_update_in_order_and_read_prev(tmp_path: Path) -> None:
    text = """
name = "latch"
background = "rest"
[state]
lower = [0]
upper = [10]
[regions.a]
box = { lower = [0], upper = [2] }
[regions.b]
box = { lower = [4], upper = [6] }
[latches.seen_a]
set = "a"
[latches.armed]
set = "b & seen_a"
reset = "a"
[sensors]
x = "armed"
y = "prev(armed) & !armed"
"""
    task = _task(text, tmp_path)
    # a -> rest -> b (armed: a was seen) -> rest -> a (disarmed) -> b (armed again)
    X = np.array([1.0, 3.0, 5.0, 3.0, 1.0, 5.0])[:, None]
    R = task.sensors(X)
    np.testing.assert_array_equal(R[:, 0], [0, 0, 1, 1, 0, 1])
    np.testing.assert_array_equal(R[:, 1], [0, 0, 0, 0, 1, 0])
    # the lag: the reading at step k is computed from the state lag steps back
    lagged = task.with_lag(2).sensors(X)
    np.testing.assert_array_equal(lagged[2:], task.sensors(X)[:-2])


@pytest.mark.parametrize(("text", "message"), [
    ('name = "x"', "missing the [state] table"),
    ('name = "x"\n[state]\nlower = [0]', "state.upper: missing"),
    (BOX3 + '[sensors]\nq = "nowhere"', "sensors.q: 'nowhere': unknown name 'nowhere'"),
    (BOX3 + '[regions.a]\nbox = { lower = [0, 0], upper = [1, 1] }\n[sensors]\nq = "a"',
     "regions.a.box.lower: expected a list of 3 numbers"),
    (BOX3 + '[regions.a]\nball = { center = [0, 0, 0], radius = -1 }\n[sensors]\nq = "a"',
     "regions.a.ball.radius: expected a number in (0, 1e+06]"),
    (BOX3 + '[regions.a]\nellipsoid = { center = [0, 0, 0], matrix = [[1, 0, 0], [0, -1, 0], '
     '[0, 0, 1]] }\n[sensors]\nq = "a"', "not positive definite"),
    (BOX3 + '[regions.a]\npolytope = { A = [[1, 0, 0], [-1, 0, 0]], b = [0, -1] }\n'
     '[sensors]\nq = "a"', "empty polytope"),
    (BOX3 + '[regions.a]\nunion = ["a"]\n[sensors]\nq = "a"', "defined in terms of itself"),
    (BOX3 + '[regions.a]\nbox = { lower = [0, 0, 0], upper = [1, 1, 1] }\n'
     'ball = { center = [0, 0, 0], radius = 1 }\n[sensors]\nq = "a"', "exactly one shape key"),
    (BOX3 + '[latches.l]\nset = "m"\n[latches.m]\nset = "true"\n[sensors]\nq = "l"',
     "reads latch 'm' before it is updated: write prev(m)"),
    (BOX3 + '[sensors]\nq = "(true"', "unexpected end of formula"),
    (BOX3 + '[sensors]\nq = "true && false"', "unexpected '&'"),
    (BOX3 + '[sensors]\nQ = "true"', "not a valid sensor"),
    (BOX3 + '[sensors]\nq = "true"\n[goal]\nsensors = ["z"]', "goal.sensors: 'z'"),
    (BOX3 + '[sensors]\nq = "true"\n[starts]\nnominal = [[2, 0, 0]]', "outside the workspace"),
    (BOX3 + '[sensors]\nq = "true"\n[unknown]\nx = 1', "unknown key 'unknown'"),
    (box3("lag = -1", '[sensors]\nq = "true"'), "lag"),
])
def test_bad_task_files_name_the_field(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(TaskError, match=None) as err:
        _task(text, tmp_path)
    assert message in str(err.value), str(err.value)
    assert str(tmp_path / "t.toml") in str(err.value)


def test_formula_precedence_and_operators() -> None:
    names = {"a", "b", "c"}
    env = {n: np.array([bool(i >> k & 1) for i in range(8)]) for k, n in enumerate("abc")}
    cases = {"a | b & c": env["a"] | (env["b"] & env["c"]),
             "!a & b": ~env["a"] & env["b"],
             "a -> b -> c": ~env["a"] | (~env["b"] | env["c"]),
             "a <-> b | c": env["a"] == (env["b"] | env["c"]),
             "a ^ b & c": env["a"] ^ (env["b"] & env["c"]),
             "(a | b) & !(c)": (env["a"] | env["b"]) & ~env["c"],
             "true & !false": np.ones(8, dtype=bool)}
    for text, want in cases.items():
        f = fml.parse(text, names=names, where="t")
        np.testing.assert_array_equal(f.evaluate(env, env, 8), want, err_msg=text)


@settings(max_examples=60, deadline=None)
@given(st.text(alphabet="ab!&|()-<>^ prevtu", max_size=40))
def test_formula_parser_never_crashes(text: str) -> None:
    try:
        f = fml.parse(text, names={"a", "b"}, where="t")
    except TaskError:
        return
    env = {"a": np.array([True, False]), "b": np.array([False, False])}
    assert f.evaluate(env, env, 2).shape == (2,)


def test_goal_and_starts_and_spec_link(tmp_path: Path) -> None:
    (tmp_path / "tasks").mkdir()
    text = box3('spec = "../specs/t3.toml"', """
[regions.g]
box = { lower = [0.5, 0, 0], upper = [1, 1, 1] }
[sensors]
q = "g"
[goal]
modes = ["b"]
sensors = ["q"]
[starts]
nominal = [[0.1, 0.1, 0.1]]
region = "outside"
[perturbations]
max_magnitude = 0.5
window = 50
max_pushes = 2
""")
    task = _task(text, tmp_path / "tasks", "t3.toml")
    assert task.goal.modes == ("b",) and task.goal.sensors == ("q",)
    assert task.starts.nominal == ((0.1, 0.1, 0.1),) and task.starts.region == "outside"
    assert task.perturbations.max_magnitude == 0.5 and task.perturbations.window == 50
    assert task.spec_path == tmp_path / "tasks" / ".." / "specs" / "t3.toml"
    samples = task.sample_region("g", 50, np.random.default_rng(0))
    assert (samples[:, 0] >= 0.5).all() and len(samples) == 50
    with pytest.raises(TaskError, match="no region 'h'"):
        task.in_region("h", samples)


def test_registry_names_files_projects_and_errors(tmp_path: Path) -> None:
    assert find_task("scoop").name == "scoop"
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "scoop.toml").write_text(BOX3 + '[sensors]\nq = "true"')
    local = find_task("scoop", project=tmp_path)  # a project's task shadows the bundled one
    assert local.dim == 3
    assert "scoop" in task_names(tmp_path)
    with pytest.raises(TaskError, match="unknown task 'nope'"):
        find_task("nope")
    with pytest.raises(TaskError, match="no such task file"):
        find_task(tmp_path / "missing.toml")


def test_entry_point_sensor_model_and_task(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                           ) -> None:
    """A plug-in distribution (written here: a module and its dist-info on sys.path) gives a
    Python sensor model to a task file and a whole task by name; evidence binds its source."""
    import importlib

    pkg = tmp_path / "site"
    pkg.mkdir()
    (pkg / "myplugin.py").write_text(
        "import numpy as np\n"
        "from tli_verify.tasks.taskfile import parse_task\n"
        "class Far:\n"
        "    sensor_names = ('far',)\n"
        "    latent_names = ()\n"
        "    cell_based = False\n"
        "    def initial_latent(self, batch):\n"
        "        return np.zeros((batch, 0), dtype=bool)\n"
        "    def read(self, x_prev, x, latent):\n"
        "        return (np.linalg.norm(x, axis=1) > 1.0)[:, None], latent\n"
        "def sensors(*, dim, partition):\n"
        "    return Far()\n"
        "def task():\n"
        "    return parse_task('name = \"coded\"\\nsensor_model = \"far-sensor\"\\n'\n"
        "                      '[state]\\nlower = [-2, -2]\\nupper = [2, 2]\\n')\n")
    info = pkg / "myplugin-1.2.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: myplugin\nVersion: 1.2\n")
    (info / "entry_points.txt").write_text(
        "[tli_verify.tasks]\nfar-sensor = myplugin:sensors\ncoded = myplugin:task\n")
    monkeypatch.syspath_prepend(str(pkg))
    importlib.invalidate_caches()
    text = 'name = "plug"\nsensor_model = "far-sensor"\n[state]\nlower = [-2, -2]\nupper = [2, 2]\n'
    task = _task(text, tmp_path)
    np.testing.assert_array_equal(task.sensors(np.array([[0.0, 0.0], [1.5, 0.0]]))[:, 0],
                                  [False, True])
    src = task.source
    assert src.entry_point == "far-sensor" and src.distribution == "myplugin"
    assert src.version == "1.2" and src.source_sha256 is not None and len(src.source_sha256) == 64
    with pytest.raises(TaskError, match="is not a task"):
        find_task("far-sensor")
    coded = find_task("coded")  # a whole task from Python, bound by its entry point
    assert coded.name == "coded" and coded.source.kind == "entry-point"
    assert coded.source.entry_point == "coded" and coded.source.distribution == "myplugin"
    sys.modules.pop("myplugin", None)


def test_clearance_is_exact_for_a_rotated_polytope_and_sound_for_composites() -> None:
    rng = np.random.default_rng(4)
    for n in (2, 3, 4, 5, 6):
        Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
        A = np.vstack([Q, -Q])
        b = np.concatenate([rng.uniform(0.5, 1.5, n), rng.uniform(0.5, 1.5, n)])
        text = (f'name = "p{n}"\n[state]\nlower = {[-3.0] * n}\nupper = {[3.0] * n}\n'
                f'[regions.p]\npolytope = {{ A = {A.tolist()}, b = {b.tolist()} }}\n'
                f'[regions.hole]\nball = {{ center = {[2.5] * n}, radius = 0.1 }}\n'
                '[sensors]\nq = "p"\n')
        task = parse_task(text)
        x = np.zeros(n)
        r = task.clearance(x)
        assert r == pytest.approx(float(np.min(b)), rel=1e-12)  # unit rows: distance = b_i
        # brute force: points at 0.999 r all read the same cell, a point at 1.001 r does not
        d = rng.normal(size=(2000, n))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        assert (task.region_index(x + 0.999 * r * d) == 0).all()
        k = int(np.argmin(b))
        assert task.region_index((x + 1.001 * r * A[k])[None])[0] != 0
    # a difference: the ball of the clearance stays in the region (a lower bound is sound)
    task = parse_task('name = "d"\n[state]\nlower = [-2, -2]\nupper = [2, 2]\n'
                      '[regions.ring]\ndifference = [{ ball = { center = [0, 0], radius = 1 } },'
                      ' { ball = { center = [0, 0], radius = 0.4 } }]\n[sensors]\nq = "ring"\n')
    x = np.array([0.7, 0.0])
    r = task.clearance(x)
    assert r == pytest.approx(0.3, rel=1e-9)
    ang = np.linspace(0, 2 * math.pi, 721)
    ring = x + 0.999 * r * np.column_stack([np.cos(ang), np.sin(ang)])
    assert (task.true_mode(ring) == "ring").all()
