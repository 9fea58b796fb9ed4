"""The partition of a physical campaign's seeds into chunks (one executive each), and the CLI
options that choose it: pure, no simulator.

The partition decides which cuts a trial inherits (the cuts an executive learned in the earlier
trials of its chunk), so it must depend on ``(seed, trials, workers)`` only, never on the
scheduling: contiguous runs of seeds, in seed order, covering every trial once.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.support.cli import run
from tli_verify.errors import CampaignError
from tli_verify.sim.chunks import chunk_seeds


@given(seed=st.integers(0, 2**32 - 1), trials=st.integers(1, 500), workers=st.integers(1, 256))
def test_chunks_are_a_contiguous_balanced_partition_of_the_seeds(seed: int, trials: int,
                                                                 workers: int) -> None:
    """Theorem: the chunks, in order, list every seed ``seed .. seed + trials - 1`` exactly
    once, each chunk a run of consecutive seeds; there are ``min(workers, trials)`` of them,
    their sizes differ by at most one, the larger first; and the same arguments give the same
    chunks."""
    chunks = chunk_seeds(seed, trials, workers)
    assert len(chunks) == min(workers, trials)
    seeds = [first + j for first, n in chunks for j in range(n)]
    assert seeds == list(range(seed, seed + trials))
    sizes = [n for _, n in chunks]
    assert min(sizes) >= 1 and max(sizes) - min(sizes) <= 1 and sizes == sorted(sizes,
                                                                                 reverse=True)
    assert chunk_seeds(seed, trials, workers) == chunks


def test_chunks_by_example() -> None:
    assert chunk_seeds(0, 30, 1) == ((0, 30),)  # the default: one executive for every trial
    assert chunk_seeds(0, 30, 4) == ((0, 8), (8, 8), (16, 7), (23, 7))
    assert chunk_seeds(7, 2, 2) == ((7, 1), (8, 1))
    assert chunk_seeds(5, 2, 4) == ((5, 1), (6, 1))  # never an empty chunk


@pytest.mark.parametrize(("seed", "trials", "workers", "said"), [
    (-1, 3, 1, "seed: expected an integer >= 0"),
    (0, 0, 1, "trials: expected an integer >= 1"),
    (0, 3, 0, "workers: expected an integer >= 1"),
    (0, 3, True, "workers: expected an integer >= 1"),
    (0, 3, 1.5, "workers: expected an integer >= 1"),
])
def test_bad_partition_arguments_are_refused(seed: object, trials: object, workers: object,
                                             said: str) -> None:
    with pytest.raises(CampaignError, match=said):
        chunk_seeds(seed, trials, workers)  # type: ignore[arg-type]


@pytest.mark.parametrize("argv", [
    ("sim", "franka", "--workers", "0"),
    ("sim", "franka", "--workers", "257"),
    ("sim", "franka", "--workers", "two"),
    ("sim", "franka", "--backend", "threads"),
    ("sim", "franka", "--scheduler", "tcp://127.0.0.1:1"),
    ("sim", "franka", "--backend", "process", "--fig9", "flow.png"),
    ("sim", "franka", "--workers", "2", "--fig9", "flow.png"),
    ("evidence", ".", "--workers", "0"),
    ("evidence", ".", "--backend", "threads"),
], ids=["sim-workers-0", "sim-workers-257", "sim-workers-word", "sim-backend", "sim-scheduler",
        "sim-fig9-process", "sim-fig9-chunks", "evidence-workers-0", "evidence-backend"])
def test_bad_worker_options_exit_2_with_one_error_line(
        argv: tuple[str, ...], capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # nothing is written, whatever happens
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "", (code, out, err)
    assert err.startswith("error:") and err.count("\n") == 1, err
    assert list(tmp_path.iterdir()) == []
