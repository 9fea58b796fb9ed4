"""The SE(3) benchmark's own pieces: its DTW against a brute-force recursion, and its data
rule (files pinned by SHA-256; a missing or different file is said, never used)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from benchmarks import bench_se3


def _dtw_reference(C: np.ndarray) -> float:
    n, m = C.shape

    @functools.cache
    def best(i: int, j: int) -> tuple[float, int]:
        if i == 0 and j == 0:
            return float(C[0, 0]), 1
        options = []
        if i > 0:
            options.append(best(i - 1, j))
        if j > 0:
            options.append(best(i, j - 1))
        if i > 0 and j > 0:
            options.append(best(i - 1, j - 1))
        cost, length = min(options)
        return cost + float(C[i, j]), length + 1

    cost, length = best(n - 1, m - 1)
    return cost / length


@pytest.mark.parametrize("seed", range(6))
def test_dtw_matches_the_recursion(seed: int) -> None:
    rng = np.random.default_rng(seed)
    C = rng.uniform(0.0, 1.0, size=(int(rng.integers(1, 9)), int(rng.integers(1, 9))))
    assert bench_se3.dtw_cost(C) == pytest.approx(_dtw_reference(C), rel=1e-12)


def test_missing_and_changed_files_are_said(tmp_path: Path) -> None:
    base, why = bench_se3.dataset_dir(str(tmp_path))
    assert base is None and "missing" in why
    for name in bench_se3.FILES:
        (tmp_path / name).write_bytes(b"not the pinned file")
    base, why = bench_se3.dataset_dir(str(tmp_path))
    assert base is None and "differ from sunan-sun/se3_lpvds" in why
    section = bench_se3.main(tmp_path, data=str(tmp_path))
    assert "Not run:" in section and "differ" in section
