"""The executive's bounded record of mode-entry states: the incremental distances
(:class:`tli_verify.runtime.executive._EntryRecord`) drop exactly the states the
straightforward all-pairs computation drops, also when a fork copied the lists midway."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.runtime.executive import MAX_ENTRY_STATES, LTLDSPolicy


def _reference(kept: list[np.ndarray], x: np.ndarray) -> None:
    """The bounded record recomputing all pairs each time (the plain version)."""
    kept.append(x)
    if len(kept) <= MAX_ENTRY_STATES:
        return
    P = np.array(kept)
    d2 = ((P[:, None, :] - P[None, :, :]) ** 2).sum(axis=-1)
    d2[np.tril_indices(len(kept))] = np.inf
    i, _ = np.unravel_index(int(np.argmin(d2)), d2.shape)
    del kept[int(i)]


coords = st.one_of(st.integers(-3, 3).map(float),  # ties: equal distances, duplicates
                   st.floats(-10, 10, allow_nan=False))


@settings(max_examples=30, deadline=None)
@given(points=st.lists(st.tuples(coords, coords, coords), min_size=MAX_ENTRY_STATES - 2,
                       max_size=3 * MAX_ENTRY_STATES),
       modes=st.lists(st.sampled_from("ab"), min_size=1, max_size=8),
       copy_at=st.integers(0, 3 * MAX_ENTRY_STATES))
def test_same_states_kept_as_the_all_pairs_computation(
        points: list[tuple[float, float, float]], modes: list[str], copy_at: int) -> None:
    pol = object.__new__(LTLDSPolicy)
    pol._entries = {}
    ref: dict[str, list[np.ndarray]] = {}
    for k, p in enumerate(points):
        if k == copy_at:  # what fork() and the campaign's watch() do
            pol._entries = {m: list(v) for m, v in pol._entries.items()}
        mode = modes[k % len(modes)]
        x = np.array(p)
        pol._record_entry(mode, x)
        _reference(ref.setdefault(mode, []), x)
        assert len(pol._entries[mode]) == len(ref[mode])
        assert all(a is b for a, b in zip(pol._entries[mode], ref[mode], strict=True))


def test_a_long_run_stays_incremental_and_exact() -> None:
    rng = np.random.default_rng(4)
    pol = object.__new__(LTLDSPolicy)
    pol._entries = {}
    ref: list[np.ndarray] = []
    for k, x in enumerate(rng.normal(size=(5 * MAX_ENTRY_STATES, 4))):
        pol._record_entry("a", x)
        _reference(ref, x)
        if k % 50 == 49:  # the newest state replaced in place: the distances must follow
            y = ref[-2] + 1e-3
            pol._entries["a"][-1] = ref[-1] = y
    kept = pol._entries["a"]
    assert type(kept).__name__ == "_EntryRecord"  # the fast path was the one that ran
    assert all(a is b for a, b in zip(kept, ref, strict=True))
    assert len(kept) == MAX_ENTRY_STATES
