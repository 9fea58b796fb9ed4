"""The task file: its format, :func:`load_task` and :func:`parse_task`.

A task file (TOML, schema ``tli_verify/schemas/task.schema.json``) declares everything the
closed loop, the campaigns and the pictures need about a user's task, in any dimension ``n``;
the spec (``specs/*.toml``) says what to do, the task says what the environment is. The paper's four
tasks ship as task files (``tasks/scoop.toml``, ``cooking.toml``, ``color-tracing.toml``,
``inspection.toml``). The format::

    name = "drawer"
    description = "approach the handle, pull the drawer open, retract"
    lag = 0                       # sensor lag in control steps
    dt = 0.01                     # control period (s); a certificate must cover it
    background = "free"           # the region of every state no listed region contains
    spec = "../specs/drawer.toml" # optional: the default spec of `tli run --task drawer`

    [state]
    names = ["x", "y", "z"]       # n = 3 (default names x0, x1, ...)
    lower = [-1.0, -1.0, 0.0]     # the workspace box
    upper = [1.0, 1.0, 1.0]

    [regions.handle]              # listed in priority order: a state is in the FIRST listed
    box = { lower = [0.4, -0.1, 0.3], upper = [0.6, 0.1, 0.5] }   # region holding it
    color = "#f7e27a"
    [regions.zone]
    ball = { center = [0, 0, 0.5], radius = 0.3 }
    layer = true                  # a layer: read by formulas, not a cell of the partition

    [latches.pulled]              # history: value = set | (prev(value) & !reset)
    initial = false
    set = "handle & prev(handle)"
    reset = "false"

    [sensors]                     # the spec's inputs: formulas over regions and latches
    h = "handle"
    p = "pulled & !handle"

    [goal]                        # what completes an episode (default: the automaton's
    modes = ["c"]                 # sink modes); sensors that must also read true
    sensors = []

    [starts]
    nominal = [[-0.5, 0.0, 0.5]]  # the default start of `tli verify`
    region = "free"               # random starts are drawn here (default: the workspace)

    [perturbations]               # the defaults of `tli verify`
    max_magnitude = 2.0           # default: the workspace's largest side
    window = 700
    max_pushes = 3

    [demonstrator]                # optional: `tli demos TASK` (tli_verify.tasks.demonstrator)
    count = 3
    duration = 8.0
    dt = 0.05
    sigma = 0.02
    [[demonstrator.scripts]]
    start = [-0.5, 0.0, 0.5]
    start_jitter = 0.05
    waypoints = [[0.5, 0.0, 0.4], [0.5, 0.0, 0.8]]
    jitter = [1.0, 0.0]

Sensor and latch formulas (:mod:`tli_verify.tasks.formula`) read a region name as "the state
lies in that cell of the partition" (or in that layer), ``prev(NAME)`` one step before (the
current state at the first step), a latch name as the latch's value: in a latch's own
``set``/``reset`` only latches declared before it may be read without ``prev``. Latches update
in order, then the sensors are read. A reading at control step ``k`` is computed from the state
``lag`` steps back.

A task may compute its sensors in Python instead (``sensor_model = "NAME"``: an entry point of
group ``tli_verify.tasks``, :mod:`tli_verify.tasks.registry`), for sensors physics computes.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation", CoRL 2022: Sec. 3 (modes as sets
of states sharing a sensor reading, sigma = L(alpha)), Sec. 7 and the appendices (the tasks),
Asm. 2 (finitely many perturbations).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.errors import TaskError, TliError
from tli_verify.io import check_numbers, parse_toml, read_text, validate_schema
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES
from tli_verify.logic.ltl import is_ap_name
from tli_verify.tasks import formula as fml
from tli_verify.tasks.demonstrator import parse_demonstrator
from tli_verify.tasks.fields import number, vector
from tli_verify.tasks.orientation import OrientationChart, parse_cone, parse_orientation
from tli_verify.tasks.plugins import entry_point, entry_point_source
from tli_verify.tasks.regions import Region, parse_region
from tli_verify.tasks.sensing import (
    FormulaSensors,
    Latch,
    PluginSensors,
    SensorModel,
    _raised,
)
from tli_verify.tasks.task import Task
from tli_verify.tasks.values import (
    DEFAULT_COLORS,
    MAX_LAG,
    MAX_LATCHES,
    MAX_REGIONS,
    MAX_SENSORS,
    MAX_TASK_DIM,
    TASK_KEYS,
    FloatArray,
    Goal,
    NamedRegion,
    Partition,
    PerturbationBounds,
    Starts,
    TaskSource,
)

__all__ = [
    "load_task",
    "parse_task",
]


def _keys(raw: Any, allowed: Sequence[str], where: str) -> Mapping[str, Any]:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: expected a table")
    unknown = sorted(set(raw) - set(allowed))
    if unknown:
        raise TaskError(f"{where}: unknown key {unknown[0]!r} (allowed: {', '.join(allowed)})")
    return raw


def _text(raw: Any, where: str, *, limit: int = 200, one_line: bool = True) -> str:
    if not isinstance(raw, str) or len(raw) > limit or (one_line and any(
            ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0 for ch in raw)):
        raise TaskError(f"{where}: expected {'one line of ' if one_line else ''}text of at "
                        f"most {limit} characters")
    return raw


def _name(raw: Any, where: str) -> str:
    if not isinstance(raw, str) or not fml.is_name(raw) or len(raw) > 64:
        raise TaskError(f"{where}: {raw!r} is not a valid name (an identifier: letters, "
                        "digits and _, not true/false/prev, at most 64 characters)")
    return raw


def load_task(path: str | os.PathLike[str], *,
              entry_points: Callable[[str], object] | None = None) -> Task:
    """Load and validate a task file.

    Parameters
    ----------
    path : path-like
    entry_points : callable, optional
        ``name -> object`` resolving a ``sensor_model`` entry point (default:
        :func:`tli_verify.tasks.plugins.entry_point`).

    Raises
    ------
    TaskError
        (exit 2) Naming the file and the field of the first problem.
    """
    text = read_text(path, what="task", error=TaskError)
    return parse_task(text, path=str(path), entry_points=entry_points)


def parse_task(text: str, *, path: str | None = None,
               entry_points: Callable[[str], Any] | None = None) -> Task:
    """Parse the TOML text of a task file (module docstring).

    Raises
    ------
    TaskError
        (exit 2) Naming the file and the field.
    """
    where = path or "<task>"
    if not text.strip():
        raise TaskError(f"{where}: empty task file")
    data = parse_toml(text, where=where, error=TaskError)
    check_numbers(data, where=where, error=TaskError)
    task = _build(data, where, text, path, entry_points)
    validate_schema(data, "task.schema.json", where=where, error=TaskError)
    return task


def _build(data: Mapping[str, Any], where: str, text: str, path: str | None,
           entry_points: Callable[[str], Any] | None) -> Task:
    _keys(data, TASK_KEYS, where)
    if "name" not in data:
        raise TaskError(f"{where}: missing 'name'")
    name = _text(data["name"], f"{where}: name", limit=100)
    if not name.strip():
        raise TaskError(f"{where}: name: must not be empty")
    description = _text(data.get("description", ""), f"{where}: description", limit=10_000,
                        one_line=False)
    if "state" not in data:
        raise TaskError(f"{where}: missing the [state] table (the workspace box: lower, upper; "
                        "optional names)")
    st = _keys(data["state"], ("names", "lower", "upper", "orientation"), f"{where}: [state]")
    for k in ("lower", "upper"):
        if k not in st:
            raise TaskError(f"{where}: state.{k}: missing (the workspace box)")
    if not isinstance(st["lower"], list) or not 1 <= len(st["lower"]) <= MAX_TASK_DIM:
        raise TaskError(f"{where}: state.lower: expected 1 to {MAX_TASK_DIM} numbers (the "
                        "dimension n)")
    dim = len(st["lower"])
    lo = vector(st["lower"], dim, f"{where}: state.lower")
    hi = vector(st["upper"], dim, f"{where}: state.upper")
    if not np.all(lo < hi):
        raise TaskError(f"{where}: state: the workspace box needs lower < upper in every "
                        "coordinate")
    names_raw = st.get("names", [f"x{i}" for i in range(dim)])
    if not isinstance(names_raw, list) or len(names_raw) != dim:
        raise TaskError(f"{where}: state.names: expected {dim} names (one per coordinate)")
    state_names = tuple(_text(v, f"{where}: state.names[{i}]", limit=64)
                        for i, v in enumerate(names_raw))
    if len(set(state_names)) != dim:
        raise TaskError(f"{where}: state.names: names must be distinct")
    chart = (parse_orientation(st["orientation"], lo, hi, f"{where}: state.orientation")
             if "orientation" in st else None)
    lag = number(data.get("lag", 0), f"{where}: lag", lo=0, hi=MAX_LAG, integer=True)
    dt = number(data.get("dt", DEFAULT_DT_FLOAT), f"{where}: dt", lo=1e-6, hi=10.0)
    if dt <= 0:
        raise TaskError(f"{where}: dt: must be > 0")
    background = _name(data.get("background", "outside"), f"{where}: background")
    bg_color = _color(data.get("background_color", "#ffffff"), f"{where}: background_color")
    partition = _partition(data.get("regions", {}), dim, background, bg_color, where,
                           chart=chart)
    region_names = set(partition.names) | {la.name for la in partition.layers}
    model: SensorModel
    source = TaskSource("file" if path is not None else "code", path=path,
                        sha256=hashlib.sha256(text.encode("utf-8")).hexdigest()
                        if path is not None else None)
    if "sensor_model" in data:
        for key in ("sensors", "latches"):
            if key in data:
                raise TaskError(f"{where}: [{key}] and sensor_model: the sensors come from one "
                                "of them")
        ep = _text(data["sensor_model"], f"{where}: sensor_model", limit=100)
        model, source = _entry_sensor_model(ep, where, source, entry_points, dim, partition)
    else:
        latches = _latches(data.get("latches", {}), region_names, where)
        model = FormulaSensors(partition, _sensor_formulas(data.get("sensors"), region_names,
                                                          latches, where), latches)
    goal = _goal(data.get("goal", {}), model.sensor_names, where)
    starts = _starts(data.get("starts", {}), dim, lo, hi, partition, where)
    pert = _perturbations(data.get("perturbations", {}), where)
    demo = (parse_demonstrator(data["demonstrator"], dim=dim, where=where)
            if "demonstrator" in data else None)
    spec = data.get("spec")
    if spec is not None:
        spec = _text(spec, f"{where}: spec", limit=1000)
    return Task(name=name, description=description, state_names=state_names,
                lo=tuple(lo.tolist()), hi=tuple(hi.tolist()), partition=partition,
                sensor_model=model, lag=int(lag), dt=dt, goal=goal, starts=starts,
                perturbations=pert, demonstrator=demo, source=source, spec=spec,
                orientation=chart)


def _color(raw: Any, where: str) -> str:
    from matplotlib.colors import is_color_like

    if not isinstance(raw, str) or len(raw) > 40 or not is_color_like(raw):
        raise TaskError(f"{where}: {raw!r} is not a colour (e.g. \"#f7e27a\" or \"tab:blue\")")
    return raw


def _partition(raw: Any, dim: int, background: str, bg_color: str, where: str, *,
               chart: OrientationChart | None = None) -> Partition:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: [regions]: expected a table of regions")
    if len(raw) > MAX_REGIONS:
        raise TaskError(f"{where}: more than {MAX_REGIONS} regions")
    built: dict[str, Region] = {}
    busy: list[str] = []

    def cone(table: Any, at: str) -> Region:
        return parse_cone(table, dim=dim, chart=chart, where=at)

    def named(ref: str, at: str) -> Region:
        if ref in built:
            return built[ref]
        if ref in busy:
            raise TaskError(f"{at}: region {ref!r} is defined in terms of itself "
                            f"({' -> '.join([*busy, ref])})")
        if ref not in raw:
            raise TaskError(f"{at}: unknown region {ref!r} (regions: "
                            f"{', '.join(raw) or 'none'})")
        return make(ref)

    def make(rname: str) -> Region:
        busy.append(rname)
        table = raw[rname]
        at = f"{where}: regions.{rname}"
        if not isinstance(table, dict):
            raise TaskError(f"{at}: expected a table with a shape key")
        shape = {k: v for k, v in table.items() if k not in ("color", "layer")}
        region = parse_region(shape, dim=dim, where=at, named=named, shapes={"cone": cone})
        busy.pop()
        built[rname] = region
        return region

    cells: list[NamedRegion] = []
    layers: list[NamedRegion] = []
    for i, rname in enumerate(raw):
        at = f"{where}: regions.{rname}"
        _name(rname, at)
        if rname == background:
            raise TaskError(f"{at}: {rname!r} is the background's name")
        region = named(rname, at)
        table = raw[rname]
        color = _color(table.get("color", DEFAULT_COLORS[i % len(DEFAULT_COLORS)]),
                       f"{at}.color")
        layer = table.get("layer", False)
        if not isinstance(layer, bool):
            raise TaskError(f"{at}.layer: expected true or false")
        (layers if layer else cells).append(NamedRegion(rname, region, color, layer))
    return Partition(tuple(cells), background, bg_color, tuple(layers))


def _latches(raw: Any, regions: set[str], where: str) -> tuple[Latch, ...]:
    if not isinstance(raw, dict):
        raise TaskError(f"{where}: [latches]: expected a table of latches")
    if len(raw) > MAX_LATCHES:
        raise TaskError(f"{where}: more than {MAX_LATCHES} latches")
    names = list(raw)
    out: list[Latch] = []
    for i, lname in enumerate(names):
        at = f"{where}: latches.{lname}"
        _name(lname, at)
        if lname in regions:
            raise TaskError(f"{at}: {lname!r} is also a region's name")
        table = _keys(raw[lname], ("initial", "set", "reset"), at)
        initial = table.get("initial", False)
        if not isinstance(initial, bool):
            raise TaskError(f"{at}.initial: expected true or false")
        if "set" not in table:
            raise TaskError(f"{at}: missing 'set' (the formula that sets it)")
        every = regions | set(names)
        later = set(names[i:])
        parsed = []
        for key in ("set", "reset"):
            f = fml.parse(table.get(key, "false"), names=every, where=f"{at}.{key}")
            early = sorted(f.now & later)
            if early:
                raise TaskError(f"{at}.{key}: {f.text!r} reads latch {early[0]!r} before it "
                                f"is updated: write prev({early[0]}) (latches update in the "
                                "order listed)")
            parsed.append(f)
        out.append(Latch(lname, initial, parsed[0], parsed[1]))
    return tuple(out)


def _sensor_formulas(raw: Any, regions: set[str], latches: tuple[Latch, ...], where: str
                     ) -> tuple[tuple[str, fml.Formula], ...]:

    if not isinstance(raw, dict) or not raw:
        raise TaskError(f"{where}: [sensors]: expected a table sensor = formula (the spec's "
                        "inputs)")
    if len(raw) > MAX_SENSORS:
        raise TaskError(f"{where}: more than {MAX_SENSORS} sensors")
    names = regions | {la.name for la in latches}
    out = []
    for sname, text in raw.items():
        at = f"{where}: sensors.{sname}"
        if not is_ap_name(sname):
            raise TaskError(f"{at}: {sname!r} is not a valid sensor (spec input) name")
        out.append((sname, fml.parse(text, names=names, where=at)))
    return tuple(out)


def _goal(raw: Any, sensors: Sequence[str], where: str) -> Goal:
    t = _keys(raw, ("modes", "sensors"), f"{where}: [goal]")
    modes_raw = t.get("modes", "sinks")
    modes: tuple[str, ...] | None
    if modes_raw == "sinks":
        modes = None
    elif isinstance(modes_raw, list) and modes_raw and all(isinstance(m, str) for m in modes_raw):
        modes = tuple(modes_raw)
    else:
        raise TaskError(f"{where}: goal.modes: expected \"sinks\" or a non-empty list of mode "
                        "names")
    gs = t.get("sensors", [])
    if not isinstance(gs, list) or not all(isinstance(s, str) for s in gs):
        raise TaskError(f"{where}: goal.sensors: expected a list of sensor names")
    unknown = [s for s in gs if s not in sensors]
    if unknown:
        raise TaskError(f"{where}: goal.sensors: {unknown[0]!r} is not a sensor of the task "
                        f"({', '.join(sensors)})")
    return Goal(modes, tuple(gs))


def _starts(raw: Any, dim: int, lo: FloatArray, hi: FloatArray, partition: Partition,
            where: str) -> Starts:
    t = _keys(raw, ("nominal", "region", "random"), f"{where}: [starts]")
    nominal_raw = t.get("nominal", [])
    if not isinstance(nominal_raw, list) or len(nominal_raw) > 1000:
        raise TaskError(f"{where}: starts.nominal: expected a list of at most 1000 states")
    nominal = []
    for i, p in enumerate(nominal_raw):
        x = vector(p, dim, f"{where}: starts.nominal[{i}]")
        if not np.all((x >= lo) & (x <= hi)):
            raise TaskError(f"{where}: starts.nominal[{i}]: {x.tolist()} is outside the "
                            "workspace")
        nominal.append(tuple(x.tolist()))
    region = t.get("region")
    known = set(partition.names) | {la.name for la in partition.layers}
    if region is not None and region not in known:
        raise TaskError(f"{where}: starts.region: unknown region {region!r} (regions: "
                        f"{', '.join(sorted(known))})")
    if region is not None:  # random starts are drawn in its box within the workspace
        for nr in (*partition.cells, *partition.layers):
            if nr.name == region:
                rlo, rhi = nr.region.bounds()
                if not np.all(np.maximum(lo, rlo) <= np.minimum(hi, rhi)):
                    raise TaskError(f"{where}: starts.region: region {region!r} lies outside "
                                    "the workspace: no start can be drawn in it")
    random = t.get("random", False)
    if not isinstance(random, bool):
        raise TaskError(f"{where}: starts.random: expected true or false, got {random!r}")
    return Starts(tuple(nominal), region, random)


def _perturbations(raw: Any, where: str) -> PerturbationBounds:

    t = _keys(raw, ("max_magnitude", "window", "max_pushes"), f"{where}: [perturbations]")
    mag = t.get("max_magnitude")
    return PerturbationBounds(
        max_magnitude=None if mag is None else number(mag, f"{where}: perturbations."
                                                      "max_magnitude", lo=0.0, hi=1e6),
        window=int(number(t.get("window", 700), f"{where}: perturbations.window", lo=1,
                          hi=MAX_CAMPAIGN_STEPS, integer=True)),
        max_pushes=int(number(t.get("max_pushes", 3), f"{where}: perturbations.max_pushes",
                              lo=0, hi=MAX_PUSHES, integer=True)))


def _entry_sensor_model(name: str, where: str, source: TaskSource,
                        entry_points: Callable[[str], Any] | None, dim: int,
                        partition: Partition) -> tuple[SensorModel, TaskSource]:

    resolve = entry_points or entry_point
    try:
        obj = resolve(name)
    except TliError as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: {exc}") from None
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit too: a plug-in never ends the process
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point does not load "
                        f"({_raised(exc)})") from None
    try:
        model = obj(dim=dim, partition=partition)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point failed to build a "
                        f"sensor model ({_raised(exc)})") from None
    try:
        conforms = isinstance(model, SensorModel)  # reads its attributes (properties run)
    except KeyboardInterrupt:
        raise
    except BaseException as exc:
        raise TaskError(f"{where}: sensor_model {name!r}: reading the sensor model's "
                        f"attributes raised {_raised(exc)}") from None
    if not conforms:
        raise TaskError(f"{where}: sensor_model {name!r}: the entry point returned "
                        f"{type(model).__name__}, not a sensor model (sensor_names, "
                        "latent_names, cell_based, initial_latent, read)")
    model = PluginSensors(model, name=name, where=where)
    info = entry_point_source(name) if entry_points is None else {}
    return model, replace(source, entry_point=name, distribution=info.get("distribution"),
                          version=info.get("version"), source_sha256=info.get("source_sha256"))

