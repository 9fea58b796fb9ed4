"""GR(1) task specifications: the TOML file format and the :class:`GR1Spec` value.

A spec file names the sensor inputs (environment APs), the mode outputs (system APs), an
optional ``[modes]`` table (the sensor state that labels each mode, paper Sec. 3:
``sigma = L(alpha)``) and the assumption ``phi_e`` and guarantee ``phi_s`` of the GR(1) formula
``phi_e -> phi_s`` (paper Sec. 4.2, eq. 3)::

    name = "soup-scooping"
    inputs  = ["r", "s", "t"]
    outputs = ["a", "b", "c", "d"]
    [modes]
    a = "!r & !s & !t"
    [assume]
    init = "!r & !s & !t"
    safety = ["G(...)"]
    liveness = ["GF(!a | r)"]
    [guarantee]
    init = "a"
    safety = ["G(a -> X(a | b))"]
    liveness = ["GF d"]

With a ``[modes]`` table the tool adds the mode constraints itself (``docs/design.md``, "Modes are
labels of sensor states"): exactly one mode at a time and a mode only where its label holds
(guarantees), and sensors that always show some mode's label (an assumption, paper Asm. 3).
``tli spec check --explain`` lists them.

``task = "NAME"`` (or a path to a task file, relative to the spec) names the task whose sensors
the spec's inputs are (:mod:`tli_verify.tasks`); ``[goal]`` (``modes = ["d"]``, ``sensors =
["rel"]``) says what completes an episode when it is not the automaton's sink modes (a cyclic
task), and overrides the task's goal.

``expect = "unrealizable"`` marks a spec shipped on purpose as an unrealizable example, and
``expect = "not-well-separated"`` one that is realizable only vacuously; the default is
``"realizable"`` (and well-separated). The deployment gate checks that every spec's verdict
matches its expectation.

``semantics = "textbook"`` decides the game in the reading of Spectra and slugs, where a
safety formula constrains only the transitions (``docs/explanation/logic.md``, "Two readings
of safety at time 0"); the default ``"tli"`` also applies each side's safety formulas to the
initial state (their current-state consequence). ``tli spec import`` writes ``"textbook"``.
"""

from __future__ import annotations

import bisect
import dataclasses
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.io import check_numbers, parse_toml, read_text
from tli_verify.logic.ltl import (
    MAX_FORMULA_DEPTH,
    Slot,
    atomic_propositions,
    classify,
    is_ap_name,
    parse_formula,
)
from tli_verify.snapshot import current

__all__ = [
    "GR1Spec",
    "SpecFormula",
    "SpecSide",
    "label_holds",
    "load_spec",
    "parse_spec",
]

_TOP_KEYS = frozenset(
    {"name", "description", "inputs", "outputs", "modes", "assume", "guarantee", "expect",
     "task", "goal", "semantics"}
)
_SIDE_KEYS = frozenset({"init", "safety", "liveness"})
EXPECTATIONS = ("realizable", "unrealizable", "not-well-separated")
SEMANTICS = ("tli", "textbook")
"""Readings of ``G(phi)`` at time 0 (``docs/explanation/logic.md``, "Two readings of safety
at time 0"): ``"tli"`` (the default) or ``"textbook"`` (Spectra's and slugs')."""
MAX_TOML_DEPTH = 16
"""Deepest nesting of TOML arrays and tables accepted in a spec (a spec needs 3)."""


@dataclass(frozen=True, slots=True)
class SpecFormula:
    """One formula of a spec, with where it came from.

    Attributes
    ----------
    text : str
        The formula as written (or as added by the tool).
    section : str
        ``"assume.safety"``, ``"guarantee.liveness"``, ... .
    index : int
        Position in its section's list (0 for a single ``init`` string).
    line : int or None
        Line in the spec file, when the formula is written there.
    origin : str
        ``"file"`` or ``"modes"`` (added by the tool from the ``[modes]`` table).
    ltl : spot.formula
        The parsed formula.
    """

    text: str
    section: str
    index: int
    line: int | None
    origin: str
    ltl: Any = field(compare=False, repr=False)

    @property
    def label(self) -> str:
        """``section[index]``, e.g. ``guarantee.safety[2]``."""
        return f"{self.section}[{self.index}]"

    def where(self, path: str | None) -> str:
        """``file:line section[index]`` for messages."""
        loc = path or "<spec>"
        if self.line is not None:
            loc = f"{loc}:{self.line}"
        tag = self.label if self.origin == "file" else f"{self.label} (added from [modes])"
        return f"{loc} {tag}"


@dataclass(frozen=True, slots=True)
class SpecSide:
    """One side of the GR(1) formula: ``phi^e`` (assume) or ``phi^s`` (guarantee)."""

    init: tuple[SpecFormula, ...] = ()
    safety: tuple[SpecFormula, ...] = ()
    liveness: tuple[SpecFormula, ...] = ()

    def all(self) -> tuple[SpecFormula, ...]:
        """Every formula of this side."""
        return self.init + self.safety + self.liveness


@dataclass(frozen=True, slots=True)
class GR1Spec:
    """A GR(1) task specification ``phi_e -> phi_s`` (paper eq. 3).

    Attributes
    ----------
    name : str
        Task name.
    inputs : tuple of str
        Environment APs (sensors).
    outputs : tuple of str
        System APs (modes, and any auxiliary system variables).
    modes : dict of str to str, or None
        Mode name -> propositional formula over ``inputs`` labelling it; None for a plain
        GR(1) spec.
    assume, guarantee : SpecSide
        ``phi^e`` and ``phi^s``, including the formulas added from ``[modes]``.
    path : str or None
        The file it was loaded from.
    expect : str
        ``"realizable"`` (default: realizable and well-separated), ``"unrealizable"`` or
        ``"not-well-separated"`` (shipped on purpose as a bad example).
    description : str
        Free text.
    task : str or None
        The task the spec is written over: a task name, or a task file relative to the spec.
    goal_modes : tuple of str or None
        Modes that complete an episode (``[goal] modes``; None: not given).
    goal_sensors : tuple of str
        Sensors that must also read true there (``[goal] sensors``).
    semantics : str
        ``"tli"`` (default) or ``"textbook"``: the reading of safety at time 0
        (:data:`SEMANTICS`).
    """

    name: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    modes: dict[str, str] | None
    assume: SpecSide
    guarantee: SpecSide
    path: str | None = None
    expect: str = "realizable"
    description: str = ""
    task: str | None = None
    goal_modes: tuple[str, ...] | None = None
    goal_sensors: tuple[str, ...] = ()
    semantics: str = "tli"

    @property
    def expect_realizable(self) -> bool:
        """False for specs shipped on purpose as unrealizable examples."""
        return self.expect != "unrealizable"

    @property
    def mode_names(self) -> tuple[str, ...]:
        """The outputs that are modes (all outputs without a ``[modes]`` table)."""
        if self.modes is None:
            return self.outputs
        return tuple(o for o in self.outputs if o in self.modes)

    def formulas(self) -> tuple[SpecFormula, ...]:
        """Every formula, assumptions first."""
        return self.assume.all() + self.guarantee.all()

    def added(self) -> tuple[SpecFormula, ...]:
        """The formulas the tool added from the ``[modes]`` table."""
        return tuple(f for f in self.formulas() if f.origin == "modes")


def load_spec(path: str | os.PathLike[str]) -> GR1Spec:
    """Load and validate a spec file.

    Parameters
    ----------
    path : path-like
        A TOML spec file (format: the module docstring).

    Returns
    -------
    GR1Spec

    Raises
    ------
    SpecError
        Naming the file, line and field of the first problem.
    """
    text = read_text(path, what="spec", error=SpecError)
    snap = current()
    if snap is None:
        return parse_spec(text, path=str(path), default_name=Path(path).stem)
    spec = snap.parse("spec", path,
                      lambda: parse_spec(text, path=str(path), default_name=Path(path).stem))
    return spec if spec.path == str(path) else dataclasses.replace(spec, path=str(path))


def parse_spec(text: str, *, path: str | None = None, default_name: str = "spec") -> GR1Spec:
    """Parse the TOML text of a spec (see the module docstring for the format)."""
    where = path or "<spec>"
    if not text.strip():
        raise SpecError(f"{where}: empty spec file")
    data = parse_toml(text, where=where, error=SpecError,
                      nested=lambda: (f"{where}:{_deep_line(text)}: arrays or tables nested "
                                      f"deeper than the limit of {MAX_TOML_DEPTH} levels"))
    deep = _too_deep(data)
    if deep is not None:
        raise SpecError(f"{where}: '{deep}': arrays or tables nested deeper than the limit of "
                        f"{MAX_TOML_DEPTH} levels")

    check_numbers(data, where=where, error=SpecError)
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise SpecError(f"{where}: unknown top-level key {unknown[0]!r} "
                        f"(allowed: {', '.join(sorted(_TOP_KEYS))})")
    lines = _LineFinder(text)
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise SpecError(f"{where}: 'name' must be a non-empty string")
    if any(ord(ch) < 0x20 or 0x7F <= ord(ch) < 0xA0 for ch in name):
        raise SpecError(f"{where}:{lines.key('name') or 1}: 'name' must be one line without "
                        "control characters")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise SpecError(f"{where}: 'description' must be a string")
    expect = data.get("expect", "realizable")
    if expect not in EXPECTATIONS:
        raise SpecError(f"{where}: 'expect' must be one of {', '.join(EXPECTATIONS)}")
    semantics = data.get("semantics", "tli")
    if semantics not in SEMANTICS:
        raise SpecError(f"{where}:{lines.key('semantics') or 1}: 'semantics' must be one of "
                        f"{', '.join(repr(s) for s in SEMANTICS)}")
    inputs = _ap_list(data, "inputs", where, lines)
    outputs = _ap_list(data, "outputs", where, lines)
    both = sorted(set(inputs) & set(outputs))
    if both:
        raise SpecError(f"{where}:{lines.key('inputs')}: AP {both[0]!r} is both an input and "
                        "an output")
    if not outputs:
        raise SpecError(f"{where}: 'outputs' must name at least one system AP")
    modes = _modes(data.get("modes"), inputs, outputs, where, lines)
    memo: dict[int, tuple[int, int, Any]] = {}  # formula sizes, shared by the formulas
    assume = _side(data.get("assume", {}), "assume", inputs, outputs, where, lines, memo)
    guarantee = _side(data.get("guarantee", {}), "guarantee", inputs, outputs, where, lines,
                      memo)
    if modes is not None:
        assume, guarantee = _add_mode_constraints(modes, outputs, assume, guarantee)
    task = data.get("task")
    if task is not None and (not isinstance(task, str) or not task.strip() or len(task) > 1000
                             or any(ord(ch) < 0x20 for ch in task)):
        raise SpecError(f"{where}:{lines.key('task') or 1}: 'task' must be a task name or a "
                        "task file path (one line)")
    goal_modes, goal_sensors = _goal(data.get("goal"), inputs, outputs, modes, where, lines)
    return GR1Spec(
        name=name,
        inputs=inputs,
        outputs=outputs,
        modes=modes,
        assume=assume,
        guarantee=guarantee,
        path=path,
        expect=expect,
        description=description,
        task=task,
        goal_modes=goal_modes,
        goal_sensors=goal_sensors,
        semantics=semantics,
    )


def _goal(raw: Any, inputs: tuple[str, ...], outputs: tuple[str, ...],
          modes: dict[str, str] | None, where: str, lines: _LineFinder
          ) -> tuple[tuple[str, ...] | None, tuple[str, ...]]:
    """The ``[goal]`` table: goal modes (outputs that are modes) and goal sensors (inputs)."""
    if raw is None:
        return None, ()
    loc = f"{where}:{lines.section('goal') + 1}"
    if not isinstance(raw, dict):
        raise SpecError(f"{loc}: [goal] must be a table with modes and sensors")
    unknown = sorted(set(raw) - {"modes", "sensors"})
    if unknown:
        raise SpecError(f"{loc}: [goal]: unknown key {unknown[0]!r} (allowed: modes, sensors)")
    mode_names = tuple(o for o in outputs if modes is None or o in modes)
    gm = raw.get("modes")
    if gm is not None and (not isinstance(gm, list) or not gm
                           or not all(isinstance(m, str) for m in gm)):
        raise SpecError(f"{loc}: goal.modes: expected a non-empty list of mode names")
    for m in gm or ():
        if m not in mode_names:
            raise SpecError(f"{loc}: goal.modes: {m!r} is not a mode of the spec "
                            f"({', '.join(mode_names)})")
    gs = raw.get("sensors", [])
    if not isinstance(gs, list) or not all(isinstance(v, str) for v in gs):
        raise SpecError(f"{loc}: goal.sensors: expected a list of input names")
    for v in gs:
        if v not in inputs:
            raise SpecError(f"{loc}: goal.sensors: {v!r} is not an input of the spec "
                            f"({', '.join(inputs)})")
    return (None if gm is None else tuple(gm)), tuple(gs)


def _too_deep(data: Any) -> str | None:
    """The top-level key of a value nested deeper than ``MAX_TOML_DEPTH`` (no recursion)."""
    stack: list[tuple[str, Any, int]] = [(str(k), v, 1) for k, v in data.items()]
    while stack:
        key, value, depth = stack.pop()
        if depth > MAX_TOML_DEPTH:
            return key
        if isinstance(value, dict):
            stack.extend((key, v, depth + 1) for v in value.values())
        elif isinstance(value, list):
            stack.extend((key, v, depth + 1) for v in value)
    return None


def _deep_line(text: str) -> int:
    """Best-effort line where bracket nesting first exceeds ``MAX_TOML_DEPTH``."""
    depth = 0
    for number, line in enumerate(text.splitlines(), start=1):
        for ch in line:
            depth += (ch in "[{") - (ch in "]}")
            if depth > MAX_TOML_DEPTH:
                return number
    return 1


def label_holds(spec: GR1Spec, mode: str, sensors: Mapping[str, bool]) -> bool:
    """Whether mode ``mode``'s sensor label holds for the reading ``sensors``.

    Parameters
    ----------
    spec : GR1Spec
        A spec with a ``[modes]`` table.
    mode : str
        A mode name.
    sensors : mapping of str to bool
        Value of every input AP.
    """
    if spec.modes is None or mode not in spec.modes:
        raise SpecError(f"{spec.path or '<spec>'}: mode {mode!r} has no label in [modes]")
    missing = [i for i in spec.inputs if i not in sensors]
    if missing:
        raise SpecError(f"sensor reading lacks input {missing[0]!r}")
    return _eval_bool(parse_formula(spec.modes[mode], where=f"modes.{mode}"), sensors)


def _eval_bool(f: Any, values: Mapping[str, bool]) -> bool:
    from tli_verify.logic.spot_import import spot

    kind = f.kind()
    if kind == spot.op_tt:
        return True
    if kind == spot.op_ff:
        return False
    if kind == spot.op_ap:
        return bool(values[str(f.ap_name())])
    args = [_eval_bool(c, values) for c in f]
    if kind == spot.op_Not:
        return not args[0]
    if kind == spot.op_And:
        return all(args)
    if kind == spot.op_Or:
        return any(args)
    if kind == spot.op_Implies:
        return (not args[0]) or args[1]
    if kind == spot.op_Equiv:
        return args[0] == args[1]
    if kind == spot.op_Xor:
        return args[0] != args[1]
    raise SpecError(f"{f}: not a propositional formula")


class _LineFinder:
    """Best-effort line numbers for values in a TOML text (tomllib keeps none)."""

    def __init__(self, text: str) -> None:
        self.lines = text.splitlines()
        # The lines joined by "\n" and where each starts, so that :meth:`value` searches in
        # C (``str.find``) instead of line by line: a spec of n formulas over n lines cost
        # O(n^2) Python steps, most of the fixed cost of an imported spec.
        self._joined = "\n".join(self.lines)
        self._starts = [0]
        for line in self.lines[:-1]:
            self._starts.append(self._starts[-1] + len(line) + 1)

    def section(self, name: str) -> int:
        for i, line in enumerate(self.lines):
            if line.strip().replace(" ", "") == f"[{name}]":
                return i
        return 0

    def key(self, key: str, start: int = 0) -> int | None:
        for i in range(start, len(self.lines)):
            stripped = self.lines[i].lstrip()
            if stripped.startswith(key) and stripped[len(key):].lstrip().startswith("="):
                return i + 1
        return None

    def value(self, value: str, start: int = 0) -> int | None:
        """The first line at or after ``start`` (0-based) that contains ``value`` quoted
        (``"..."``, then ``'...'``), else unquoted; 1-based, None if no line does."""
        if start >= len(self.lines) or (value and value.splitlines() != [value]):
            return None  # no line contains a line break
        for quoted in (f'"{value}"', f"'{value}'", value):
            pos = self._joined.find(quoted, self._starts[start])
            if pos >= 0:
                return bisect.bisect_right(self._starts, pos)
        return None


def _ap_list(data: Mapping[str, Any], key: str, where: str, lines: _LineFinder
             ) -> tuple[str, ...]:
    raw = data.get(key, [])
    line = lines.key(key)
    loc = f"{where}:{line}" if line else where
    if not isinstance(raw, list) or not all(isinstance(v, str) for v in raw):
        raise SpecError(f"{loc}: '{key}' must be a list of strings")
    seen: set[str] = set()
    for name in raw:
        if not is_ap_name(name):
            raise SpecError(f"{loc}: '{key}': {name!r} is not a valid AP name (lower-case "
                            "identifier, not true/false)")
        if name in seen:
            raise SpecError(f"{loc}: '{key}': {name!r} listed twice")
        seen.add(name)
    return tuple(raw)


def _modes(raw: Any, inputs: tuple[str, ...], outputs: tuple[str, ...], where: str,
           lines: _LineFinder) -> dict[str, str] | None:
    if raw is None:
        return None
    start = lines.section("modes")
    if not isinstance(raw, dict) or not raw:
        raise SpecError(f"{where}:{start + 1}: [modes] must be a non-empty table mode = label")
    modes: dict[str, str] = {}
    for mode, label in raw.items():
        line = lines.key(mode, start)
        loc = f"{where}:{line}" if line else where
        if mode not in outputs:
            raise SpecError(f"{loc}: modes.{mode}: {mode!r} is not an output")
        if not isinstance(label, str):
            raise SpecError(f"{loc}: modes.{mode}: label must be a formula string")
        f = parse_formula(label, where=f"{loc}: modes.{mode}")
        if not f.is_boolean():
            raise SpecError(f"{loc}: modes.{mode}: {label!r}: not propositional")
        extra = sorted(atomic_propositions(f) - set(inputs))
        if extra:
            kind = "an output" if extra[0] in outputs else "unknown AP"
            raise SpecError(f"{loc}: modes.{mode}: label uses {kind} {extra[0]!r}; labels "
                            "are formulas over the inputs")
        modes[mode] = str(f)
    return modes


def _as_list(raw: Any, loc: str, *, allow_str: bool) -> list[str]:
    if isinstance(raw, str) and allow_str:
        return [raw]
    if isinstance(raw, list) and all(isinstance(v, str) for v in raw):
        return list(raw)
    what = "a formula string or a list of them" if allow_str else "a list of formula strings"
    raise SpecError(f"{loc}: must be {what}")


def _side(raw: Any, side: str, inputs: tuple[str, ...], outputs: tuple[str, ...], where: str,
          lines: _LineFinder, memo: dict[int, tuple[int, int, Any]] | None = None
          ) -> SpecSide:
    start = lines.section(side)
    if not isinstance(raw, dict):
        raise SpecError(f"{where}:{start + 1}: [{side}] must be a table")
    unknown = sorted(set(raw) - _SIDE_KEYS)
    if unknown:
        raise SpecError(f"{where}:{start + 1}: [{side}]: unknown key {unknown[0]!r} "
                        "(allowed: init, safety, liveness)")
    known = set(inputs) | set(outputs)
    parts: dict[str, tuple[SpecFormula, ...]] = {}
    for slot in Slot:
        key = slot.value
        line = lines.key(key, start)
        items = _as_list(raw.get(key, []), f"{where}:{line or start + 1}: {side}.{key}",
                         allow_str=slot is Slot.INIT)
        formulas = []
        for i, text in enumerate(items):
            fline = lines.value(text, start) or line
            loc = f"{where}:{fline}" if fline else where
            tag = f"{loc}: {side}.{key}[{i}]"
            f = parse_formula(text, where=tag, memo=memo)
            classify(f, slot, where=tag)
            aps = atomic_propositions(f)
            unknown_aps = sorted(aps - known)
            if unknown_aps:
                raise SpecError(f"{tag}: unknown AP {unknown_aps[0]!r} (declare it in inputs "
                                "or outputs)")
            if side == "assume":
                _check_assumption_vars(f, outputs, slot, tag)
            formulas.append(SpecFormula(text=text, section=f"{side}.{key}", index=i,
                                        line=fline, origin="file", ltl=f))
        parts[key] = tuple(formulas)
    return SpecSide(init=parts["init"], safety=parts["safety"], liveness=parts["liveness"])


def _check_assumption_vars(f: Any, outputs: tuple[str, ...], slot: Slot, tag: str) -> None:
    """Assumptions may not constrain the system's initial or next values."""
    from tli_verify.logic.spot_import import spot

    outs = set(outputs)
    if slot is Slot.INIT:
        used = sorted(atomic_propositions(f) & outs)
        if used:
            raise SpecError(f"{tag}: the environment's initial condition mentions output "
                            f"{used[0]!r}; it may use inputs only")
        return

    def visit(g: Any, under_x: bool) -> None:
        if g.kind() == spot.op_X:
            visit(g[0], True)
            return
        if g.kind() == spot.op_ap and under_x and str(g.ap_name()) in outs:
            raise SpecError(f"{tag}: the assumption constrains the next value of output "
                            f"{g.ap_name()!s} (X {g.ap_name()!s}); assumptions may refer to "
                            "next inputs only")
        for c in g:
            visit(c, under_x)

    visit(f, False)


def _exactly_one(names: Iterable[str]) -> str:
    names = list(names)
    if len(names) == 1:
        return names[0]
    terms = []
    for n in names:
        terms.append(" & ".join(n if m == n else f"!{m}" for m in names))
    return " | ".join(f"({t})" for t in terms)


def _add_mode_constraints(modes: dict[str, str], outputs: tuple[str, ...], assume: SpecSide,
                          guarantee: SpecSide) -> tuple[SpecSide, SpecSide]:
    """The constraints a ``[modes]`` table stands for (``docs/design.md``, "Modes are labels").

    Each is stated on the initial state and on every next state (``G(X ...)``), so that it
    constrains the move that enters a state: a system that runs two modes, or a mode whose
    label does not hold, has made an illegal move, even where that would also leave the
    environment without a legal move.
    """
    names = [o for o in outputs if o in modes]
    one = _exactly_one(names)
    couple = [f"({m} -> ({modes[m]}))" for m in names]
    labels = " | ".join(f"({lab})" for lab in sorted({modes[m] for m in names}))
    g_init = [" & ".join([f"({one})", *couple])]
    g_safety = [f"G(X({one}))"] + [f"G(X({m} -> ({modes[m]})))" for m in names]
    a_init = [labels]
    a_safety = [f"G(X({labels}))"]

    def formula(text: str, section: str, index: int) -> SpecFormula:
        # Built from labels already checked against the limits: allow the few levels and
        # characters the constraint itself adds.
        return SpecFormula(text=text, section=section, index=index, line=None, origin="modes",
                           ltl=parse_formula(text, where=f"[modes] constraint {section}",
                                             max_nodes=None,
                                             max_depth=MAX_FORMULA_DEPTH + 8))

    def extend(side: SpecSide, name: str, inits: list[str], safeties: list[str]) -> SpecSide:
        init = side.init + tuple(formula(t, f"{name}.init", len(side.init) + i)
                                 for i, t in enumerate(inits))
        safety = side.safety + tuple(formula(t, f"{name}.safety", len(side.safety) + i)
                                     for i, t in enumerate(safeties))
        return SpecSide(init=init, safety=safety, liveness=side.liveness)

    return (extend(assume, "assume", a_init, a_safety),
            extend(guarantee, "guarantee", g_init, g_safety))
