"""Drawing campaign cases with hypothesis, deterministically from a seed.

:func:`draw_cases` runs ``hypothesis.find`` with ``random=Random(seed)``, a condition that never
holds and no example database, collecting what it generates; :func:`draw_chunks` does so in
chunks (:func:`chunk_seed`) on a thread while workers simulate.
:func:`import_independent_draws` makes the draws independent of what hypothesis has seen
before in the process (its module-level constant pool), so a seed means the same cases in a
fresh process, a worker and a test run.
"""

from __future__ import annotations

import contextlib
import math
import random
from collections.abc import Iterator, Sequence
from typing import Any

from tli_verify.verify.config import CampaignConfig
from tli_verify.verify.simulate import Loaded, start_regions
from tli_verify.verify.strategies import (
    Case,
    cases,
)

__all__ = [
    "chunk_seed",
    "draw_cases",
    "draw_chunks",
    "import_independent_draws",
]


def config_strategy(cfg: CampaignConfig, ld: Loaded) -> Any:
    """The cases of a filled-in config (:func:`resolve_config`): its start or random starts,
    the task's perturbation bound."""
    task = ld.task
    assert cfg.max_pushes is not None
    assert cfg.window is not None
    regions = None
    if cfg.random_starts:
        regions = start_regions(task, ld.automaton)
        if task.starts.region is not None:
            regions = tuple(r for r in regions if r == task.starts.region) or regions
    return cases(task, start=None if cfg.random_starts else cfg.start,
                 max_pushes=cfg.max_pushes, window=cfg.window, levels=cfg.levels,
                 max_magnitude=task.perturbations.max_magnitude, start_regions=regions)


def draw_settings(n: int, phases: Sequence[Any]) -> Any:
    from hypothesis import HealthCheck, settings

    return settings(max_examples=n, database=None, deadline=None, derandomize=False,
                    phases=list(phases), suppress_health_check=list(HealthCheck),
                    report_multiple_bugs=False, print_blob=False)


def examples_for(n: int) -> int:
    """Examples hypothesis is asked for to yield ``n`` distinct cases (different choice
    sequences can give one case, e.g. the empty sequence)."""
    return math.ceil(1.3 * n) + 10


@contextlib.contextmanager
def import_independent_draws() -> Iterator[None]:
    """Hypothesis generation that does not depend on which modules are imported.

    Hypothesis (6.13x+) sometimes (p = 0.05 a choice) draws a "local constant" harvested from
    every non-library module in ``sys.modules``, a pool that grows as modules are imported.
    A campaign that lazily imports a module while running would then draw other cases from the
    same seed later in the process (measured: the first campaign of a process differed from the
    next ones). Inside this context that pool is empty, so a seed gives the same cases in any
    process state. The module-level ``CONSTANTS_CACHE`` (constants allowed per choice kind,
    filled by any earlier draw with the same bounds: a ``@given`` test, an unguarded ``find``)
    is swapped for a fresh one for the same reason (measured: a draw after a module's property
    tests differed from the same draw in a fresh process). Without the (private) hooks the
    draws still run, only less reproducibly.
    """
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover - a hypothesis without the module
        yield
        return
    getter = getattr(providers, "_get_local_constants", None)
    empty_type = getattr(providers, "Constants", None)
    if getter is None or empty_type is None:  # pragma: no cover - hypothesis changed
        yield
        return
    empty = empty_type()
    providers._get_local_constants = lambda: empty
    cache = getattr(providers, "CONSTANTS_CACHE", None)
    if cache is not None:
        providers.CONSTANTS_CACHE = type(cache)(1024)
    try:
        yield
    finally:
        providers._get_local_constants = getter
        if cache is not None:
            providers.CONSTANTS_CACHE = cache


def draw_cases(strategy: Any, n: int, seed: int | str) -> list[Case]:
    """``n`` cases from ``strategy``, deterministic in ``seed`` (hypothesis in this process).

    ``hypothesis.find`` with ``random=Random(seed)``, no example database, the generate phase
    only and a condition that never holds: every example it generates is collected, in order.
    Hypothesis may generate fewer than ``n`` when the strategy's space is exhausted.
    """
    from hypothesis import Phase, find
    from hypothesis.errors import NoSuchExample

    out: list[Case] = []
    seen: set[Case] = set()

    def collect(c: Case) -> bool:
        if c not in seen:
            seen.add(c)
            out.append(c)
        return False

    try:
        with import_independent_draws():
            find(strategy, collect, settings=draw_settings(examples_for(n), [Phase.generate]),
                 random=random.Random(seed))
    except NoSuchExample:
        pass
    return out[:n]


def chunk_seed(seed: int, chunk: int) -> str:
    """The hypothesis seed of chunk ``chunk`` of a campaign seeded ``seed``."""
    return f"tli-verify:{seed}:{chunk}"


def draw_chunks(strategy: Any, n: int, seed: int, size: int
                ) -> Iterator[list[tuple[int, Case]]]:
    """The campaign's cases in chunks of ``size``: ``[(index, case), ...]`` per chunk.

    Chunk ``j`` is the first cases of :func:`draw_cases` ``(strategy, size + 10,
    chunk_seed(seed, j))`` (so a
    chunk can be replayed on its own to shrink, and drawing overlaps the simulation); cases
    drawn by an earlier chunk are skipped (each chunk starts from hypothesis's simplest case),
    so every index is a distinct case.
    """
    seen: set[Case] = set()
    index = 0
    j = 0
    while index < n:
        want = min(size, n - index)
        fresh = [c for c in draw_cases(strategy, size + 10, chunk_seed(seed, j))
                 if c not in seen][:want]
        if not fresh:
            return
        seen.update(fresh)
        yield [(index + k, c) for k, c in enumerate(fresh)]
        index += len(fresh)
        j += 1
