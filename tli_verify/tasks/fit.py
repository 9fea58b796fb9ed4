"""Does a task fit its spec? Every sensor change the task can produce, under any push, decided
on its geometry and checked against the spec's assumptions (issue 30, "checks before
learning").

The readings of a task file's formula sensors depend on a state only through the cell of the
partition it lies in and the layers that hold it, and on the latches. So the changes a task can
produce are found exactly on a finite graph: its *atoms* (each non-empty combination of a cell
and layers, with one state of it) times the latch valuations reachable from the start, with an
edge from every atom to every atom (a push may move the state anywhere in the workspace). Each
edge gives a sensor change ``r -> r'``; the spec allows it when the task automaton has a state
read ``r`` that takes ``r'`` (its environment assumptions do not rule it out). A change the
spec rules out is a task/spec mismatch: at run time it is an assumption violation, the
guarantees are void from there, and no campaign can pass. The atoms are found by sampling each
cell (and layer) and the workspace; a cell too small to sample is reported, not assumed empty.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton
from tli_verify.tasks.task import Task

__all__ = ["Mismatch", "sensor_changes", "task_spec_mismatches"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Mismatch:
    """A sensor change the task can produce that the spec's assumptions rule out.

    Attributes
    ----------
    before, after : tuple of str
        The true sensors before and after (``()``: none; ``before`` is ``None`` for a first
        reading the initial assumptions rule out).
    region_before, region_after : str
        The regions (cells, with their layers) of the two states.
    latches : tuple of str
        The latches set before the change.
    """

    before: tuple[str, ...] | None
    after: tuple[str, ...]
    region_before: str
    region_after: str
    latches: tuple[str, ...]

    def describe(self) -> str:
        """One line naming the pair of regions."""
        def show(r: tuple[str, ...]) -> str:
            return "{" + ", ".join(r) + "}"

        if self.before is None:
            return (f"a start in region {self.region_after} reads {show(self.after)}, which "
                    "the spec's initial assumptions rule out")
        held = f" with latches {', '.join(self.latches)} set" if self.latches else ""
        return (f"a move or push from region {self.region_before} to region "
                f"{self.region_after}{held} changes the reading {show(self.before)} -> "
                f"{show(self.after)}, which the spec's assumptions rule out")


def _atoms(task: Task, rng: np.random.Generator, per: int = 64) -> list[tuple[str, FloatArray]]:
    """One state per non-empty (cell, layers) combination, with its name."""
    names = list(task.region_names)
    layers = task.partition.layers
    lo, hi = np.array(task.lo), np.array(task.hi)
    pts = [rng.uniform(lo, hi, size=(4096, lo.size))]
    for n in (*names, *(la.name for la in layers)):
        try:
            pts.append(task.sample_region(n, per, rng))
        except TaskError:
            continue
    X = np.concatenate(pts)
    idx = task.region_index(X)
    bits = np.zeros(len(X), dtype=np.int64)
    for i, la in enumerate(layers):
        bits |= la.region.contains(X).astype(np.int64) << i
    out: list[tuple[str, FloatArray]] = []
    seen: set[tuple[int, int]] = set()
    for j in range(len(X)):
        key = (int(idx[j]), int(bits[j]))
        if key in seen:
            continue
        seen.add(key)
        lay = [la.name for i, la in enumerate(layers) if (key[1] >> i) & 1]
        out.append((names[key[0]] + (f" (in {', '.join(lay)})" if lay else ""), X[j]))
    return out


def sensor_changes(task: Task, *, seed: int = 0
                   ) -> tuple[set[frozenset[str]],
                              dict[tuple[frozenset[str], frozenset[str]],
                                   tuple[str, str, tuple[str, ...]]]]:
    """The first readings and the sensor changes a task can produce (module docstring).

    Returns
    -------
    first : set of frozenset of str
        Readings at a start anywhere in the workspace.
    changes : dict
        ``(reading, next reading) -> (region before, region after, latches set)`` (one
        witness per change).
    """
    if not bool(getattr(task.sensor_model, "cell_based", False)):
        raise TaskError(f"{task.where}: its sensors are not computed from the regions alone "
                        "(a plug-in): the changes they can produce are not decided here")
    rng = np.random.default_rng(seed)
    atoms = _atoms(task, rng)
    names = task.sensor_names
    latches = task.latent_names

    def reading(row: npt.NDArray[np.bool_]) -> frozenset[str]:
        return frozenset(n for n, v in zip(names, row.tolist(), strict=True) if v)

    P = np.array([x for _, x in atoms])
    init = task.initial_latent(len(P))
    r0, l0 = task.read(P, P, init)
    first = {reading(r) for r in r0}
    start = [(i, tuple(bool(v) for v in l0[i].tolist()), reading(r0[i]))
             for i in range(len(atoms))]
    seen = {(i, la) for i, la, _ in start}
    queue = deque(start)
    changes: dict[tuple[frozenset[str], frozenset[str]], tuple[str, str, tuple[str, ...]]] = {}
    while queue:
        i, la, r = queue.popleft()
        A = np.repeat(P[i:i + 1], len(P), axis=0)
        L = np.tile(np.array(la, dtype=bool).reshape(1, -1), (len(P), 1))
        r1, l1 = task.read(A, P, L)
        for j in range(len(P)):
            rr = reading(r1[j])
            changes.setdefault((r, rr), (atoms[i][0], atoms[j][0],
                                         tuple(n for n, v in zip(latches, la, strict=True)
                                               if v)))
            nxt = (j, tuple(bool(v) for v in l1[j].tolist()))
            if nxt not in seen:
                seen.add(nxt)
                queue.append((j, nxt[1], rr))
    return first, changes


def task_spec_mismatches(task: Task, automaton: TaskAutomaton, *, seed: int = 0
                         ) -> list[Mismatch]:
    """Every sensor change (and first reading) the task can produce that the spec's
    assumptions rule out, with a witness pair of regions (module docstring)."""
    _, changes = sensor_changes(task, seed=seed)
    out: list[Mismatch] = []
    # random starts are drawn among the states the initial assumption allows; the nominal
    # starts must be such states
    if task.starts.nominal:
        X = np.array(task.starts.nominal, dtype=np.float64)
        r0, _ = task.read(X, X, task.initial_latent(len(X)))
        for x, row in zip(X, r0, strict=True):
            r = frozenset(n for n, v in zip(task.sensor_names, row.tolist(), strict=True) if v)
            try:
                automaton.initial_state(r)
            except AssumptionViolation:
                name = task.region_names[int(task.region_index(x[None, :])[0])]
                out.append(Mismatch(None, tuple(sorted(r)), "",
                                    f"{name} (nominal start {x.tolist()})", ()))
    by_reading: dict[frozenset[str], list[int]] = {}
    for s in automaton.states:
        by_reading.setdefault(frozenset(s.inputs), []).append(s.id)
    for (r, rr), (ra, rb, la) in sorted(changes.items(), key=lambda kv: (sorted(kv[0][0]),
                                                                         sorted(kv[0][1]))):
        states = by_reading.get(r, [])
        if not states:
            continue  # a reading no state has: reported as the change into it
        ok = False
        for sid in states:
            try:
                automaton.next_mode(sid, rr)
            except AssumptionViolation:
                continue
            ok = True
            break
        if not ok:
            out.append(Mismatch(tuple(sorted(r)), tuple(sorted(rr)), ra, rb, la))
    return out
