"""Offline mode boundaries and the hand-off between modes (issue 30; paper Sec. 5.2, Thm. 1-2).

The paper learns a mode's cuts online, one invariance failure at a time, and proves two things
that do not compose by themselves: Lemma 2 (mode ``m``'s DS reaches ``x*_m`` inside the next
mode's region ``delta_n``) and Thm. 1 (the modulated DS of ``n`` never leaves the set its cuts
bound). Nothing makes ``m``'s flow enter ``delta_n`` *inside* the set where ``n`` is invariant:
entered elsewhere, ``n``'s DS may leave again, ``m`` brings it back, and each exit adds a cut
next to the last one (``abab...``). Where a task file declares the regions, this module closes
the gap before deployment.

**The result** (``docs/explanation/handoff.md`` has the proof sketch). Let a DS key ``k`` run
mode ``m`` towards ``n`` with its certified ``P`` and the guarded modulation at the control
period ``dt`` (Thm. 1 and the corner guard: no Euler step crosses a cut from its inner side,
and ``V`` decreases at least as fast as without the cuts). If

* **(E1)** every state of ``delta_m`` lies on the inner side of every cut of ``m``, and
* **(E2)** every state reached from ``delta_m`` that is inside the cuts but no longer in
  ``delta_m`` reads a mode the plan allows (``n``, or a later mode of the plan),

then from *every* state of ``delta_m`` -- wherever a previous mode or a push left it -- the
closed loop stays in ``delta_m`` until it hands off to an allowed mode, within the certified
deadline. If every key the plan runs satisfies (E1)-(E2), every mode change without a
perturbation moves strictly forward along the planned path (:func:`plan_progress`), so after
the last perturbation there are at most as many mode changes as the path has modes and no cut
is ever learned online: looping is impossible by construction.

**How it is established** (:func:`learn_handoffs`):

1. the states of each mode are drawn (uniform in the workspace, every latch valuation, read by
   the task's own sensor model; where the mode's boundaries are flat, a quarter of them moved
   along a random ray to just inside the boundary, where exits are likeliest; plus the states
   where the previous modes' flows
   handed off into it, so the composition itself is tested) and simulated with the modulated
   DS at ``dt``;
2. an exit into a mode the plan does not allow is a failure. Its cut is the **supporting plane
   of the region shape crossed** (the face of a box or polytope, the tangent plane of a ball or
   ellipsoid) when that plane keeps every attractor of the mode strictly inside: a plane of the
   mode's own convex shape keeps the whole shape inside (E1 for every entry), a plane of a
   forbidden convex shape keeps all of it out. Otherwise the cut QCQP of appendix E.3 (the
   online rule) is solved with the drawn entry states kept inside;
3. rounds repeat on fresh draws until two rounds in a row find no exit; a final round on an
   independent draw of ``samples`` states then checks the model as it stands. Exits it finds
   are cut and learning resumes, at most :data:`FINAL_CHECKS` checks; the last check gives the
   claim's figures;
4. a claim is **proved** (exact) when the mode's region is one box or polytope cell that no
   earlier-listed cell overlaps and no layer touches, every facet that keeps ``x*`` strictly
   inside is a cut (E1 holds for every state), and every other facet, within the cuts, lies in
   a box or polytope cell of an allowed mode (E2), decided with linear programs; it is
   **sampled** otherwise (``N`` states, 0 exits: an exit probability below ``3/N`` at 95%
   confidence, the rule of three, after one check; after ``c`` checks, each on a fresh draw,
   below ``ln(20 c)/N``, since a model that fails a check is not the one claimed), and
   **online only** for tasks whose sensors only physics computes.

The cuts go into the model (they are the mode's cuts, the ones the runtime modulates with and
the certificate covers); the claims go into its ``source.handoff`` record (bound by the model's
hash), which ``tli certify`` copies, ``tli check-cert`` re-checks and the gate reports.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut, InvarianceFailure
from tli_verify.errors import ModelError, TliError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton, plan_progress
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model.types import Model
from tli_verify.runtime.coverage import plan_states
from tli_verify.runtime.online import online_cut
from tli_verify.tasks.project import check_goal, spec_task
from tli_verify.tasks.regions import Ball, Box, Ellipsoid, Polytope, Primitive
from tli_verify.tasks.task import FormulaSensors, Goal, Task

__all__ = [
    "HANDOFF_VERSION",
    "Exit",
    "HandoffClaim",
    "HandoffReport",
    "learn_handoffs",
    "recheck_handoffs",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

HANDOFF_VERSION = 1
"""Version of the ``source.handoff`` record of a model file."""

PROVED = "proved"
SAMPLED = "sampled"
ONLINE = "online"
FINAL_CHECKS = 3
"""Final checks at most (module docstring, step 3): a check that finds exits cuts them and
learning resumes; the claim's 95% bound after ``c`` checks is ``ln(20 c) / N``."""

_MAX_LATCHES = 8
_INWARD = 1e-10
"""A face cut lies this far (times ``1 + |p - x*|``) inside the face: within the guard's
rounding band (1e-9), so a state between the cut and the face is held, never pushed out."""


# ------------------------------------------------------------------------------ values
@dataclass(frozen=True, slots=True)
class Exit:
    """One exit found offline (the diagnosis of a hand-off that fails).

    Attributes
    ----------
    key, mode : str
        The DS and its mode.
    to_mode : str
        The mode read after the exit (``"?"``: a reading no mode has; ``"(rest)"``: the run
        stayed in the mode until its deadline without the next reading).
    entry, last_inside, outside : tuple of float
        ``x^0``, ``x^{T_f-1}``, ``x^{T_f}`` (shape (n,) each).
    crossed : str
        The region (cell or layer) whose boundary was crossed, ``""`` if unknown.
    kind : str
        ``"composition"`` (the start was a hand-off state of a previous mode), ``"invariance"``
        (a drawn state of the mode) or ``"reachability"`` (a rest).
    """

    key: str
    mode: str
    to_mode: str
    entry: tuple[float, ...]
    last_inside: tuple[float, ...]
    outside: tuple[float, ...]
    crossed: str
    kind: str

    def describe(self) -> str:
        """One line naming the mode, the region it leaves through and where it entered."""
        at = ", ".join(f"{v:.4g}" for v in self.entry)
        if self.kind == "reachability":
            return (f"mode {self.mode} (DS {self.key}) entered at [{at}] rests without the next "
                    "reading (reachability)")
        through = f" across the boundary of region {self.crossed!r}" if self.crossed else ""
        cls = {"composition": "composition gap: entered where the previous mode handed off",
               "assumption": "a sensor change the spec's assumptions rule out"}.get(
                   self.kind, "invariance")
        last = ", ".join(f"{v:.4g}" for v in self.last_inside)
        return (f"mode {self.mode} (DS {self.key}) entered at [{at}] leaves into "
                f"{self.to_mode}{through} after [{last}] ({cls})")

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "mode": self.mode, "to_mode": self.to_mode,
                "entry": list(self.entry), "last_inside": list(self.last_inside),
                "outside": list(self.outside), "crossed": self.crossed, "kind": self.kind}


@dataclass(frozen=True, slots=True)
class HandoffClaim:
    """What is established about one DS key: invariance of its mode and the hand-off.

    Attributes
    ----------
    key, mode : str
    hands_to : tuple of str
        The modes its exits may read (the planned next mode first).
    region : tuple of str
        The cells (and layers) where the mode's label can hold.
    cuts : int
        Cuts of the mode's region in the model (shared by its DS keys).
    cuts_offline : int
        Of them, learned by this step.
    face_cuts : int
        Of those, supporting planes of the region shapes (the rest: the QCQP).
    established : str
        ``"proved"``, ``"sampled"`` or ``"online"``.
    samples : int
        States simulated in the final (independent) round.
    exits : int
        Exits found in that round (0 for a claim that holds).
    rests : int
        Runs of that round that stayed in the mode without the next reading.
    bound : float
        95% upper bound on the probability that a drawn state exits (``3 / samples`` with 0
        exits; 1 otherwise).
    rounds : int
        Rounds until the final one.
    note : str
        Why the claim is not proved, or the first remaining exit.
    """

    key: str
    mode: str
    hands_to: tuple[str, ...]
    region: tuple[str, ...]
    cuts: int
    cuts_offline: int
    face_cuts: int
    established: str
    samples: int
    exits: int
    rests: int
    bound: float
    rounds: int
    note: str = ""

    @property
    def holds(self) -> bool:
        """Proved, or sampled with no exit and no rest."""
        return self.established == PROVED or (self.established == SAMPLED and self.exits == 0
                                              and self.rests == 0)

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "mode": self.mode, "hands_to": list(self.hands_to),
                "region": list(self.region), "cuts": self.cuts,
                "cuts_offline": self.cuts_offline, "face_cuts": self.face_cuts,
                "established": self.established, "samples": self.samples,
                "exits": self.exits, "rests": self.rests, "bound": self.bound,
                "rounds": self.rounds, "note": self.note}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], where: str) -> HandoffClaim:
        try:
            return cls(key=str(data["key"]), mode=str(data["mode"]),
                       hands_to=tuple(str(v) for v in data["hands_to"]),
                       region=tuple(str(v) for v in data["region"]), cuts=int(data["cuts"]),
                       cuts_offline=int(data["cuts_offline"]),
                       face_cuts=int(data["face_cuts"]),
                       established=str(data["established"]), samples=int(data["samples"]),
                       exits=int(data["exits"]), rests=int(data["rests"]),
                       bound=float(data["bound"]), rounds=int(data["rounds"]),
                       note=str(data.get("note", "")))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"{where}: source.handoff: malformed claim ({exc})") from None


@dataclass(frozen=True, slots=True, eq=False)
class HandoffReport:
    """The outcome of :func:`learn_handoffs`.

    Attributes
    ----------
    model : Model
        The model with the offline cuts and its ``source.handoff`` record.
    claims : tuple of HandoffClaim
        One per DS key the plan runs.
    exits : tuple of Exit
        The exits of the final round (empty when every claim holds).
    seed, samples : int
    """

    model: Model
    claims: tuple[HandoffClaim, ...]
    exits: tuple[Exit, ...] = ()
    seed: int = 0
    samples: int = 0
    history: tuple[tuple[str, int], ...] = field(default=())

    @property
    def ok(self) -> bool:
        """Every claim holds."""
        return all(c.holds for c in self.claims)

    def record(self) -> dict[str, Any]:
        """The ``source.handoff`` record (JSON-ready)."""
        return {"version": HANDOFF_VERSION, "seed": self.seed, "samples": self.samples,
                "claims": [c.to_dict() for c in self.claims],
                "exits": [e.to_dict() for e in self.exits[:20]]}


# ------------------------------------------------------------------------------ geometry
def _support(prim: Primitive, y: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """Outward unit normal of ``prim`` at a boundary point ``y`` and a point of that
    supporting plane; None when the shape has no plane there (degenerate)."""
    if isinstance(prim, Box):
        best: tuple[float, int, float] | None = None
        for i in range(y.size):
            for sign, bound in ((-1.0, float(prim.lower[i])), (1.0, float(prim.upper[i]))):
                if math.isfinite(bound):
                    gap = abs(float(y[i]) - bound)
                    if best is None or gap < best[0]:
                        best = (gap, i, sign)
        if best is None:
            return None
        _, i, sign = best
        n = np.zeros(y.size)
        n[i] = sign
        p = y.copy()
        p[i] = float(prim.upper[i] if sign > 0 else prim.lower[i])
        return n, p
    if isinstance(prim, Polytope):
        norms = np.linalg.norm(prim.A, axis=1)
        j = int(np.argmax((prim.A @ y - prim.b) / norms))
        n = prim.A[j] / norms[j]
        return n, y - ((float(prim.A[j] @ y) - float(prim.b[j])) / norms[j]) * n
    if isinstance(prim, Ball):
        off = y - prim.center
        r = float(np.linalg.norm(off))
        if r == 0.0:
            return None
        return off / r, prim.center + float(prim.radius) * (off / r)
    if isinstance(prim, Ellipsoid):
        off = y - prim.center
        g = prim.matrix @ off
        gn = float(np.linalg.norm(g))
        q = float(off @ prim.matrix @ off)
        if gn == 0.0 or q <= 0.0:
            return None
        return g / gn, prim.center + off / math.sqrt(q)
    return None  # another primitive (a pose task's cone): no supporting plane, no face cut


def _crossing(prim: Primitive, a: FloatArray, b: FloatArray) -> FloatArray:
    """The point where the segment ``a -> b`` crosses ``prim``'s boundary (bisection; the
    membership of ``a`` and ``b`` differ)."""
    inside_a = bool(prim.contains_one(a.tolist()))
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if bool(prim.contains_one((a + mid * (b - a)).tolist())) == inside_a:
            lo = mid
        else:
            hi = mid
    return a + hi * (b - a)


def _leaves(task: Task) -> list[tuple[str, Primitive]]:
    """Every convex shape that decides a state's reading, and the workspace box (a bound:
    leaving it is an exit too), with the region's name."""
    out: list[tuple[str, Primitive]] = [
        ("(workspace)", Box(lower=np.array(task.lo, dtype=np.float64),
                            upper=np.array(task.hi, dtype=np.float64)))]
    seen: list[Primitive] = []
    for nr in (*task.partition.cells, *task.partition.layers):
        for leaf in nr.region.leaves():
            if all(leaf is not q for q in seen):
                seen.append(leaf)
                out.append((nr.name, leaf))
    return out


def _face_cut(task: Task, attractors: Sequence[FloatArray], last: FloatArray,
              out: FloatArray, existing: Sequence[Cut]) -> tuple[Cut, str] | None:
    """The supporting plane of the shape crossed between ``last`` and ``out`` that keeps every
    attractor strictly inside (module docstring, step 2), and the region's name."""
    cands: list[tuple[int, float, Cut, str]] = []
    for name, leaf in _leaves(task):
        a_in = bool(leaf.contains_one(last.tolist()))
        b_in = bool(leaf.contains_one(out.tolist()))
        if a_in == b_in:
            continue
        y = _crossing(leaf, last, out)
        sup = _support(leaf, y)
        if sup is None:
            continue
        n, p = sup
        w = n if a_in else -n  # out of the kept side
        hs = [float(w @ (p - xs)) for xs in attractors]
        scale = max(1.0, max(float(np.linalg.norm(p - xs)) for xs in attractors))
        if min(hs) <= 1e-6 * scale or float(w @ (out - p)) <= 0.0:
            continue
        p_in = p - _INWARD * (1.0 + min(float(np.linalg.norm(p - xs)) for xs in attractors)) * w
        if float(w @ (last - p_in)) > 0.0:  # the last in-mode state must stay inside
            p_in = p_in + (float(w @ (last - p_in))) * w
        cut = Cut(normal=w / np.linalg.norm(w), point=p_in)
        if any(np.allclose(cut.normal, c.normal, atol=1e-9) and
               abs(float(c.normal @ (cut.point - c.point))) <= 1e-7 * scale for c in existing):
            continue  # already a cut: the start was outside it (not a face problem)
        cands.append((0 if a_in else 1, -min(hs), cut, name))
    if not cands:
        return None
    cands.sort(key=lambda c: (c[0], c[1]))
    return cands[0][2], cands[0][3]


def _crossed_name(task: Task, last: FloatArray, out: FloatArray) -> str:
    for name, leaf in _leaves(task):
        if bool(leaf.contains_one(last.tolist())) != bool(leaf.contains_one(out.tolist())):
            return name
    return ""


# ------------------------------------------------------------------------------ the plan
@dataclass(frozen=True, slots=True)
class _Key:
    key: str
    mode: str
    next_mode: str | None
    readings: frozenset[frozenset[str]]
    allowed: frozenset[str]
    goal: bool = False
    region: tuple[str, ...] = ()


def _plan(task: Task, automaton: TaskAutomaton, model: Model, goal_modes: Sequence[str] | None
          ) -> tuple[list[_Key], dict[frozenset[str], frozenset[str]]]:
    """Per DS key the plan runs: its mode's readings and the modes its exits may read
    (the planned next mode, and the later modes of its plan:
    :func:`~tli_verify.logic.automaton.plan_progress`, the executive's rule)."""
    steps = plan_states(automaton, model, goal_modes, str(model.path or "model"))
    goals = tuple(automaton.sink_modes() if goal_modes is None else goal_modes)
    progress = plan_progress(steps.values())
    by_reading: dict[frozenset[str], set[str]] = {}
    mode_readings: dict[str, set[frozenset[str]]] = {}
    for s in automaton.states:
        r = frozenset(s.inputs)
        by_reading.setdefault(r, set()).add(s.mode)
        mode_readings.setdefault(s.mode, set()).add(r)
    keys: dict[str, _Key] = {}
    for st in steps.values():
        if st.key is None or st.key in keys:
            continue
        allowed = set(progress.get(st.mode, frozenset()))
        if st.next_mode is not None:
            allowed.add(st.next_mode)
        readings = frozenset(mode_readings.get(st.mode, set()))
        keys[st.key] = _Key(st.key, st.mode, st.next_mode, readings, frozenset(allowed),
                            st.mode in goals, _region_names(task, readings))
    return list(keys.values()), {r: frozenset(m) for r, m in by_reading.items()}


# ------------------------------------------------------------------------------ simulation
def _code(reading: frozenset[str], names: Sequence[str]) -> int:
    return sum(1 << i for i, n in enumerate(names) if n in reading)


def _valuations(L: int) -> npt.NDArray[np.bool_]:
    if L > _MAX_LATCHES:
        raise TliError(f"offline boundaries: {L} latches (at most {_MAX_LATCHES})")
    return np.array([[(v >> j) & 1 == 1 for j in range(L)] for v in range(2 ** L)],
                    dtype=bool).reshape(2 ** L, L)


def _draw(task: Task, k: _Key, count: int, rng: np.random.Generator
          ) -> tuple[FloatArray, BoolArray]:
    """States of the key's mode (uniform in the workspace, a random latch valuation each, read
    by the task's sensors), with the latch state after that reading."""
    lo, hi = np.array(task.lo), np.array(task.hi)
    vals = _valuations(len(task.latent_names))
    names = task.sensor_names
    xs: list[FloatArray] = []
    ls: list[BoolArray] = []
    got = 0
    for _ in range(400):
        X = rng.uniform(lo, hi, size=(max(4 * count, 256), lo.size))
        lat = vals[rng.integers(0, len(vals), size=len(X))]
        reading, lat2 = task.read(X, X, lat)
        keep = np.array([frozenset(n for n, v in zip(names, row, strict=True) if v)
                         in k.readings for row in reading.tolist()], dtype=bool)
        xs.append(X[keep])
        ls.append(lat2[keep])
        got += int(keep.sum())
        if got >= count:
            break
    if not xs or got == 0:
        return np.zeros((0, lo.size)), np.zeros((0, len(task.latent_names)), dtype=bool)
    return np.concatenate(xs)[:count], np.concatenate(ls)[:count]


@dataclass(slots=True)
class _Outcome:
    exits: list[Exit]
    handed: list[tuple[str, FloatArray, BoolArray]]  # (mode entered, state, latch)
    rests: int


def _assumed(automaton: TaskAutomaton, mode: str, old: frozenset[str], new: frozenset[str]
             ) -> bool:
    """Whether the spec's assumptions allow the sensor change ``old -> new`` from a state of
    ``mode`` read ``old`` (else the exit is the task's, not the policy's: a task/spec
    mismatch the executive reports as an assumption violation and never cuts)."""
    for s in automaton.states:
        if s.mode == mode and frozenset(s.inputs) == old:
            try:
                automaton.next_mode(s.id, new)
            except AssumptionViolation:
                continue
            return True
    return False


def _simulate(task: Task, model: Model, k: _Key, X0: FloatArray, L0: BoolArray,
              is_entry: BoolArray, by_reading: Mapping[frozenset[str], frozenset[str]], *,
              dt: float, steps: int, automaton: TaskAutomaton) -> _Outcome:
    """Run the key's modulated DS from every start (vectorised), until its reading leaves
    the mode's readings or ``steps`` pass."""
    names = task.sensor_names
    mm = model.modes[k.key]
    X = X0.copy()
    lat = L0.copy()
    active = np.arange(len(X))
    exits: list[Exit] = []
    handed: list[tuple[str, FloatArray, BoolArray]] = []
    lo, hi = np.array(task.lo), np.array(task.hi)
    bits = 1 << np.arange(len(names), dtype=np.int64)
    own = np.array(sorted(_code(r, names) for r in k.readings), dtype=np.int64)
    first, _ = task.read(X, X, lat)
    prev_read = [frozenset(n for n, v in zip(names, row, strict=True) if v)
                 for row in first.tolist()]
    for _ in range(steps):
        if active.size == 0:
            break
        Xa = X[active]
        V = mm.velocity(Xa, dt=dt)
        Xn = Xa + dt * V
        reading, lat_n = task.read(Xa, Xn, lat[active])
        codes = reading.astype(np.int64) @ bits
        left = ~np.isin(codes, own)
        beyond = ~np.all((Xn >= lo) & (Xn <= hi), axis=1)
        X[active] = Xn
        lat[active] = lat_n
        done = left | beyond
        for j in np.flatnonzero(done).tolist():
            i = int(active[j])
            r = frozenset(n for n, v in zip(names, reading[j].tolist(), strict=True) if v)
            modes = by_reading.get(r, frozenset()) if left[j] else frozenset()
            if left[j] and not beyond[j] and modes & k.allowed:
                handed.append((sorted(modes & k.allowed)[0], Xn[j].copy(), lat_n[j].copy()))
                continue
            to = "(beyond the workspace)" if beyond[j] else (
                ",".join(sorted(modes)) if modes else "?")
            kind = "composition" if bool(is_entry[i]) else "invariance"
            if left[j] and not beyond[j] and not _assumed(automaton, k.mode, prev_read[i], r):
                kind = "assumption"
            exits.append(Exit(k.key, k.mode, to, tuple(X0[i].tolist()),
                              tuple(Xa[j].tolist()), tuple(Xn[j].tolist()),
                              _crossed_name(task, Xa[j], Xn[j]), kind))
        active = active[~done]
    return _Outcome(exits, handed, 0 if k.goal else int(active.size))


def _horizon(model: Model, key: str, dt: float) -> int:
    """Steps to simulate: 1.5 times the time the DS's own rate (the smallest decay of
    ``A_k^T P + P A_k`` relative to ``P``, floats) takes to bring ``V`` down by the condition
    number of ``P`` times 1e4, plus 50 steps; at least 200, at most 20,000."""
    ds = model.modes[key].ds
    P = np.asarray(ds.P, dtype=np.float64)
    A = np.asarray(ds.A, dtype=np.float64)
    rate = math.inf
    for Ak in A:
        Q = Ak.T @ P + P @ Ak
        lam = float(np.max(np.linalg.eigvals(np.linalg.solve(P, Q)).real))
        rate = min(rate, -lam)
    eig = np.linalg.eigvalsh(P)
    t = math.log(float(eig[-1] / eig[0]) * 1e4) / max(rate, 1e-6)
    return int(min(max(200.0, 1.5 * t / dt + 50.0), 20000.0))


# ------------------------------------------------------------------------------ learning
def learn_handoffs(task: Task, automaton: TaskAutomaton, model: Model, *, dt: float,
                   goal_modes: Sequence[str] | None = None, samples: int = 1000,
                   rounds: int = 60, seed: int = 0, margin: float = 1e-3
                   ) -> HandoffReport:
    """Learn every mode's cuts offline until no drawn state exits (module docstring).

    Parameters
    ----------
    task : Task
        The task whose regions and sensors define the modes (a task whose sensors physics
        computes is refused: its boundaries are learned online).
    automaton : TaskAutomaton
        The task automaton the plan comes from.
    model : Model
        The model (its DS's ``P`` is the one the runtime modulates with).
    dt : float
        Control period (the certified one).
    goal_modes : sequence of str, optional
        Default: the automaton's sink modes.
    samples : int
        States drawn per DS key in each round (the final round's ``N``).
    rounds : int
        Learning rounds at most (one or more cuts per round).
    seed : int
        Seed of the draws.
    margin : float
        Separation margin of the QCQP fallback.

    Returns
    -------
    HandoffReport

    References
    ----------
    Paper Sec. 5.2 (cuts), appendix E.3 (the QCQP), Thm. 1 (modulation), Lemma 2 and Thm. 2
    (reachability and the composed guarantee).
    """
    if bool(getattr(task.sensor_model, "physics", False)):
        raise TliError(f"{task.where}: its sensors are computed by physics: mode boundaries "
                       "are learned online there")
    if not isinstance(samples, int) or samples < 10:
        raise TliError(f"samples must be an integer >= 10, got {samples!r}")
    if not isinstance(rounds, int) or rounds < 0:
        raise TliError(f"rounds must be a non-negative integer, got {rounds!r}")
    if model.dim != task.dim:
        raise TliError(f"{task.where}: the task has {task.dim} states, the model {model.dim}")
    keys, by_reading = _plan(task, automaton, model, goal_modes)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 30]))
    start_cuts = {m: len(model.region_cuts(m)) for m in {k.mode for k in keys}}
    face_cuts: dict[str, int] = {}
    entries: dict[str, list[tuple[FloatArray, BoolArray]]] = {}
    rounds_used: dict[str, int] = {k.key: 0 for k in keys}
    history: list[tuple[str, int]] = []
    stuck: dict[str, str] = {}
    clean = 0
    for k in keys:  # exact where the geometry allows: a convex cell's facets are cuts at once
        model, added = _facet_cuts(task, model, k)
        face_cuts[k.mode] = face_cuts.get(k.mode, 0) + added
    r = 0
    checks = 0
    while True:
        while r < rounds:
            r += 1
            found = False
            handed: list[tuple[str, FloatArray, BoolArray]] = []
            for k in keys:
                X, lat, is_entry = _starts(task, k, samples, rng, entries.get(k.mode, []))
                if len(X) == 0:
                    continue
                out = _simulate(task, model, k, X, lat, is_entry, by_reading, dt=dt,
                                steps=_horizon(model, k.key, dt), automaton=automaton)
                handed += out.handed
                out.exits[:] = [e for e in out.exits if e.kind != "assumption"]
                if not out.exits:
                    continue
                found = True
                rounds_used[k.key] = r
                model, added, faces, why = _cut_round(task, model, k, out.exits, X, margin)
                face_cuts[k.mode] = face_cuts.get(k.mode, 0) + faces
                history.append((k.key, added))
                if added == 0:
                    stuck[k.key] = why
                else:
                    stuck.pop(k.key, None)
            for mode, x, la in handed:
                lst = entries.setdefault(mode, [])
                if len(lst) < 4 * samples:
                    lst.append((x, la))
            if not found:
                clean += 1
                if clean >= 2:  # two rounds in a row without an exit
                    break
            else:
                clean = 0
                if all(k.key in stuck for k in keys if rounds_used[k.key] == r):
                    break
        # the final round: an independent draw on the model as it stands. Exits it finds are
        # cut and learning resumes, at most FINAL_CHECKS times; the claim's bound accounts for
        # the number of checks made (module docstring)
        checks += 1
        claims: list[HandoffClaim] = []
        final_exits: list[Exit] = []
        failed: list[tuple[_Key, list[Exit], FloatArray]] = []
        for k in keys:
            X, lat, is_entry = _starts(task, k, samples, rng, entries.get(k.mode, []))
            out = _simulate(task, model, k, X, lat, is_entry, by_reading, dt=dt,
                            steps=_horizon(model, k.key, dt), automaton=automaton)
            if out.exits and checks < FINAL_CHECKS:
                failed.append((k, [e for e in out.exits if e.kind != "assumption"], X))
            mismatch = [e for e in out.exits if e.kind == "assumption"]
            out.exits[:] = [e for e in out.exits if e.kind != "assumption"]
            final_exits += out.exits + mismatch[:3]
            final_exits += [Exit(k.key, k.mode, "(rest)", tuple(x.tolist()), tuple(x.tolist()),
                                 tuple(x.tolist()), "", "reachability")
                            for x in ([] if out.rests == 0 else [X[0]])]
            proved, why_not = _prove(task, model, k, by_reading)
            n = len(X)
            exits = len(out.exits)
            established = PROVED if proved and exits == 0 else SAMPLED
            note = why_not if established != PROVED else ""
            if exits:
                note = out.exits[0].describe()
            elif mismatch:
                note = (f"{len(mismatch)} drawn states leave by a sensor change the spec's "
                        f"assumptions rule out (task/spec mismatch), e.g. {mismatch[0].describe()}")
            elif k.key in stuck:
                note = stuck[k.key]
            claims.append(HandoffClaim(
                key=k.key, mode=k.mode,
                hands_to=tuple([*([k.next_mode] if k.next_mode else []),
                                *sorted(k.allowed - {k.next_mode})]),
                region=k.region, cuts=len(model.region_cuts(k.mode)),
                cuts_offline=len(model.region_cuts(k.mode)) - start_cuts[k.mode],
                face_cuts=face_cuts.get(k.mode, 0), established=established, samples=n,
                exits=exits, rests=out.rests,
                bound=(math.log(20.0 * checks) / n if n and exits == 0 else 1.0),
                rounds=rounds_used[k.key], note=note))
        failed = [f for f in failed if f[1]]
        if not failed:
            break
        for k, exits_k, X in failed:
            model, added, faces, why = _cut_round(task, model, k, exits_k, X, margin)
            face_cuts[k.mode] = face_cuts.get(k.mode, 0) + faces
            history.append((k.key, added))
            rounds_used[k.key] = r
        clean = 0  # learning resumes: two clean rounds again before the next check
    report = HandoffReport(model=model, claims=tuple(claims), exits=tuple(final_exits),
                           seed=int(seed), samples=int(samples), history=tuple(history))
    source = dict(model.source or {})
    source["handoff"] = report.record()
    from types import MappingProxyType

    model = Model(state_names=model.state_names, modes=model.modes, spec=model.spec,
                  path=model.path, source=MappingProxyType(source))
    return HandoffReport(model=model, claims=report.claims, exits=report.exits,
                         seed=report.seed, samples=report.samples, history=report.history)


def _flat(task: Task, k: _Key) -> bool:
    """Whether every boundary of the key's mode is flat (its cells, and the cells listed before
    them, are boxes and polytopes; for the background, every cell). On a curved boundary the
    boundary draws would ask for a tangent plane at every point (measured: 256 cuts for the
    4-D ellipsoid, exits left); there the uniform draws decide how many cuts are needed."""
    cells = task.partition.cells
    names = [c.name for c in cells]
    mine = [n for n in k.region if n in names]
    upto = len(cells) if (task.partition.background in k.region or not mine) \
        else max(names.index(n) for n in mine) + 1
    return all(isinstance(leaf, Box | Polytope)
               for c in (*cells[:upto], *task.partition.layers) for leaf in c.region.leaves())


def _to_boundary(task: Task, k: _Key, X: FloatArray, lat: BoolArray,
                 rng: np.random.Generator) -> FloatArray:
    """Move each state along a random direction to just inside the boundary of the set where
    the key's mode is read (bisection on the task's own sensors, the latches held): the
    states where an exit is likeliest (the adversarial part of the draw)."""
    if len(X) == 0:
        return X
    names = task.sensor_names
    own = np.array(sorted(_code(r, names) for r in k.readings), dtype=np.int64)
    bits = 1 << np.arange(len(names), dtype=np.int64)
    d = rng.normal(size=X.shape)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    size = float(np.max(np.array(task.hi) - np.array(task.lo)))
    lo = np.zeros(len(X))
    hi = np.full(len(X), size)

    def inside(t: FloatArray) -> npt.NDArray[np.bool_]:
        Y = X + t[:, None] * d
        r, _ = task.read(Y, Y, lat)
        ws = np.all((Y >= np.array(task.lo)) & (Y <= np.array(task.hi)), axis=1)
        return np.asarray(np.isin(r.astype(np.int64) @ bits, own) & ws)

    far = inside(hi)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        ok = inside(mid)
        lo = np.where(ok, mid, lo)
        hi = np.where(ok, hi, mid)
    t = np.where(far, 0.0, lo)  # a ray that never leaves: keep the state
    return np.asarray(X + t[:, None] * d)


def _starts(task: Task, k: _Key, samples: int, rng: np.random.Generator,
            entries: Sequence[tuple[FloatArray, BoolArray]]
            ) -> tuple[FloatArray, BoolArray, BoolArray]:
    """Drawn states of the mode (a quarter of them moved to just inside its boundary) plus (a
    quarter) hand-off states of previous modes."""
    n_entry = min(len(entries), samples // 4)
    X, lat = _draw(task, k, samples - n_entry, rng)
    q = len(X) // 4 if _flat(task, k) else 0
    if q:
        X = X.copy()
        X[:q] = _to_boundary(task, k, X[:q], lat[:q], rng)
    if n_entry:
        pick = rng.choice(len(entries), size=n_entry, replace=False)
        EX = np.array([entries[i][0] for i in pick.tolist()])
        EL = np.array([entries[i][1] for i in pick.tolist()], dtype=bool).reshape(
            n_entry, len(task.latent_names))
        flags = np.concatenate([np.zeros(len(X), dtype=bool), np.ones(n_entry, dtype=bool)])
        return np.vstack([X, EX]), np.vstack([lat, EL]), flags
    return X, lat, np.zeros(len(X), dtype=bool)


def _cut_round(task: Task, model: Model, k: _Key, exits: Sequence[Exit], starts: FloatArray,
               margin: float) -> tuple[Model, int, int, str]:
    """Cut the exits of one round: every distinct face cut, else one QCQP cut; returns the
    model, the cuts added, the face cuts among them and why none was added."""
    attractors = [model.modes[kk].ds.attractor for kk in model.keys_of(k.mode)]
    added = faces = 0
    why = ""
    qcqp_done = False
    for e in exits:
        last = np.array(e.last_inside)
        out = np.array(e.outside)
        existing = model.region_cuts(k.mode)
        if any(float(c.normal @ (out - c.point)) > 0.0 >= float(c.normal @ (last - c.point))
               for c in existing[len(existing) - added:]) and added:
            continue  # a cut of this round already separates this exit
        face = _face_cut(task, attractors, last, out, existing)
        if face is not None:
            try:
                model = model.add_cut(k.key, face[0])
            except ModelError:
                pass
            else:
                added += 1
                faces += 1
                continue
        if qcqp_done:
            continue
        inside = starts[np.all([(starts - c.point) @ c.normal <= 0.0 for c in existing], axis=0)
                        ] if existing else starts
        keep = inside[np.argsort(np.linalg.norm(inside - np.array(e.entry), axis=1))[:48]]
        try:
            failure = InvarianceFailure(entry=np.array(e.entry), last_inside=last, outside=out)
        except ModelError as exc:
            why = str(exc)
            continue
        oc = online_cut(model, k.key, k.mode, failure, list(keep), margin=margin)
        qcqp_done = True
        if oc.model is None:
            why = (f"{e.describe()}: no cut separates it ({oc.error}); the region crossed lies "
                   "between the start and the attractor (a composition gap no cut can close)")
            continue
        model = oc.model
        added += 1
    return model, added, faces, why


def _region_names(task: Task, readings: frozenset[frozenset[str]]) -> tuple[str, ...]:
    """The cells where a mode's label (one of ``readings``) can hold, under some latch
    valuation (computed once per DS key, by :func:`_plan`)."""
    names = task.sensor_names
    vals = _valuations(len(task.latent_names))
    out: list[str] = []
    for nr_name in task.region_names:
        pts = _cell_points(task, nr_name)
        if pts is None:
            continue
        X = np.repeat(pts, len(vals), axis=0)
        lat = np.tile(vals, (len(pts), 1))
        reading, _ = task.read(X, X, lat)
        if any(frozenset(n for n, v in zip(names, row, strict=True) if v) in readings
               for row in reading.tolist()):
            out.append(nr_name)
    return tuple(out)


def _cell_points(task: Task, name: str) -> FloatArray | None:
    try:
        return task.sample_region(name, 8, np.random.default_rng(0))
    except TliError:
        return None


# ------------------------------------------------------------------------------ proof
def _as_polytope(prim: Primitive) -> tuple[FloatArray, FloatArray] | None:
    if isinstance(prim, Polytope):
        return np.asarray(prim.A, dtype=np.float64), np.asarray(prim.b, dtype=np.float64)
    if isinstance(prim, Box):
        n = prim.lower.size
        rows: list[FloatArray] = []
        rhs: list[float] = []
        for i in range(n):
            if math.isfinite(float(prim.upper[i])):
                e = np.zeros(n)
                e[i] = 1.0
                rows.append(e)
                rhs.append(float(prim.upper[i]))
            if math.isfinite(float(prim.lower[i])):
                e = np.zeros(n)
                e[i] = -1.0
                rows.append(e)
                rhs.append(-float(prim.lower[i]))
        return np.array(rows).reshape(len(rows), n), np.array(rhs)
    return None


def _lp_max(c: FloatArray, A: FloatArray, b: FloatArray) -> float | None:
    """max c.x over {A x <= b}; None if infeasible, inf if unbounded."""
    from scipy.optimize import linprog

    res = linprog(-c, A_ub=A, b_ub=b, bounds=[(None, None)] * c.size, method="highs")
    if res.status == 2:
        return None
    if res.status == 3:
        return math.inf
    if res.status != 0:
        return math.inf  # undecided: treated as "not contained"
    return float(-res.fun)


def _prove(task: Task, model: Model, k: _Key,
           by_reading: Mapping[frozenset[str], frozenset[str]]) -> tuple[bool, str]:
    """(E1)-(E2) decided exactly for a mode that is one box or polytope cell (module
    docstring, step 4); returns (proved, why not)."""
    if task.partition.layers or not isinstance(task.sensor_model, FormulaSensors):
        return False, "the task has layers or a sensor plug-in (not decided exactly)"
    cells = task.partition.cells
    region = k.region
    if len(region) != 1 or region[0] == task.partition.background:
        return False, "the mode's region is not one box or polytope cell (sampled)"
    idx = [c.name for c in cells].index(region[0])
    shape = cells[idx].region
    if not isinstance(shape, Box | Polytope):
        return False, f"region {region[0]!r} is not a box or polytope (sampled)"
    poly = _as_polytope(shape)
    assert poly is not None
    A, b = poly
    lo, hi = np.array(task.lo), np.array(task.hi)
    n = lo.size
    W = np.vstack([np.eye(n), -np.eye(n)])
    wb = np.concatenate([hi, -lo])
    # the cell is the shape: no earlier cell overlaps it (an LP per earlier polytope cell)
    for other in cells[:idx]:
        op = _as_polytope(other.region) if isinstance(other.region, Box | Polytope) else None
        if op is None:
            return False, f"earlier region {other.name!r} is not a box or polytope (sampled)"
        if _interior_meet(np.vstack([A, op[0], W]), np.concatenate([b, op[1], wb])):
            return False, f"region {region[0]!r} overlaps the earlier region {other.name!r}"
    cuts = model.region_cuts(k.mode)
    attractors = [model.modes[kk].ds.attractor for kk in model.keys_of(k.mode)]
    norms = np.linalg.norm(A, axis=1)
    handoff_rows: list[int] = []
    for j in range(len(A)):
        a_j = A[j] / norms[j]
        b_j = b[j] / norms[j]
        inside = all(float(a_j @ xs) < b_j for xs in attractors)
        if not inside:
            handoff_rows.append(j)
            continue
        # (E1): a cut with this facet's normal at most _INWARD-close inside it
        tol = 2e-9 * (1.0 + max(abs(b_j), 1.0))
        if not any(np.allclose(c.normal, a_j, atol=1e-9)
                   and float(a_j @ c.point) >= b_j - tol for c in cuts):
            # a facet of the shape outside the workspace is harmless: the cell there is empty
            if _lp_max(a_j, np.vstack([A, W]), np.concatenate([b, wb])) is not None and \
                    _lp_max(a_j, np.vstack([A, W]), np.concatenate([b, wb])) >= b_j - 1e-12:
                return False, f"facet {j} of region {region[0]!r} is not a cut (E1 not shown)"
    # every cut keeps the whole cell inside (E1 for every state of the cell)
    for c in cuts:
        m = _lp_max(c.normal, np.vstack([A, W]), np.concatenate([b, wb]))
        if m is None:
            continue
        if m > float(c.normal @ c.point) + 2e-9 * (1.0 + abs(float(c.normal @ c.point))):
            return False, "a cut of the mode excludes part of its region (E1 fails)"
    # (E2): every hand-off facet, within the cuts and the workspace, lies in an allowed mode's
    # box or polytope cell listed before any cell that could override it there
    CA = np.array([c.normal for c in cuts]).reshape(len(cuts), n)
    Cb = np.array([float(c.normal @ c.point) for c in cuts])
    for j in handoff_rows:
        FA = np.vstack([A, -A[j:j + 1], CA, W])
        Fb = np.concatenate([b, -b[j:j + 1], Cb, wb])
        if _lp_max(A[j], FA, Fb) is None:
            continue  # the facet lies outside the cuts or the workspace
        ok = False
        for t, cell in enumerate(cells):
            if t == idx:
                continue
            tp = _as_polytope(cell.region) if isinstance(cell.region, Box | Polytope) else None
            if tp is None:
                if _lp_feasible_meet(FA, Fb, cell.region):
                    break
                continue
            TA, Tb = tp
            contained = all((m := _lp_max(TA[r], FA, Fb)) is not None and m <= Tb[r]
                            for r in range(len(TA)))
            if contained:
                reading = _handoff_readings(task, region[0], cell.name, k)
                if reading and all(by_reading.get(rr, frozenset()) & k.allowed
                                   for rr in reading):
                    ok = True
                break
            if _interior_meet(np.vstack([FA, TA]), np.concatenate([Fb, Tb]), flat=True):
                break  # an earlier cell covers part of the facet only: not decided
        if not ok:
            return False, (f"facet {j} of region {region[0]!r} (a hand-off facet) does not lie "
                           "in one cell of an allowed mode within the cuts (E2 not shown)")
    return True, ""


def _convex_cell(task: Task, k: _Key) -> tuple[int, FloatArray, FloatArray] | None:
    """The mode's region as ``(cell index, A, b)`` when it is one box or polytope cell."""
    region = k.region
    cells = [c.name for c in task.partition.cells]
    if len(region) != 1 or region[0] not in cells:
        return None
    idx = cells.index(region[0])
    shape = task.partition.cells[idx].region
    poly = _as_polytope(shape) if isinstance(shape, Box | Polytope) else None
    return None if poly is None else (idx, poly[0], poly[1])


def _facet_cuts(task: Task, model: Model, k: _Key) -> tuple[Model, int]:
    """Every facet of a convex cell mode that keeps all the mode's attractors strictly inside
    and meets the workspace, as a cut (just inside the facet); returns the model and the count."""
    cell = _convex_cell(task, k)
    if cell is None:
        return model, 0
    _, A, b = cell
    lo, hi = np.array(task.lo), np.array(task.hi)
    n = lo.size
    W = np.vstack([np.eye(n), -np.eye(n)])
    wb = np.concatenate([hi, -lo])
    attractors = [model.modes[kk].ds.attractor for kk in model.keys_of(k.mode)]
    added = 0
    for j in range(len(A)):
        nj = float(np.linalg.norm(A[j]))
        a_j, b_j = A[j] / nj, float(b[j]) / nj
        if not all(b_j - float(a_j @ xs) > 1e-6 * max(1.0, abs(b_j)) for xs in attractors):
            continue
        top = _lp_max(a_j, np.vstack([A, W]), np.concatenate([b, wb]))
        if top is None or top < b_j - 1e-12:
            continue  # the facet lies outside the workspace
        dist = min(b_j - float(a_j @ xs) for xs in attractors)
        point = a_j * (b_j - _INWARD * (1.0 + dist))
        cut = Cut(normal=a_j, point=point)
        if any(np.allclose(cut.normal, c.normal, atol=1e-12) and
               abs(float(c.normal @ (cut.point - c.point))) <= 1e-12 * (1.0 + abs(b_j))
               for c in model.region_cuts(k.mode)):
            continue
        try:
            model = model.add_cut(k.key, cut)
        except ModelError:
            continue
        added += 1
    return model, added


def _interior_meet(A: FloatArray, b: FloatArray, *, flat: bool = False) -> bool:
    """Whether ``{A x <= b}`` has interior (a Chebyshev ball of positive radius); with
    ``flat``, whether it is non-empty at all (a facet is flat)."""
    from scipy.optimize import linprog

    n = A.shape[1]
    if flat:
        res = linprog(np.zeros(n), A_ub=A, b_ub=b + 1e-12, bounds=[(None, None)] * n,
                      method="highs")
        return bool(res.status == 0)
    norms = np.linalg.norm(A, axis=1)
    c = np.zeros(n + 1)
    c[-1] = -1.0
    res = linprog(c, A_ub=np.hstack([A, norms[:, None]]), b_ub=b,
                  bounds=[(None, None)] * n + [(0, 1e6)], method="highs")
    return bool(res.status == 0 and -res.fun > 1e-9)


def _lp_feasible_meet(A: FloatArray, b: FloatArray, region: Any) -> bool:
    """Conservative: a non-polytope cell may meet the facet (True unless its bounding box
    misses the facet's)."""
    rlo, rhi = region.bounds()
    n = A.shape[1]
    for i in range(n):
        e = np.zeros(n)
        e[i] = 1.0
        top = _lp_max(e, A, b)
        bot = _lp_max(-e, A, b)
        if top is None or bot is None:
            return False
        if top < float(rlo[i]) or -bot > float(rhi[i]):
            return False
    return True


def _handoff_readings(task: Task, source: str, target: str, k: _Key) -> list[frozenset[str]]:
    """The readings of a step from cell ``source`` into cell ``target``, for every latch
    valuation under which ``source`` reads the key's mode (exact for cell-based formula
    sensors without layers: the reading depends on the cells and the latches only)."""
    a = _cell_points(task, source)
    b = _cell_points(task, target)
    if a is None or b is None:
        return []
    vals = _valuations(len(task.latent_names))
    names = task.sensor_names
    A = np.repeat(a[:1], len(vals), axis=0)
    first, lat = task.read(A, A, vals)
    mine = [frozenset(n for n, v in zip(names, row, strict=True) if v) in k.readings
            for row in first.tolist()]
    if not any(mine):
        return []
    keep = np.array(mine, dtype=bool)
    B = np.repeat(b[:1], int(keep.sum()), axis=0)
    nxt, _ = task.read(A[keep], B, lat[keep])
    return [frozenset(n for n, v in zip(names, row, strict=True) if v)
            for row in nxt.tolist()]


# ------------------------------------------------------------------------------ re-check
def recheck_handoffs(task: Task, automaton: TaskAutomaton, model: Model, *,
                     goal_modes: Sequence[str] | None = None) -> list[tuple[HandoffClaim, bool,
                                                                             str]]:
    """Re-decide every claim the model's ``source.handoff`` record calls proved (the exact
    part: (E1)-(E2) by linear programs on the task's regions and the model's cuts).

    Returns
    -------
    list of (claim, ok, message)
        One per recorded claim; sampled and online claims are reported as tested, not proved
        (``ok`` True: nothing to re-decide).
    """
    rec = (model.source or {}).get("handoff")
    if not rec:
        return []
    where = str(model.path or "model")
    if not isinstance(rec, Mapping) or not isinstance(rec.get("claims"), list):
        raise ModelError(f"{where}: source.handoff: malformed record")
    keys, by_reading = _plan(task, automaton, model, goal_modes)
    by_key = {k.key: k for k in keys}
    out: list[tuple[HandoffClaim, bool, str]] = []
    for raw in rec["claims"]:
        if not isinstance(raw, Mapping):
            raise ModelError(f"{where}: source.handoff: malformed claim")
        claim = HandoffClaim.from_dict(raw, where)
        if claim.established != PROVED:
            what = (f"tested on {claim.samples} states, {claim.exits} exits"
                    if claim.established == SAMPLED else "online only")
            out.append((claim, True, f"{claim.key}: {claim.established} ({what})"))
            continue
        k = by_key.get(claim.key)
        if k is None:
            out.append((claim, False, f"{claim.key}: claimed proved, but the plan does not "
                        "run this DS"))
            continue
        ok, why = _prove(task, model, k, by_reading)
        out.append((claim, ok, f"{claim.key}: proved (re-decided: invariant from every "
                    f"state of {', '.join(claim.region)}, hands off to "
                    f"{', '.join(claim.hands_to)})" if ok else
                    f"{claim.key}: claimed proved, re-check fails: {why}"))
    return out


# ------------------------------------------------------------------------------ entry points
@dataclass(frozen=True, slots=True, eq=False)
class HandoffContext:
    """What the hand-off step needs besides the model: the task, the automaton and the goal
    (settled from a spec file by :func:`context_for_spec`)."""

    task: Task
    automaton: TaskAutomaton
    goal_modes: tuple[str, ...]


def context_for_spec(spec_path: str | Any) -> HandoffContext | None:
    """The task the spec names (None: it names none, or its sensors are computed by physics:
    boundaries are learned online there), its automaton and its goal (the spec's, else the
    task's, else the sink modes; checked reachable)."""
    spec = load_spec(spec_path)
    task = spec_task(spec, spec_path)
    if task is None or bool(getattr(task.sensor_model, "physics", False)):
        return None
    automaton = synthesize(spec)
    goal = (Goal(spec.goal_modes, spec.goal_sensors)
            if spec.goal_modes is not None or spec.goal_sensors else task.goal)
    modes = check_goal(automaton, goal, where=str(spec_path))
    return HandoffContext(task=task, automaton=automaton, goal_modes=tuple(modes))


def retest_handoffs(task: Task, automaton: TaskAutomaton, model: Model, *, dt: float,
                    goal_modes: Sequence[str] | None = None, samples: int = 200,
                    seed: int = 0) -> dict[str, list[Exit]]:
    """Draw ``samples`` fresh states per DS key (with the modes' hand-off states) on ``seed``
    and simulate them with the model's cuts, learning nothing: the exits each key shows (the
    gate's own test of a *sampled* claim)."""
    keys, by_reading = _plan(task, automaton, model, goal_modes)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 31]))
    entries: dict[str, list[tuple[FloatArray, BoolArray]]] = {}
    out: dict[str, list[Exit]] = {}
    for _ in range(2):  # the second pass starts from the first's hand-off states too
        for k in keys:
            X, lat, is_entry = _starts(task, k, samples, rng, entries.get(k.mode, []))
            res = _simulate(task, model, k, X, lat, is_entry, by_reading, dt=dt,
                            steps=_horizon(model, k.key, dt), automaton=automaton)
            out.setdefault(k.key, []).extend(e for e in res.exits if e.kind != "assumption")
            for mode, x, la in res.handed:
                entries.setdefault(mode, []).append((x, la))
    return out


def handoff_status(model: Model, spec_path: str | Any, *, retest: int = 0,
                   seed: int = 0) -> tuple[bool, list[str]]:
    """The hand-off guarantees of a model file, re-checked where they can be: one line per
    DS (proved and re-decided, tested on N states, or online only), and whether nothing
    fails (a proved claim that does not re-decide, or a recorded hand-off with exits).

    Returns
    -------
    ok : bool
    lines : list of str
    """
    rec = (model.source or {}).get("handoff")
    ctx = context_for_spec(spec_path)
    if ctx is None:
        return True, ["hand-off: online only (the task's sensors are computed by physics, or "
                      "the spec names no task)"]
    if not rec:
        return True, ["hand-off: not established offline (the model has no hand-off record: "
                      "its modes' boundaries are learned online; tli learn records it)"]
    ok = True
    lines: list[str] = []
    found: dict[str, list[Exit]] = {}
    if retest:
        found = retest_handoffs(ctx.task, ctx.automaton, model, dt=ctx.task.dt,
                                goal_modes=ctx.goal_modes, samples=retest, seed=seed)
    for claim, good, msg in recheck_handoffs(ctx.task, ctx.automaton, model,
                                             goal_modes=ctx.goal_modes):
        if not good or (claim.established != PROVED and not claim.holds):
            ok = False
            msg = msg if not good else f"{msg}: {claim.note}"
        elif claim.established == SAMPLED and retest:
            bad = found.get(claim.key, [])
            if bad and claim.exits == 0:
                ok = False
                msg = (f"{msg}; re-tested on {2 * retest} fresh states (seed {seed}): "
                       f"{len(bad)} exit(s), the claim does not hold: {bad[0].describe()}")
            else:
                msg += f"; re-tested on {2 * retest} fresh states (seed {seed}): 0 exits"
        lines.append(msg)
    return ok, lines
