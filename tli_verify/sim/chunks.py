"""The partition of a physical campaign's seeds into chunks, one executive each.

:func:`chunk_seeds` is pure and loads no simulator, so the evidence check
(:mod:`tli_verify.sim.physics_checks`) recomputes the partition a campaign recorded.
"""

from __future__ import annotations

from tli_verify.errors import CampaignError

__all__ = ["chunk_seeds"]


def chunk_seeds(seed: int, trials: int, workers: int) -> tuple[tuple[int, int], ...]:
    """The contiguous chunks of a physical campaign's seeds, one executive each.

    The seeds ``seed, ..., seed + trials - 1`` in ``min(workers, trials)`` runs of consecutive
    seeds whose sizes differ by at most one, the larger ones first (as ``numpy.array_split``).
    A pure function of its arguments: the partition, hence which cuts a trial inherits, never
    depends on the scheduling.

    Parameters
    ----------
    seed : int
        The first trial's seed, >= 0.
    trials : int
        >= 1.
    workers : int
        >= 1.

    Returns
    -------
    tuple of (int, int)
        ``(first seed, trials)`` per chunk, in seed order; the trials add up to ``trials``.

    Raises
    ------
    CampaignError
        (exit 2) A negative seed, or fewer than one trial or worker.

    Examples
    --------
    >>> chunk_seeds(0, 30, 4)
    ((0, 8), (8, 8), (16, 7), (23, 7))
    >>> chunk_seeds(5, 2, 4)
    ((5, 1), (6, 1))
    """
    for name, value, lo in (("seed", seed, 0), ("trials", trials, 1), ("workers", workers, 1)):
        if not isinstance(value, int) or isinstance(value, bool) or value < lo:
            raise CampaignError(f"{name}: expected an integer >= {lo}, got {value!r}")
    count = min(workers, trials)
    size, extra = divmod(trials, count)
    chunks = []
    first = seed
    for i in range(count):
        n = size + (1 if i < extra else 0)
        chunks.append((first, n))
        first += n
    return tuple(chunks)
