"""Shrinking a counterexample, and the targeted search (paper Sec. 4.4).

:func:`shrink` replays the generation of the chunk a violation was found in (the same
``hypothesis.find`` with the chunk's seed; verdicts already computed are looked up) until it
meets that case, then lets hypothesis's shrinker minimise it -- fewer, smaller, later
perturbations -- keeping the violation kind. :func:`targeted_search` steers generation with
``hypothesis.target`` on the oracle's robustness margin.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from typing import Any

from tli_verify.verify.config import SimSpec
from tli_verify.verify.draws import draw_settings, examples_for, import_independent_draws
from tli_verify.verify.oracle import (
    Verdict,
    ViolationKind,
)
from tli_verify.verify.simulate import check_case
from tli_verify.verify.strategies import (
    Case,
)

__all__ = [
    "shrink",
]


class _Shrinker:
    """The condition hypothesis shrinks with: 'the case violates ``kind``' (cached)."""

    def __init__(self, spec: SimSpec, kind: ViolationKind, known: Mapping[Case, Verdict]
                 ) -> None:
        self.spec = spec
        self.kind = kind
        self.known = dict(known)
        self.simulated = 0

    def verdict(self, case: Case) -> Verdict:
        v = self.known.get(case)
        if v is None:
            v = check_case(self.spec, case)
            self.known[case] = v
            self.simulated += 1
        return v

    def __call__(self, case: Case) -> bool:
        return self.kind in self.verdict(case).kinds


def shrink(spec: SimSpec, strategy: Any, seed: int | str, examples: int, kind: ViolationKind,
           known: Mapping[Case, Verdict]) -> tuple[Case | None, Verdict | None, int]:
    """Shrink the first case violating ``kind`` in the seeded generation order.

    Replays :func:`draw_cases`'s generation of ``examples`` cases with ``seed`` (a campaign
    replays the chunk, :func:`chunk_seed`, of its first counterexample; same strategy and
    settings; verdicts in ``known`` are looked up, not simulated) with the condition "violates
    ``kind``", so hypothesis stops at the same first failing case and shrinks it (candidates
    simulated here).

    Returns
    -------
    (Case or None, Verdict or None, int)
        The minimal case, its verdict, and the simulations the shrinker ran.
    """
    from hypothesis import Phase, find
    from hypothesis.errors import NoSuchExample

    cond = _Shrinker(spec, kind, known)
    try:
        with import_independent_draws():
            found = find(strategy, cond, settings=draw_settings(examples_for(examples),
                                                            [Phase.generate, Phase.shrink]),
                         random=random.Random(seed))
    except NoSuchExample:
        return None, None, cond.simulated
    return found, cond.verdict(found), cond.simulated


def targeted_search(spec: SimSpec, strategy: Any, seed: int, n: int
              ) -> tuple[Case | None, Verdict | None, int]:
    """Driver-side search with ``hypothesis.target`` on the robustness margin."""
    from hypothesis import Phase, find, target
    from hypothesis.errors import NoSuchExample

    count = [0]
    cache: dict[Case, Verdict] = {}

    def cond(case: Case) -> bool:
        v = cache.get(case)
        if v is None:
            v = check_case(spec, case)
            cache[case] = v
            count[0] += 1
        if math.isfinite(v.robustness):
            target(-v.robustness, label="negated robustness")
        return not v.ok

    try:
        with import_independent_draws():
            found = find(strategy, cond, settings=draw_settings(n, [Phase.generate, Phase.target,
                                                                Phase.shrink]),
                         random=random.Random(seed + 7919))
    except NoSuchExample:
        return None, None, count[0]
    return found, cache.get(found) or check_case(spec, found), count[0]
