"""Spec inference from demonstrations and online re-synthesis (paper appendix F, "Automatic
construction of GR(1) LTL formulas").

Given the mode labels (a ``[modes]`` table: mode -> sensor formula, paper Sec. 3) and
demonstrations with sensor columns, :func:`infer_spec` writes the partial GR(1) formula
``(phi_i^e & phi_t^e & phi_g^e) -> (phi_i^s & phi_t^s & phi_g^s)`` the demonstrations imply.
The demonstrations are segmented by the labels (:func:`tli_verify.segmentation.spec_labeler`);
each segment has a *label group* (the modes whose label holds; one mode unless several share a
label) and a *reading class* (the formula of that group's readings: its label when the distinct
labels are pairwise disjoint, else the conjunction of the group's labels and the negations of
the other labels).

What is inferred, and why (the paper says only which parts can be inferred, not how the
environment part is made sound; these choices follow the sound ``specs/scoop.toml``):

* ``phi_i^e`` (``[assume] init``): the reading classes the demonstrations start in;
  ``phi_i^s`` (``[guarantee] init``): one of their modes, and ``!p`` (below).
* ``phi_t^s`` (system safety): ``G(m -> X(m | n1 | ...))`` with ``n1, ...`` the modes whose
  groups follow ``m``'s group in some demonstration (paper: "a partial formula phi_t^s can be
  inferred"). Modes that share a label cannot be told apart by the sensors, so each gets its
  group's successors.
* ``phi_t^e`` (environment safety), two parts. The mode-sensor coupling comes from the
  ``[modes]`` table (the loader adds it: one mode at a time, a mode only where its label holds,
  as guarantees; sensors always show some label, paper Asm. 3). The *physically possible sensor
  changes* are the changes the demonstrations show: ``G(C -> X(C | C1 | ...))`` per observed
  reading class ``C``, ``C1, ...`` the classes that follow it. Without them the environment
  could jump to any labelled reading (``specs/scoop-unrealizable.toml``).
* ``phi_g^e`` (environment fairness): for each mode ``m`` that is not a goal,
  ``GF(!m | P)`` with ``P`` the reading classes of ``m``'s *progress* successors (those closer to
  the goal in the demonstrated mode graph): while in ``m`` the environment eventually shows a
  reading that lets the task progress, unless something else ends ``m`` first -- scoop's
  ``GF(!a | r)``. Without it nothing forces the environment ever to change.
* ``phi_g^s`` (goal): ``GF(g1 | ... | p)`` with ``g1, ...`` the modes the demonstrations end in.

The auxiliary output ``p`` (named ``p``, or the first of ``p_``, ``p0``, ``p1``, ... that names
no sensor and no mode) is the sound scoop spec's perturbation marker, kept on purpose:
``G(X p <-> ((m1 & X n1) | ...))`` lists the *regressing* mode changes, and the goal is
``GF(goals | p)``. A regressing change is one that does not bring the task closer to a goal:
every transition added online by :func:`add_transition` (by default; these are the changes a
perturbation caused, paper appendix F) and every demonstrated change into a mode no closer to a
goal. Paper Asm. 2 (finitely many perturbations) makes ``FG !p -> GF goals`` hold, which is not
GR(1); ``GF(goals | p)`` is its GR(1) form. Without the marker the first recovery edge
(``b -> a``) would make the grown spec unrealizable: the environment could then loop ``a, b, a, b``
forever, meeting every fairness assumption, and ``GF d`` would be lost. With it, the scoop
demonstrations grow to exactly the automaton of ``specs/scoop.toml`` (paper Fig. 3(a)).

Limits. Modes that share a label get the union of their group's successors (cooking's
``w1``/``w2``: which of them came first is not in the sensors), so the spec is weaker than a
hand-written one. The goal is where the demonstrations end: a cyclic task (inspection,
``a, b, a, ...``) gets ``GF(last mode | p)`` with the edges out of the last mode marked as
regressing, not its hand-written ``GF((b & rel) | p)``. Readings no label covers are refused
(file and line), as is a mode no demonstration visits (paper Asm. 3).

Online re-synthesis (paper: "phi_t^s will be modified to incorporate those newly observed
transitions as valid mode switches, and a new automaton will be re-synthesized"):
:func:`add_transition` adds a transition into a known mode (paper Asm. 3) to ``phi_t^s``. The
sensor change that carried it was *observed*, so the environment assumption that ruled it out
was false: the change is also added to the environment's possible sensor changes (otherwise
the new edge could never appear in the automaton). The result is re-checked (realizable and
well-separated) or refused with the old spec kept. :func:`resume_state` finds the state of the
new automaton to carry on from, and :func:`spec_to_toml` writes the grown spec.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from tli_verify.errors import DemoError, SpecError, UnrealizableError
from tli_verify.io import parse_toml, read_text
from tli_verify.logic.automaton import AssumptionViolation, AutomatonState, TaskAutomaton
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.gr1 import Game, build_game, formula_bdd, new_manager
from tli_verify.logic.labels import runs as _runs
from tli_verify.logic.labels import spec_labeler
from tli_verify.logic.ltl import atomic_propositions, is_ap_name, parse_formula
from tli_verify.logic.spec import GR1Spec, SpecFormula, SpecSide, _LineFinder, _modes, parse_spec

__all__ = [
    "Regrowth",
    "add_transition",
    "infer_spec",
    "infer_spec_text",
    "load_labels",
    "regrow",
    "resume_state",
    "spec_to_toml",
]

MARKER_NAMES = ("p", "p_", *(f"p{i}" for i in range(100)))
"""Candidate names of the perturbation marker output, first free one wins."""


# --------------------------------------------------------------------------------------------
# Labels


def load_labels(path: str | os.PathLike[str], sensors: Sequence[str]) -> dict[str, str]:
    """Read the ``[modes]`` table of a labels file or of a spec file.

    Parameters
    ----------
    path : path-like
        A TOML file with a ``[modes]`` table (mode = sensor formula), as in ``specs/*.toml``;
        a whole spec file is accepted too (its other keys are ignored).
    sensors : sequence of str
        The demonstrations' sensor columns: the labels may use these APs only.

    Returns
    -------
    dict of str to str
        Mode -> label formula (Spot's text), in file order.

    Raises
    ------
    SpecError
        Unreadable file, invalid TOML, no ``[modes]`` table, a mode name that is not an AP
        name or names a sensor, a label that is not propositional or uses an unknown sensor.
    """
    where = str(path)
    text = read_text(path, what="labels", error=SpecError)
    data = parse_toml(text, where=where, error=SpecError)
    raw = data.get("modes")
    lines = _LineFinder(text)
    if not isinstance(raw, dict) or not raw:
        raise SpecError(f"{where}: no [modes] table (mode = \"sensor formula\" entries)")
    for mode in raw:
        line = lines.key(mode, lines.section("modes"))
        loc = f"{where}:{line}" if line else where
        if not is_ap_name(mode):
            raise SpecError(f"{loc}: modes.{mode}: {mode!r} is not a valid mode name "
                            "(lower-case identifier, not true/false)")
        if mode in sensors:
            raise SpecError(f"{loc}: modes.{mode}: {mode!r} is also a sensor column")
        label = raw[mode]
        if isinstance(label, str):
            f = parse_formula(label, where=f"{loc}: modes.{mode}")
            extra = sorted(atomic_propositions(f) - set(sensors) - set(raw))
            if extra:
                raise SpecError(f"{loc}: modes.{mode}: label uses {extra[0]!r}, which is not a "
                                "sensor column of the demonstrations "
                                f"({', '.join(sensors) or 'none'})")
    table = _modes(raw, tuple(sensors), tuple(raw), where, lines)
    if table is None:  # pragma: no cover - raw is a non-empty table
        raise SpecError(f"{where}: no [modes] table")
    return table

# --------------------------------------------------------------------------------------------
# Inference


@dataclass(frozen=True, slots=True)
class _Observed:
    """What the segmented demonstrations show, at the level of label groups."""

    groups: tuple[tuple[str, ...], ...]
    initial: tuple[tuple[str, ...], ...]
    final: tuple[tuple[str, ...], ...]
    successors: dict[tuple[str, ...], tuple[tuple[str, ...], ...]]


def _observe(demos: Sequence[Any], labels: Mapping[str, str], sensors: Sequence[str]
             ) -> _Observed:
    """Label every sample (:func:`~tli_verify.segmentation.spec_labeler`) and collect the
    runs of equal label groups. Unlike :func:`~tli_verify.segmentation.segment_demos` this
    needs no DS training data: a group seen for one sample is a valid observation."""
    # A minimal spec carrying the labels, for spec_labeler (label evaluation and messages).
    holder = GR1Spec(name="labels", inputs=tuple(sensors), outputs=tuple(labels),
                     modes=dict(labels), assume=_empty_side(), guarantee=_empty_side())
    labeler, modes, shown = spec_labeler(holder)
    groups: list[tuple[str, ...]] = []
    initial: list[tuple[str, ...]] = []
    final: list[tuple[str, ...]] = []
    succ: dict[tuple[str, ...], list[tuple[str, ...]]] = {}
    for demo in demos:
        cache: dict[bytes, tuple[str, ...]] = {}
        per_sample: list[tuple[str, ...]] = []
        for i in range(demo.n_samples):
            key = demo.sensors[i].tobytes()
            if key not in cache:
                cache[key] = labeler(demo.sensor_reading(i))
            if not cache[key]:
                reading = ", ".join(f"{n}={int(v)}" for n, v in
                                    zip(demo.sensor_names, demo.sensors[i], strict=True))
                raise DemoError(f"{demo.where(i)}: sensor reading {reading} satisfies no mode "
                                "label")
            per_sample.append(cache[key])
        runs = [per_sample[start] for start, _ in _runs(per_sample)]
        for g in runs:
            if g not in groups:
                groups.append(g)
            succ.setdefault(g, [])
        if runs[0] not in initial:
            initial.append(runs[0])
        if runs[-1] not in final:
            final.append(runs[-1])
        for g, h in itertools.pairwise(runs):
            if h not in succ[g]:
                succ[g].append(h)
    visited = {m for g in groups for m in g}
    for m in modes:
        if m not in visited:
            raise DemoError(f"mode {m!r} (label {shown[m]!r}) is visited by no demonstration; "
                            "every mode needs demonstration data (paper Asm. 3)")
    order = {g: i for i, g in enumerate(groups)}
    return _Observed(groups=tuple(groups), initial=tuple(initial), final=tuple(final),
                     successors={g: tuple(sorted(v, key=order.__getitem__))
                                 for g, v in succ.items()})


def _empty_side() -> Any:

    return SpecSide()


def _distances(obs: _Observed) -> dict[tuple[str, ...], int]:
    """Demonstrated steps from each group to a final group (backward BFS)."""
    dist = {g: 0 for g in obs.final}
    frontier = list(obs.final)
    while frontier:
        nxt = []
        for g in obs.groups:
            if g in dist:
                continue
            if any(h in frontier for h in obs.successors.get(g, ())):
                dist[g] = dist[frontier[0]] + 1
                nxt.append(g)
        frontier = nxt
    return dist


def _label_bdds(labels: Mapping[str, str], sensors: Sequence[str]) -> tuple[Any, dict[str, Any]]:

    bdd = new_manager()
    bdd.declare(*sensors)
    return bdd, {m: formula_bdd(parse_formula(lab, where=f"modes.{m}"), bdd, primed=False)
                 for m, lab in labels.items()}


def _class_formulas(groups: Sequence[tuple[str, ...]], labels: Mapping[str, str],
                    sensors: Sequence[str]) -> dict[tuple[str, ...], str]:
    """The reading class of each label group (module docstring)."""
    bdd, b = _label_bdds(labels, sensors)
    distinct: dict[str, list[str]] = {}
    for m, lab in labels.items():
        distinct.setdefault(lab, []).append(m)
    reps = [ms[0] for ms in distinct.values()]
    disjoint = all((b[x] & b[y]) == bdd.false for i, x in enumerate(reps) for y in reps[i + 1:])
    out: dict[tuple[str, ...], str] = {}
    for g in groups:
        own = sorted({labels[m] for m in g})
        if disjoint and len(own) == 1:
            out[g] = own[0]
            continue
        others = sorted({lab for m, lab in labels.items() if m not in g} - set(own))
        out[g] = " & ".join([f"({lab})" for lab in own] + [f"!({lab})" for lab in others])
    return out


def _or(parts: Sequence[str]) -> str:
    if len(parts) == 1:
        return parts[0]
    return " | ".join(f"({p})" for p in parts)


def _fresh_marker(taken: set[str]) -> str:
    for name in MARKER_NAMES:
        if name not in taken:
            return name
    raise SpecError("no free name for the perturbation marker output")  # pragma: no cover


def infer_spec_text(demos: Sequence[Any], labels: Mapping[str, str], *,
                    name: str = "inferred", sources: Sequence[str] = ()) -> str:
    """The TOML text of the spec the demonstrations imply (module docstring).

    Parameters
    ----------
    demos : sequence of Demonstration
        From :func:`tli_verify.demos.load_demos` (same sensor columns).
    labels : mapping of str to str
        Mode -> sensor label formula (:func:`load_labels`).
    name : str
        The spec's name.
    sources : sequence of str
        Demonstration file names, quoted in the header comment.

    Raises
    ------
    DemoError
        No demonstrations, a reading no label covers, a mode no demonstration visits (paper
        Asm. 3).
    SpecError
        A label naming a sensor the demonstrations lack.
    """
    if not demos:
        raise DemoError("no demonstrations to infer a spec from")
    sensors = tuple(demos[0].sensor_names)
    if not sensors:
        raise DemoError(f"{demos[0].path}: no sensor columns: modes are labels of sensor "
                        "readings, so a spec cannot be inferred without them")
    for mode, lab in labels.items():
        extra = sorted(atomic_propositions(parse_formula(lab, where=f"modes.{mode}"))
                       - set(sensors))
        if extra:
            raise SpecError(f"modes.{mode}: label uses sensor {extra[0]!r}, which is not a "
                            f"sensor column of the demonstrations ({', '.join(sensors)})")
    obs = _observe(demos, labels, sensors)
    cls = _class_formulas(obs.groups, labels, sensors)
    dist = _distances(obs)
    modes = list(labels)
    marker = _fresh_marker(set(sensors) | set(modes))
    goal_modes = [m for m in modes if any(m in g for g in obs.final)]
    init_modes = [m for m in modes if any(m in g for g in obs.initial)]

    mode_succ: dict[str, list[str]] = {m: [m] for m in modes}
    regress: list[tuple[str, str]] = []
    fair: list[str] = []
    for g in obs.groups:
        progress = []
        for h in obs.successors.get(g, ()):
            for m in g:
                for n in h:
                    if n not in mode_succ[m]:
                        mode_succ[m].append(n)
                    if dist[h] >= dist[g]:
                        regress.append((m, n))
            if dist[h] < dist[g]:
                progress.append(cls[h])
        if dist[g] > 0:
            for m in g:
                fair.append(f"GF(!{m} | ({_or(progress)}))")
    env_safety = []
    for g in obs.groups:
        nxt = [cls[g]] + [cls[h] for h in obs.successors.get(g, ()) if h != g]
        env_safety.append(f"G(({cls[g]}) -> X({_or(nxt)}))")
    sys_safety = [f"G({m} -> X({' | '.join(mode_succ[m])}))" for m in modes]
    sys_safety.append(_marker_formula(marker, regress))
    goal = " | ".join([*goal_modes, marker])

    lines = [
        "# Inferred by `tli spec infer` (tli_verify.logic.infer) from "
        + (", ".join(sources) if sources else f"{len(demos)} demonstration(s)") + ".",
        "# Environment: the demonstrated sensor changes and fairness toward the goal;",
        f"# system: the demonstrated mode changes; {marker} marks a regressing mode change",
        "# (a perturbation; paper Asm. 2 as the GR(1) goal below).",
        f"name = {_toml_str(name)}",
        f"description = {_toml_str('partial spec inferred from demonstrations')}",
        f"inputs = {_toml_list(sensors)}",
        f"outputs = {_toml_list([*modes, marker])}",
        "",
        "[modes]",
        *(f"{m} = {_toml_str(labels[m])}" for m in modes),
        "",
        "[assume]",
        f"init = {_toml_str(_or([cls[g] for g in obs.initial]))}",
        "safety = [", *(f"  {_toml_str(t)}," for t in env_safety), "]",
        "liveness = [", *(f"  {_toml_str(t)}," for t in fair), "]",
        "",
        "[guarantee]",
        f"init = {_toml_str(_init_guarantee(init_modes, marker))}",
        "safety = [", *(f"  {_toml_str(t)}," for t in sys_safety), "]",
        f"liveness = [{_toml_str(f'GF({goal})')}]",
    ]
    return "\n".join(lines) + "\n"


def _init_guarantee(modes: Sequence[str], marker: str) -> str:
    if len(modes) == 1:
        return f"{modes[0]} & !{marker}"
    return f"({' | '.join(modes)}) & !{marker}"


def _marker_formula(marker: str, regress: Sequence[tuple[str, str]]) -> str:
    if not regress:
        return f"G(X {marker} <-> false)"
    return f"G(X {marker} <-> ({' | '.join(f'({m} & X {n})' for m, n in regress)}))"


def infer_spec(demos: Sequence[Any], labels: Mapping[str, str], *, name: str = "inferred",
               sources: Sequence[str] = ()) -> GR1Spec:
    """The inferred spec as a :class:`GR1Spec` (parsed from :func:`infer_spec_text`)."""
    return parse_spec(infer_spec_text(demos, labels, name=name, sources=sources),
                      default_name=name)

# --------------------------------------------------------------------------------------------
# Writing specs


def _toml_str(s: str) -> str:
    """A TOML basic string (every control character escaped)."""
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_list(items: Sequence[str]) -> str:
    return "[" + ", ".join(_toml_str(i) for i in items) + "]"


def spec_to_toml(spec: GR1Spec) -> str:
    """The TOML text of ``spec`` (its file formulas; the ``[modes]`` constraints are re-added
    by the loader). ``parse_spec(spec_to_toml(spec))`` has the same formulas, so the same game
    and the same automaton."""

    def side(name: str, formulas: Sequence[SpecFormula], key: str) -> list[str]:
        own = [f.text for f in formulas if f.origin == "file"]
        if not own:
            return []
        return [f"{key} = [", *(f"  {_toml_str(t)}," for t in own), "]"]

    lines = [f"name = {_toml_str(spec.name)}"]
    if spec.description:
        lines.append(f"description = {_toml_str(spec.description)}")
    if spec.expect != "realizable":
        lines.append(f"expect = {_toml_str(spec.expect)}")
    if spec.semantics != "tli":
        lines.append(f"semantics = {_toml_str(spec.semantics)}")
    lines += [f"inputs = {_toml_list(spec.inputs)}", f"outputs = {_toml_list(spec.outputs)}"]
    if spec.modes is not None:
        lines += ["", "[modes]", *(f"{m} = {_toml_str(lab)}" for m, lab in spec.modes.items())]
    for title, s in (("assume", spec.assume), ("guarantee", spec.guarantee)):
        lines += ["", f"[{title}]"]
        for key, formulas in (("init", s.init), ("safety", s.safety), ("liveness", s.liveness)):
            lines += side(title, formulas, key)
    return "\n".join(lines) + "\n"

# --------------------------------------------------------------------------------------------
# Online re-synthesis


def _ap(f: Any) -> str | None:
    from tli_verify.logic.spot_import import spot

    return str(f.ap_name()) if f.kind() == spot.op_ap else None


def _g_body(f: Any) -> Any | None:
    from tli_verify.logic.spot_import import spot

    return f[0] if f.kind() == spot.op_G else None


def _marker_parts(body: Any, markers: set[str]) -> tuple[str, str] | None:
    """``(marker, rhs text)`` if ``body`` is ``X p <-> R`` (or ``!X p``: ``R`` false)."""
    from tli_verify.logic.spot_import import spot

    def xp(g: Any) -> str | None:
        if g.kind() == spot.op_X:
            name = _ap(g[0])
            return name if name in markers else None
        return None

    if body.kind() == spot.op_Equiv:
        a, b = body[0], body[1]
        if xp(a) is not None:
            return xp(a), str(b)  # type: ignore[return-value]
        if xp(b) is not None:
            return xp(b), str(a)  # type: ignore[return-value]
    if body.kind() == spot.op_Not and xp(body[0]) is not None:
        return xp(body[0]), "false"  # type: ignore[return-value]
    if body.kind() == spot.op_X and body[0].kind() == spot.op_Not and _ap(body[0][0]) in markers:
        return _ap(body[0][0]), "false"  # type: ignore[return-value]
    return None


def add_transition(spec: GR1Spec, from_mode: str, to_mode: str, *,
                   perturbation: bool = True) -> GR1Spec:
    """Add the mode change ``from_mode -> to_mode`` to ``phi_t^s`` and re-check the spec.

    Parameters
    ----------
    spec : GR1Spec
        A spec with a ``[modes]`` table whose ``phi_t^s`` is written as ``G(m -> X(...))`` per
        mode, and whose environment's sensor changes are written as ``G(C -> X(...))`` per
        reading class (as :func:`infer_spec` and ``specs/scoop.toml`` write them). The
        guarantee ``G(from_mode -> X(...))`` gets ``to_mode`` as a further successor; every
        assumption ``G(C -> X(...))`` with ``C`` over the inputs meeting ``from_mode``'s label
        gets ``to_mode``'s label as a further next reading (the change was observed).
    from_mode, to_mode : str
        Known modes (paper Asm. 3: a transition into an unknown mode is not valid).
    perturbation : bool
        Mark the change as regressing in the spec's perturbation marker ``G(X p <-> ...)``
        (module docstring), when it has one: the default, for a change a perturbation caused.

    Returns
    -------
    GR1Spec
        The grown spec, realizable and well-separated (``path`` None); ``spec`` itself when
        it already allows the change (both players' safety formulas). ``spec`` is never
        modified (values are immutable), so on any error the caller keeps the old spec.

    Raises
    ------
    SpecError
        An unknown mode; a spec without ``[modes]``; labels that cannot both hold in
        successive readings under the grown assumptions.
    UnrealizableError
        The grown spec is unrealizable or not well-separated (the old spec is kept).
    """
    from tli_verify.logic.spot_import import spot

    where = spec.path or spec.name
    if spec.modes is None:
        raise SpecError(f"{where}: no [modes] table: cannot relate modes to sensor readings")
    for m in (from_mode, to_mode):
        if m not in spec.mode_names:
            raise SpecError(f"{where}: {m!r} is not a known mode ({', '.join(spec.mode_names)});"
                            " only transitions into known modes are valid (paper Asm. 3)")
    if _allowed(spec, from_mode, to_mode):
        return spec
    l_to = spec.modes[to_mode]
    l_from = spec.modes[from_mode]
    bdd, labs = _label_bdds({"from": l_from, "to": l_to}, spec.inputs)
    markers = {o for o in spec.outputs if o not in spec.mode_names}
    changed: dict[tuple[str, int], str] = {}
    # phi_t^s: from's successors (a mode without a G(from -> X ...) formula allows every next
    # mode already), and the perturbation marker.
    for f in spec.guarantee.safety:
        body = _g_body(f.ltl) if f.origin == "file" else None
        if body is None:
            continue
        if body.kind() == spot.op_Implies and _ap(body[0]) == from_mode:
            changed[(f.section, f.index)] = f"G({from_mode} -> {_or_next(body[1], to_mode)})"
            continue
        parts = _marker_parts(body, markers)
        if parts is not None and perturbation:
            p, rhs = parts
            new = f"({from_mode} & X {to_mode})"
            rhs = new if rhs == "false" else f"({rhs}) | {new}"
            changed[(f.section, f.index)] = f"G(X {p} <-> ({rhs}))"
    # The observed sensor change: every G(C -> X(...)) over the inputs whose C meets from's
    # label gets to's label as a further possible next reading.
    for f in spec.assume.safety:
        body = _g_body(f.ltl) if f.origin == "file" else None
        if body is None or body.kind() != spot.op_Implies:
            continue
        lhs = body[0]
        if atomic_propositions(lhs) - set(spec.inputs) or not lhs.is_boolean():
            continue
        if (formula_bdd(lhs, bdd, primed=False) & labs["from"]) != bdd.false:
            changed[(f.section, f.index)] = f"G(({lhs!s}) -> {_or_next(body[1], l_to)})"
    grown = _replace(spec, changed)
    _check_change_allowed(grown, from_mode, to_mode)
    if not _allowed(grown, from_mode, to_mode):
        raise SpecError(f"{where}: the guarantees still rule out the transition {from_mode} -> "
                        f"{to_mode}: no guarantee of the form G({from_mode} -> X(...)) covers "
                        "it")
    result = check_spec(grown)
    if not result.realizable:
        summary = result.diagnosis.summary if result.diagnosis is not None else ""
        raise UnrealizableError(f"{where}: adding the transition {from_mode} -> {to_mode} makes "
                                f"the spec unrealizable ({summary}); the old spec is kept")
    if not result.well_separated:
        raise UnrealizableError(f"{where}: adding the transition {from_mode} -> {to_mode} makes "
                                "the spec not well-separated (the system could win vacuously); "
                                "the old spec is kept")
    return grown


def _or_next(rhs: Any, extra: str) -> str:
    """``rhs | X extra`` as text; ``X(D | extra)`` when ``rhs`` is ``X D``, so that repeated
    growth keeps the formula flat (Spot's n-ary ``|``)."""
    from tli_verify.logic.spot_import import spot

    if rhs.kind() == spot.op_X:
        return f"X(({rhs[0]!s}) | ({extra}))"
    return f"(({rhs!s}) | X({extra}))"


def _replace(spec: GR1Spec, changed: Mapping[tuple[str, int], str]) -> GR1Spec:
    """``spec`` with some file formulas' texts replaced, re-parsed (the checks run again)."""
    from dataclasses import replace as dc_replace

    def side(s: SpecSide) -> SpecSide:
        def fix(fs: tuple[SpecFormula, ...]) -> tuple[SpecFormula, ...]:
            return tuple(dc_replace(f, text=changed[(f.section, f.index)])
                         if (f.section, f.index) in changed else f for f in fs)

        return SpecSide(init=fix(s.init), safety=fix(s.safety), liveness=fix(s.liveness))

    draft = dc_replace(spec, assume=side(spec.assume), guarantee=side(spec.guarantee))
    return parse_spec(spec_to_toml(draft), default_name=spec.name)


def _transition_bdds(spec: GR1Spec, from_mode: str, to_mode: str) -> tuple[Game, Any]:
    """``(game, step)``: the game, and the system running ``from_mode``
    under its label while the next reading is ``to_mode``'s label and the next mode is
    ``to_mode`` (``move`` without the environment's and the system's safety)."""
    game = build_game(spec)
    bdd = game.manager
    assert spec.modes is not None
    lf = formula_bdd(parse_formula(spec.modes[from_mode], where="modes"), bdd, primed=False)
    lt = formula_bdd(parse_formula(spec.modes[to_mode], where="modes"), bdd, primed=True)
    return game, lf & bdd.var(from_mode) & lt


def _allowed(spec: GR1Spec, from_mode: str, to_mode: str) -> bool:
    """Whether the game already has a move from ``from_mode`` (under its label) to
    ``to_mode`` (under its label) that both players' safety formulas allow."""
    game, step = _transition_bdds(spec, from_mode, to_mode)
    move = game.rho_e & game.rho_s & step & game.manager.var(to_mode + "'")
    return bool(move != game.manager.false)


def _check_change_allowed(spec: GR1Spec, from_mode: str, to_mode: str) -> None:
    """The grown assumptions let the sensors move from ``from_mode``'s label to
    ``to_mode``'s while the system runs ``from_mode``."""
    game, step = _transition_bdds(spec, from_mode, to_mode)
    if (game.rho_e & step) == game.manager.false:
        assert spec.modes is not None
        raise SpecError(f"{spec.name}: the environment assumptions still rule out the sensor "
                        f"change {spec.modes[from_mode]!r} -> {spec.modes[to_mode]!r} of the "
                        f"transition {from_mode} -> {to_mode}: no assumption of the form "
                        "G(C -> X(...)) covers it")


def resume_state(automaton: TaskAutomaton, old: AutomatonState,
                 sensors: Mapping[str, bool] | Iterable[str]) -> int:
    """The state of a re-synthesized automaton to carry on from.

    Parameters
    ----------
    automaton : TaskAutomaton
        The new automaton.
    old : AutomatonState
        The state of the old automaton the run was in before the sensor change (mode, goal
        memory, reading).
    sensors : mapping of str to bool, or iterable of str
        The current (new) reading (values of the inputs, or the set of true inputs).

    Returns
    -------
    int
        The new automaton's state after the Mealy step on ``sensors`` from the state that
        matches ``old`` (same mode, outputs, reading and goal; else same mode and reading,
        nearest goal). When no state matches ``old``, a state whose reading is the current
        one, preferring the mode of the old state's planned successor, then ``old.goal``,
        then the lowest id: every state of the automaton is winning, so the strategy wins
        from any of them.

    Raises
    ------
    AssumptionViolation
        No state of the new automaton carries the current reading.
    """
    inputs = set(old.inputs)
    same = [s for s in automaton.states if s.mode == old.mode and set(s.inputs) == inputs]
    same.sort(key=lambda s: (s.outputs != old.outputs, s.goal != old.goal, s.id))
    for s in same:
        try:
            return automaton.next_mode(s.id, sensors)[0]
        except AssumptionViolation:
            continue
    reading = automaton._reading(sensors) - frozenset(automaton.free_inputs)
    cands = [s for s in automaton.states if frozenset(s.inputs) == reading]
    if not cands:
        raise AssumptionViolation(f"sensor reading {sorted(reading)}: no state of the "
                                  "re-synthesized automaton carries it")
    cands.sort(key=lambda s: (s.goal != old.goal, s.id))
    return cands[0].id


@dataclass(frozen=True, slots=True)
class Regrowth:
    """The result of :func:`regrow`.

    Attributes
    ----------
    spec : GR1Spec
        The grown spec.
    automaton : TaskAutomaton
        Its task automaton.
    state : int
        The state of ``automaton`` to carry on from.
    """

    spec: GR1Spec
    automaton: TaskAutomaton
    state: int


def regrow(spec: GR1Spec, from_mode: str, to_mode: str, old: AutomatonState,
           sensors: Mapping[str, bool] | Iterable[str], *, perturbation: bool = True
           ) -> Regrowth:
    """:func:`add_transition`, re-synthesis and :func:`resume_state` in one call (for the
    executive's ``--learn-transitions``)."""
    grown = add_transition(spec, from_mode, to_mode, perturbation=perturbation)
    automaton = synthesize(grown)
    return Regrowth(spec=grown, automaton=automaton,
                    state=resume_state(automaton, old, sensors))
