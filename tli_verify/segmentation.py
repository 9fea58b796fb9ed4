"""Sensor-based segmentation and attractor identification (paper Sec. 5.1, appendix C).

Samples are grouped into modes by their sensor reading (paper Sec. 3: a mode is a label of
sensor states, ``sigma = L(alpha)``):

* with a spec, a sample belongs to every mode whose ``[modes]`` label holds for its reading
  (several modes may share a label -- cooking's ``w1``/``w2`` -- and then share the motion
  policy, paper appendix "Generalization": "they share the same motion policy");
* without a spec, each distinct sensor reading is a mode, named by its full conjunction in Spot
  syntax (``"!r & s & !t"``);
* without sensor columns, everything is one mode, ``"main"``.

Consecutive samples with the same modes form a *segment*.

Attractors -- a deliberate deviation from appendix C. Appendix C (Table 1) puts the attractor
``x*_i`` of mode ``i`` at the mean of the *last* states of its segments. Those states read mode
``i``, so ``x*_i`` lies in ``delta_i``: the DS converges to a state the next sensor never
reads, and the transition the automaton waits for need not happen (an earlier bundled scoop
model: the attractor of ``a`` 0.056 outside the soup disc; only 44 of 300 random mode-``a``
starts ever entered the disc, ``scripts/lemma2_check.py``). Lemma 2's proof needs ``x*_i``
*strictly* inside the next region ``delta_j``: an asymptotically stable DS reaches ``x*`` only
in the limit, but every open neighbourhood of it in finite time, so an interior attractor makes
every trajectory enter ``delta_j`` in finite time.
Here, for a segment followed by a segment of mode ``j``, the *entry point* is the mean of the
first ``entry_samples`` (default :data:`ENTRY_SAMPLES` = 3) states of that following segment,
and the attractor is the mean of the entry points of the DS's segments:

* every averaged state reads ``j``, so it lies in ``delta_j``; by paper Asm. 1 (``delta_j``
  convex) so does their mean;
* it is strictly inside: the mean of points with positive weights lies in the relative interior
  of their convex hull, which is interior to ``delta_j`` as soon as the points span the state
  space (three demonstrations in 2-D do) or one of them is interior -- the second and third
  sample after a crossing are, unless a demonstration runs along the boundary. The first sample
  alone is less than one sampling step past the boundary (bundled scoop demos at 20 Hz: the
  attractors of ``a``, ``b``, ``c`` are 0.055, 0.080, 0.030 inside the next region with one
  sample, 0.160, 0.199, 0.083 with three): the margin sets how soon trajectories enter;
* it stays close to the demonstrated hand-over: ``entry_samples`` steps past the crossing, not
  deep in ``delta_j`` (the DS of mode ``i`` is learned from mode-``i`` data only and must not
  extrapolate far).

A segment that ends its demonstration keeps its end point (the task's final mode, e.g. ``d``);
a DS whose segments sometimes hand over and sometimes end the demonstration uses only the
handing-over segments' entry points. With ``shift`` (default), every segment is translated by
``x* - (its own entry point)`` before learning, so that each demonstration hands over exactly at
the common attractor (appendix "Generalization", Fig. 10(b): "segmented into parts by mode
region, which are then shifted to their average attractor locations"); a segment ending its
demonstration is translated to end on ``x*``, as in appendix C.

Per-transition DS (paper appendix "Generalization", Fig. 10(b)): when the segments of a mode are
followed by different next modes, a mode-based DS would average conflicting attractors, so one DS
is learned per transition instead, keyed ``"<mode>-><next>"`` (attractor from the segments of
``mode`` followed by ``next``, with the entry-point rule above). The same holds when a mode hands
over in some demonstrations and ends others (cooking's pot: passed through after the first
ingredient, the final mode after the second): the hand-overs get ``"<mode>-><next>"`` and the
segments that end a demonstration (no next mode) keep the plain key ``"<mode>"``, a DS that stays
in the mode (its attractor the mean end point; dropped when those segments have fewer than 2
samples in all, too few to learn from). A mode whose segments all hand over to one next mode, or
all end their demonstration, has the plain key only. When modes share a label, every
pair of a mode of the group and a mode of the next group gets the key (the automaton decides at
run time which one it needs).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import numpy.typing as npt

from tli_verify.demos import Demonstration
from tli_verify.errors import DemoError
from tli_verify.logic.labels import Labeler, spec_labeler
from tli_verify.logic.labels import runs as _runs

__all__ = [
    "DEFAULT_MODE",
    "Labeler",
    "ModeData",
    "Segment",
    "Segmentation",
    "segment_demos",
    "sensor_state_labeler",
    "spec_labeler",
    "transition_key",
]

FloatArray = npt.NDArray[np.float64]

DEFAULT_MODE = "main"
"""The mode name used when the demonstrations have no sensor columns."""

ENTRY_SAMPLES = 3
"""Default number of next-mode samples averaged into an attractor (see the module docstring)."""

TRANSITION = "->"
"""Separator of per-transition DS keys: ``"<mode>-><next>"``."""

"""Maps one sensor reading to the modes whose label holds (empty: no mode)."""


def transition_key(mode: str, next_mode: str | None) -> str:
    """The model key of a DS: ``mode``, or ``"mode->next"`` for a per-transition DS."""
    return mode if next_mode is None else f"{mode}{TRANSITION}{next_mode}"


def sensor_state_labeler(sensor_names: Sequence[str]) -> Labeler:
    """Label-free segmentation: each distinct reading is its own mode.

    The mode of a reading is its full conjunction, e.g. ``"!r & s & !t"``; with no sensors,
    :data:`DEFAULT_MODE`.
    """
    names = tuple(sensor_names)

    def label(reading: Mapping[str, bool]) -> tuple[str, ...]:
        if not names:
            return (DEFAULT_MODE,)
        return (" & ".join(n if reading[n] else f"!{n}" for n in names),)

    return label


@dataclass(frozen=True, slots=True)
class Segment:
    """A maximal run of samples of one demonstration with the same modes.

    Attributes
    ----------
    demo : int
        Index of the demonstration.
    start, stop : int
        Rows ``start .. stop-1``.
    modes : tuple of str
        Modes whose label holds on these rows (one without shared labels).
    next_modes : tuple of str or None
        Modes of the following segment; None when the segment ends the demonstration.
    """

    demo: int
    start: int
    stop: int
    modes: tuple[str, ...]
    next_modes: tuple[str, ...] | None


@dataclass(frozen=True, slots=True, eq=False)
class ModeData:
    """The training data of one DS (a mode, or a mode transition).

    Attributes
    ----------
    key : str
        Model key: ``mode`` or ``"mode->next"``.
    mode : str
    next_mode : str or None
        The next mode for a per-transition DS; the unique observed next mode otherwise (None when
        there is none or several).
    attractor : ndarray, shape (n,)
        Mean entry point into the next mode (module docstring; appendix C's mean last state
        only for a DS whose segments all end their demonstration).
    x : ndarray, shape (N, n)
        Positions, each segment shifted so that its entry point (or end) is the attractor.
    dx : ndarray, shape (N, n)
        Velocities.
    segments : tuple of Segment
    """

    key: str
    mode: str
    next_mode: str | None
    attractor: FloatArray
    x: FloatArray
    dx: FloatArray
    segments: tuple[Segment, ...]


@dataclass(frozen=True, slots=True)
class Segmentation:
    """Segments of all demonstrations and the per-DS training data.

    Attributes
    ----------
    modes : tuple of str
        Every mode (spec order, or order of first appearance).
    segments : tuple of Segment
    data : mapping of str to ModeData
        DS key -> training data.
    """

    modes: tuple[str, ...]
    segments: tuple[Segment, ...]
    data: Mapping[str, ModeData] = field(default_factory=lambda: MappingProxyType({}))


def segment_demos(
    demos: Sequence[Demonstration],
    *,
    labeler: Labeler | None = None,
    modes: Sequence[str] | None = None,
    labels: Mapping[str, str] | None = None,
    shift: bool = True,
    entry_samples: int = ENTRY_SAMPLES,
) -> Segmentation:
    """Segment demonstrations by sensor readings and compute per-DS data (appendix C, Lemma 2).

    Parameters
    ----------
    demos : sequence of Demonstration
        Validated demonstrations with the same sensors and dimension.
    labeler : Labeler, optional
        Reading -> modes. Default: :func:`sensor_state_labeler` (each reading is a mode).
    modes : sequence of str, optional
        Every mode that must be visited (paper Asm. 3), e.g. the spec's labelled modes.
    labels : mapping of str to str, optional
        Mode -> label formula, quoted in messages.
    shift : bool, optional
        Translate each segment so that its entry point into the next mode (its end point, if
        it ends the demonstration) is its DS's attractor.
    entry_samples : int, optional
        Number of states of the next mode averaged into a segment's entry point (>= 1).

    Returns
    -------
    Segmentation

    Raises
    ------
    DemoError
        A reading no mode label covers (file and line named); a mode of ``modes`` that no
        demonstration visits (paper Asm. 3); a DS with fewer than 2 samples; ``entry_samples``
        below 1.
    """
    if entry_samples < 1:
        raise DemoError(f"entry_samples must be >= 1, got {entry_samples}")
    if not demos:
        raise DemoError("no demonstrations to segment")
    label = labeler or sensor_state_labeler(demos[0].sensor_names)
    segments: list[Segment] = []
    order: list[str] = []
    for d_idx, demo in enumerate(demos):
        cache: dict[bytes, tuple[str, ...]] = {}
        groups: list[tuple[str, ...]] = []
        for i in range(demo.n_samples):
            row = demo.sensors[i]
            key = row.tobytes()
            if key not in cache:
                cache[key] = label(demo.sensor_reading(i))
            group = cache[key]
            if not group:
                reading = ", ".join(f"{n}={int(v)}" for n, v in
                                    zip(demo.sensor_names, row, strict=True))
                raise DemoError(f"{demo.where(i)}: sensor reading {reading} satisfies no mode "
                                "label of the spec")
            groups.append(group)
            for m in group:
                if m not in order:
                    order.append(m)
        runs = _runs(groups)
        for r, (start, stop) in enumerate(runs):
            nxt = groups[runs[r + 1][0]] if r + 1 < len(runs) else None
            segments.append(Segment(d_idx, start, stop, groups[start], nxt))
    all_modes = tuple(modes) if modes is not None else tuple(order)
    visited = set(order)
    for m in all_modes:
        if m not in visited:
            lab = f" (label {labels[m]!r})" if labels and m in labels else ""
            raise DemoError(f"mode {m!r}{lab} is visited by no demonstration; every mode needs "
                            "demonstration data (paper Asm. 3)")
    data = _mode_data(demos, segments, shift, entry_samples)
    return Segmentation(modes=all_modes, segments=tuple(segments),
                        data=MappingProxyType(data))


def _target(demos: Sequence[Demonstration], seg: Segment, following: Segment | None,
            entry_samples: int) -> FloatArray:
    """The point a segment heads for: the mean of the first ``entry_samples`` states of the
    following segment (all in the next mode), or the segment's last state if none follows."""
    if following is None:
        return np.asarray(demos[seg.demo].x[seg.stop - 1], dtype=np.float64)
    stop = min(following.start + entry_samples, following.stop)
    return np.asarray(demos[seg.demo].x[following.start:stop].mean(axis=0), dtype=np.float64)


def _mode_data(demos: Sequence[Demonstration], segments: list[Segment], shift: bool,
               entry_samples: int) -> dict[str, ModeData]:
    """Group segments into DS keys (plain or per-transition) and build their data."""
    after = {(s.demo, s.start): s for s in segments}
    by_group: dict[tuple[str, ...], list[Segment]] = {}
    for seg in segments:
        by_group.setdefault(seg.modes, []).append(seg)
    # (key, mode, next_mode) -> segments
    buckets: dict[tuple[str, str, str | None], list[Segment]] = {}
    for group, segs in by_group.items():
        successors = {s.next_modes for s in segs if s.next_modes is not None}
        ending = any(s.next_modes is None for s in segs)
        # per-transition keys when the group hands over to several next groups, or hands over
        # in some demonstrations and ends others: the hand-overs must not share a DS (and an
        # attractor) with the segments that stay in the mode at the end of the task
        per_transition = len(successors) > 1 or (len(successors) == 1 and ending)
        for seg in segs:
            for mode in group:
                if per_transition and seg.next_modes is not None:
                    for succ in seg.next_modes:
                        buckets.setdefault((transition_key(mode, succ), mode, succ),
                                           []).append(seg)
                else:
                    unique = (next(iter(successors))
                              if len(successors) == 1 and not per_transition else None)
                    nxt_single = unique[0] if unique is not None and len(unique) == 1 else None
                    buckets.setdefault((mode, mode, nxt_single), []).append(seg)
    out: dict[str, ModeData] = {}
    handed = {mode for (key, mode, nxt) in buckets if key != mode}
    for (key, mode, nxt), segs in buckets.items():
        if key == mode and mode in handed \
                and sum(s.stop - s.start for s in segs) < 2:
            # a demonstration that ends right after entering a mode that other segments pass
            # through: too little data for a DS that stays; the hand-overs are learned
            continue
        targets = np.array([_target(demos, s, after.get((s.demo, s.stop)), entry_samples)
                            for s in segs])
        handing_over = np.array([s.next_modes is not None for s in segs])
        # Lemma 2: a mode that hands over puts its attractor in the next mode (the mean of
        # the entry points); only a mode that always ends the demonstration keeps its end point
        attractor = (targets[handing_over] if handing_over.any() else targets).mean(axis=0)
        xs, dxs = [], []
        for s, target in zip(segs, targets, strict=True):
            x = demos[s.demo].x[s.start:s.stop]
            xs.append(x + (attractor - target) if shift else x)
            dxs.append(demos[s.demo].dx[s.start:s.stop])
        x_all = np.concatenate(xs)
        if x_all.shape[0] < 2:
            first = segs[0]
            raise DemoError(f"{demos[first.demo].where(first.start)}: DS {key!r} has only "
                            f"{x_all.shape[0]} sample; a mode needs at least 2 samples to learn "
                            "a DS")
        out[key] = ModeData(key=key, mode=mode, next_mode=nxt, attractor=attractor, x=x_all,
                            dx=np.concatenate(dxs), segments=tuple(segs))
    return out
