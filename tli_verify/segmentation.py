"""Sensor-based segmentation and attractor identification (paper Sec. 5.1, appendix D).

Samples are grouped into modes by their sensor reading (paper Sec. 3: a mode is a label of
sensor states, ``sigma = L(alpha)``):

* with a spec, a sample belongs to every mode whose ``[modes]`` label holds for its reading
  (several modes may share a label -- cooking's ``w1``/``w2`` -- and then share the motion
  policy, paper appendix "Generalization": "they share the same motion policy");
* without a spec, each distinct sensor reading is a mode, named by its full conjunction in Spot
  syntax (``"!r & s & !t"``);
* without sensor columns, everything is one mode, ``"main"``.

Consecutive samples with the same modes form a *segment*. The attractor of a mode is the mean
of the last states of its segments (appendix D, Table 3), and every segment is translated so
that it ends exactly on that attractor before learning (appendix "Generalization", Fig. 7(b):
"segmented into parts by mode region, which are then shifted to their average attractor
locations").

Per-transition DS (paper appendix "Generalization", Fig. 7(b)): when the segments of a mode are
followed by different next modes, a mode-based DS would average conflicting attractors, so one DS
is learned per transition instead, keyed ``"<mode>-><next>"`` (attractor = mean last state of the
segments of ``mode`` followed by ``next``). Segments that end a demonstration (no next mode) keep
the plain key ``"<mode>"``. When modes share a label, every pair of a mode of the group and a
mode of the next group gets the key (the automaton decides at run time which one it needs).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
import numpy.typing as npt

from tli_verify.demos import Demonstration
from tli_verify.errors import DemoError, SpecError

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

TRANSITION = "->"
"""Separator of per-transition DS keys: ``"<mode>-><next>"``."""

Labeler = Callable[[Mapping[str, bool]], tuple[str, ...]]
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


def spec_labeler(spec: object) -> tuple[Labeler, tuple[str, ...], Mapping[str, str]]:
    """Segmentation through a spec's ``[modes]`` labels.

    Parameters
    ----------
    spec : GR1Spec
        From :func:`tli_verify.logic.spec.load_spec`; must have a ``[modes]`` table.

    Returns
    -------
    labeler : Labeler
        Reading -> modes whose label holds (via :func:`tli_verify.logic.spec.label_holds`,
        evaluated once per distinct reading).
    modes : tuple of str
        The labelled modes, in the spec's order.
    labels : mapping of str to str
        Mode -> label formula (for messages).

    Raises
    ------
    SpecError
        If the spec has no ``[modes]`` table.
    """
    from tli_verify.logic.spec import label_holds

    table = getattr(spec, "modes", None)
    path = getattr(spec, "path", None) or "<spec>"
    if not table:
        raise SpecError(f"{path}: no [modes] table: cannot label demonstration samples with "
                        "modes (add mode = \"sensor formula\" entries, or learn without --spec)")
    labels = dict(table)
    modes = tuple(labels)
    cache: dict[tuple[tuple[str, bool], ...], tuple[str, ...]] = {}

    def label(reading: Mapping[str, bool]) -> tuple[str, ...]:
        key = tuple(sorted(reading.items()))
        if key not in cache:
            cache[key] = tuple(m for m in modes if label_holds(spec, m, reading))  # type: ignore[arg-type]
        return cache[key]

    return label, modes, MappingProxyType(labels)


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
        Mean of the segments' last states (appendix D).
    x : ndarray, shape (N, n)
        Positions, each segment shifted to end on the attractor.
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


def _runs(groups: list[tuple[str, ...]]) -> list[tuple[int, int]]:
    """Boundaries of maximal runs of equal groups."""
    bounds = [0] + [i for i in range(1, len(groups)) if groups[i] != groups[i - 1]]
    return list(zip(bounds, [*bounds[1:], len(groups)], strict=True))


def segment_demos(
    demos: Sequence[Demonstration],
    *,
    labeler: Labeler | None = None,
    modes: Sequence[str] | None = None,
    labels: Mapping[str, str] | None = None,
    shift: bool = True,
) -> Segmentation:
    """Segment demonstrations by sensor readings and compute per-DS data (appendix D).

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
        Translate each segment to end on its DS's attractor.

    Returns
    -------
    Segmentation

    Raises
    ------
    DemoError
        A reading no mode label covers (file and line named); a mode of ``modes`` that no
        demonstration visits (paper Asm. 3); a DS with fewer than 2 samples.
    """
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
    data = _mode_data(demos, segments, shift)
    return Segmentation(modes=all_modes, segments=tuple(segments),
                        data=MappingProxyType(data))


def _mode_data(demos: Sequence[Demonstration], segments: list[Segment], shift: bool
               ) -> dict[str, ModeData]:
    """Group segments into DS keys (plain or per-transition) and build their data."""
    by_group: dict[tuple[str, ...], list[Segment]] = {}
    for seg in segments:
        by_group.setdefault(seg.modes, []).append(seg)
    # (key, mode, next_mode) -> segments
    buckets: dict[tuple[str, str, str | None], list[Segment]] = {}
    for group, segs in by_group.items():
        successors = {s.next_modes for s in segs if s.next_modes is not None}
        per_transition = len(successors) > 1
        for seg in segs:
            for mode in group:
                if per_transition and seg.next_modes is not None:
                    for succ in seg.next_modes:
                        buckets.setdefault((transition_key(mode, succ), mode, succ),
                                           []).append(seg)
                else:
                    unique = (next(iter(successors)) if len(successors) == 1 else None)
                    nxt_single = unique[0] if unique is not None and len(unique) == 1 else None
                    buckets.setdefault((mode, mode, nxt_single), []).append(seg)
    out: dict[str, ModeData] = {}
    for (key, mode, nxt), segs in buckets.items():
        lasts = np.array([demos[s.demo].x[s.stop - 1] for s in segs])
        attractor = lasts.mean(axis=0)
        xs, dxs = [], []
        for s, last in zip(segs, lasts, strict=True):
            x = demos[s.demo].x[s.start:s.stop]
            xs.append(x + (attractor - last) if shift else x)
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
