"""The Dask backend on a real ``LocalCluster`` of 2 worker processes."""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from tli_verify.errors import CampaignError, WorkerLost
from tli_verify.verify.dask_backend import DaskBackend


def batch_sum(item: tuple[int, list[int], float]) -> tuple[int, int]:
    """A batch: its tag, the sum of squares of its runs, after a (seeded) delay."""
    tag, runs, delay = item
    time.sleep(delay)
    return tag, sum(r * r for r in runs)


def die_once(item: tuple[str, int]) -> int:
    """Kill the worker process the first time batch 3 runs (a marker file remembers)."""
    marker, x = item
    if x == 3 and not os.path.exists(marker):
        Path(marker).write_text("died once")
        os._exit(1)
    return 10 * x


def always_die(x: int) -> int:
    os._exit(1)


def raise_value_error(x: int) -> int:
    if x == 1:
        raise ValueError("a bug in the batch function")
    return x


@pytest.fixture(scope="module")
def events() -> list[str]:
    return []


@pytest.fixture(scope="module")
def backend(events: list[str]) -> Iterator[DaskBackend]:
    b = DaskBackend(workers=2, on_event=events.append)
    yield b
    b.close()


def test_results_equal_the_serial_map_whatever_the_completion_order(backend: DaskBackend) -> None:
    rng = random.Random(12)
    items = [(tag, [rng.randrange(100) for _ in range(rng.randrange(1, 50))],
              rng.choice([0.0, 0.0, 0.05])) for tag in range(24)]
    serial = {i: batch_sum(item) for i, item in enumerate(items)}
    got = list(backend.map_unordered(batch_sum, items))
    assert sorted(i for i, _ in got) == list(range(len(items)))  # every index exactly once
    assert dict(got) == serial
    # the same batches in another order: each result still comes back with its own index
    order = list(range(len(items)))
    rng.shuffle(order)
    shuffled = [items[k] for k in order]
    again = dict(backend.map_unordered(batch_sum, shuffled))
    assert {order[i]: r for i, r in again.items()} == serial


def test_a_worker_killed_mid_run_is_reported_and_its_batch_rerun(
        backend: DaskBackend, events: list[str], tmp_path: Path) -> None:
    marker = str(tmp_path / "died")
    events.clear()
    got = dict(backend.map_unordered(die_once, [(marker, x) for x in range(6)]))
    assert got == {x: 10 * x for x in range(6)}
    assert Path(marker).read_text() == "died once"
    lost = [e for e in events if e.startswith("worker lost running batch 3 ")]
    assert len(lost) == 1 and "re-submitting it (attempt 2 of 3)" in lost[0], events


@pytest.mark.slow
def test_a_batch_that_always_kills_its_worker_raises_worker_lost(
        backend: DaskBackend, events: list[str]) -> None:
    events.clear()
    with pytest.raises(WorkerLost, match=r"batch 0: its worker died 3 times"):
        list(backend.map_unordered(always_die, [0]))
    assert [e.split(" (")[0] for e in events] == ["worker lost running batch 0"] * 2


def test_the_batch_functions_own_error_is_re_raised(backend: DaskBackend) -> None:
    with pytest.raises(ValueError, match="a bug in the batch function"):
        list(backend.map_unordered(raise_value_error, [0, 1, 2]))
    assert dict(backend.map_unordered(raise_value_error, [0, 2])) == {0: 0, 1: 2}


def test_ctrl_c_cancels_the_pending_batches_and_re_raises(backend: DaskBackend) -> None:
    it = backend.map_unordered(batch_sum, [(t, [t], 0.0 if t == 0 else 3.0) for t in range(4)])
    assert next(it) == (0, (0, 0))
    with pytest.raises(KeyboardInterrupt) as excinfo:
        it.throw(KeyboardInterrupt())  # Ctrl-C while waiting for the next batch
    # excinfo keeps the generator's frame, and its futures, alive: only a cancel frees them
    client = backend._client
    assert client is not None and excinfo.value is not None
    left = ["?"]
    for _ in range(100):  # the scheduler handles the cancel asynchronously
        left = [k for k in client.run_on_scheduler(_scheduler_keys) if k.startswith("tli-batch-")]
        if not left:
            break
        time.sleep(0.05)
    assert left == [], client.run_on_scheduler(_states)


def _scheduler_keys(dask_scheduler: object) -> list[str]:
    return sorted(str(k) for k in dask_scheduler.tasks)  # type: ignore[attr-defined]


def test_connecting_to_a_running_scheduler(backend: DaskBackend) -> None:
    """``--scheduler ADDR``: a second client of the fixture's cluster; closing it leaves the
    cluster running."""
    cluster = backend._cluster
    assert cluster is not None
    remote = DaskBackend(scheduler=cluster.scheduler_address, connect_timeout=10)
    try:
        assert remote.workers >= 1
        assert dict(remote.map_unordered(batch_sum, [(1, [2, 3], 0.0)])) == {0: (1, 13)}
    finally:
        remote.close()
    assert dict(backend.map_unordered(batch_sum, [(2, [4], 0.0)])) == {0: (2, 16)}


def test_an_unreachable_scheduler_is_a_campaign_error() -> None:
    with pytest.raises(CampaignError, match=r"--scheduler tcp://127.0.0.1:1: cannot reach"):
        DaskBackend(scheduler="tcp://127.0.0.1:1", connect_timeout=2)
    with pytest.raises(CampaignError, match="not an address"):
        DaskBackend(scheduler="localhost", connect_timeout=2)


def test_import_tli_verify_never_imports_dask() -> None:
    code = ("import sys, tli_verify, tli_verify.cli, tli_verify.deploy.gate, "
            "tli_verify.verify.evidence, tli_verify.verify.dask_backend; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    root = str(Path(__file__).resolve().parents[2])
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={**os.environ, "PYTHONPATH": root})
    assert out.stdout.strip() == "[]"


def _states(dask_scheduler: object) -> dict[str, str]:
    return {str(k): v.state for k, v in dask_scheduler.tasks.items()}  # type: ignore[attr-defined]


def test_a_local_cluster_that_cannot_start_is_a_campaign_error() -> None:
    """Worker processes are spawned from ``__main__``: a program read from stdin has no file to
    re-import, so they die at start-up; the driver gets one CampaignError, not Dask's."""
    code = ("from tli_verify.verify.dask_backend import DaskBackend\n"
            "from tli_verify.errors import CampaignError\n"
            "from tli_verify.commands import exit_code\n"
            "try:\n"
            "    DaskBackend(workers=1)\n"
            "except CampaignError as exc:\n"
            "    print('CampaignError', exit_code(exc), exc)\n")
    root = str(Path(__file__).resolve().parents[2])
    out = subprocess.run([sys.executable, "-"], input=code, capture_output=True, text=True,
                         check=True, env={**os.environ, "PYTHONPATH": root}, timeout=120)
    assert out.stdout.startswith("CampaignError 2 --backend dask: cannot start a LocalCluster "
                                 "of 1 worker process(es)"), out.stdout
