"""Mode labels of sensor readings: a spec's ``[modes]`` table as a labelling function.

Paper Sec. 3: a mode is a set of states sharing a sensor reading, ``sigma = L(alpha)``. The
segmentation of demonstrations (:mod:`tli_verify.segmentation`) and the inference of specs
from them (:mod:`tli_verify.logic.infer`) both label each sample with the modes whose label
holds for its reading.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

from tli_verify.errors import SpecError
from tli_verify.logic.spec import label_holds

__all__ = ["Labeler", "runs", "spec_labeler"]

Labeler = Callable[[Mapping[str, bool]], tuple[str, ...]]
"""Reading -> the modes whose label holds (empty: no label)."""


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


def runs(groups: list[tuple[str, ...]]) -> list[tuple[int, int]]:
    """Boundaries of maximal runs of equal groups."""
    bounds = [0] + [i for i in range(1, len(groups)) if groups[i] != groups[i - 1]]
    return list(zip(bounds, [*bounds[1:], len(groups)], strict=True))
