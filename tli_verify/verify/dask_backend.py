"""Campaign batches on Dask distributed (``tli verify --backend dask [--scheduler ADDR]``).

The executor layer of :mod:`tli_verify.verify.backends`: runs are independent, so a
campaign draws its perturbation sequences in the driver (hypothesis generates in one process),
groups them into batches of 100-1,000 runs and maps a simulation function over the batches.
:class:`DaskBackend` does that map on a Dask cluster: one task per batch, results yielded as
they complete.

Dask costs about 1-6 ms per task and a ``LocalCluster`` takes about 5 s to start (measured on
2 cores, see ``docs/howto/dask.md``), so a task must carry a batch, never
one run.

Dask is optional (the ``[cluster]`` extra: ``pip install 'tli-verify[cluster]'``) and imported
only when a :class:`DaskBackend` is built: ``import tli_verify`` never imports it.

Reliability
    A worker that dies while running a batch (``KilledWorker``: the process exited, was killed,
    or ran out of memory) is reported through ``on_event`` and the batch re-submitted, up to
    ``retries`` (2) times; then :class:`~tli_verify.errors.WorkerLost` (exit 1). On the
    ``LocalCluster`` this backend starts, the scheduler gives up on a task at its first worker
    death (``allowed_failures=0``) so that every loss is seen and reported here; a remote
    scheduler applies its own ``distributed.scheduler.allowed-failures`` first (default 3 silent
    re-runs). Ctrl-C (``KeyboardInterrupt``) cancels every pending future and re-raises; so
    does a consumer that stops iterating early (the futures are cancelled).
"""

from __future__ import annotations

import itertools
import logging
import os
import socket
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

from tli_verify.errors import CampaignError, WorkerLost

__all__ = ["DEFAULT_CONNECT_TIMEOUT", "DEFAULT_RETRIES", "DaskBackend"]

T = TypeVar("T")
R = TypeVar("R")

DEFAULT_RETRIES = 2
"""Re-submissions of a batch whose worker died, before :class:`WorkerLost`."""
DEFAULT_CONNECT_TIMEOUT = 10.0
"""Seconds to reach a scheduler (and to see its first worker) before :class:`CampaignError`."""

_counter = itertools.count()


def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError as exc:  # the [cluster] extra is not installed
        raise CampaignError(f"--backend dask needs Dask distributed, which is not installed "
                           f"({exc}): pip install 'tli-verify[cluster]'") from None
    return distributed


class DaskBackend:
    """Map a function over batches on a Dask cluster, yielding ``(index, result)`` as each
    batch completes (the :class:`tli_verify.verify.backends.Backend` protocol).

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``). Default: start a
        ``LocalCluster`` of ``workers`` processes with one thread each, quiet logs and no
        dashboard (about 5 s), shut down by :meth:`close`.
    workers : int, optional
        Worker processes of the ``LocalCluster`` (default: the CPU count). Ignored with
        ``scheduler`` (the cluster has its own workers).
    on_event : callable, optional
        ``message -> None``: one line per worker loss and re-submission (a campaign prints or
        records it).
    retries : int, optional
        Re-submissions of a batch whose worker died (default 2).
    connect_timeout : float, optional
        Seconds to reach ``scheduler`` and see at least one worker (default 10).

    Raises
    ------
    CampaignError
        (exit 2) Dask is not installed, the scheduler is unreachable or has no worker, or
        ``workers`` is not positive.

    Notes
    -----
    ``fn`` and the items are sent to the workers with cloudpickle: a function defined at module
    level in an importable module (or a closure over picklable values) works; the workers must
    be able to import ``tli_verify`` (the same environment).
    """

    def __init__(self, *, scheduler: str | None = None, workers: int | None = None,
                 on_event: Callable[[str], None] | None = None,
                 retries: int = DEFAULT_RETRIES,
                 connect_timeout: float = DEFAULT_CONNECT_TIMEOUT) -> None:
        distributed = _import_distributed()
        if retries < 0:
            raise CampaignError(f"retries: must be >= 0, got {retries}")
        self.retries = int(retries)
        self.on_event = on_event
        self.scheduler = scheduler
        self._cluster: Any = None
        self._client: Any = None
        if scheduler is None:
            n = int(workers) if workers is not None else (os.cpu_count() or 1)
            if n < 1:
                raise CampaignError(f"--workers: must be at least 1, got {workers}")
            # loopback only; no dashboard; the scheduler's HTTP endpoints on a free port
            # (its default 8787 may be taken by another cluster: a warning, not an error)
            try:
                self._cluster = distributed.LocalCluster(
                    n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                    dashboard_address=None, silence_logs=logging.CRITICAL,
                    scheduler_kwargs={"allowed_failures": 0, "dashboard": False,
                                      "dashboard_address": "127.0.0.1:0"})
            except Exception as exc:  # e.g. worker processes that cannot start (no __main__)
                cause = exc.__cause__ or exc
                raise CampaignError(f"--backend dask: cannot start a LocalCluster of {n} "
                                    f"worker process(es): {_short(exc)}"
                                    + (f" ({_short(cause)})" if cause is not exc else "")
                                    ) from None
            try:
                self._client = distributed.Client(self._cluster, set_as_default=False)
            except BaseException:
                self._cluster.close()
                raise
            self.workers = n
        else:
            self._client = self._connect(distributed, scheduler, float(connect_timeout))
            self.workers = len(self._client.scheduler_info().get("workers", {}))

    @staticmethod
    def _connect(distributed: Any, scheduler: str, timeout: float) -> Any:
        """A client of a running scheduler that has at least one worker."""
        if not isinstance(scheduler, str) or not scheduler.strip():
            raise CampaignError(f"--scheduler: not an address: {scheduler!r} (expected "
                               "tcp://HOST:PORT)")
        _probe(scheduler, timeout)
        why = None
        try:
            client = distributed.Client(scheduler, timeout=timeout, set_as_default=False)
        except Exception as exc:  # refused, timed out, bad address, not a Dask scheduler
            why = _short(exc)
        if why is not None:
            _collect_quietly()  # the half-built client's __del__ would print a traceback
            raise CampaignError(f"--scheduler {scheduler}: cannot reach the Dask scheduler "
                               f"within {timeout:g} s ({why})")
        try:
            client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError) as exc:
            client.close()
            raise CampaignError(f"--scheduler {scheduler}: the scheduler has no worker "
                               f"(none joined within {timeout:g} s: {type(exc).__name__})"
                               ) from None
        return client

    def _event(self, message: str) -> None:
        if self.on_event is not None:
            self.on_event(message)

    def _submit(self, fn: Callable[[T], R], item: T, index: int, attempt: int) -> Any:
        # an explicit key: a re-submission must not be the erred future of the same (fn, item)
        key = f"tli-batch-{index}-{attempt}-{next(_counter)}-{os.getpid()}"
        return self._client.submit(fn, item, key=key, pure=False)

    def map_unordered(self, fn: Callable[[T], R], items: Sequence[T]) -> Iterator[tuple[int, R]]:
        """Run ``fn`` on every item (a batch) on the cluster, one task per item.

        Parameters
        ----------
        fn : callable
            ``item -> result``, picklable.
        items : sequence
            The batches, ``len(items)`` tasks.

        Yields
        ------
        (int, object)
            ``(index into items, fn(items[index]))`` in completion order; every index once.

        Raises
        ------
        WorkerLost
            A batch's worker died ``retries + 1`` times.
        KeyboardInterrupt
            Re-raised after the pending futures are cancelled.
        Exception
            Whatever ``fn`` raised in a worker (re-raised as is, the pending futures
            cancelled).
        """
        distributed = _import_distributed()
        from distributed.scheduler import KilledWorker

        if self._client is None:
            raise CampaignError("the Dask backend is closed")
        batch = list(items)
        if not batch:
            return
        index: dict[str, int] = {}
        attempts: dict[int, int] = {}
        pending: dict[str, Any] = {}
        for i, item in enumerate(batch):
            fut = self._submit(fn, item, i, 0)
            index[fut.key] = i
            attempts[i] = 0
            pending[fut.key] = fut
        queue = distributed.as_completed(list(pending.values()), loop=self._client.loop)
        try:
            for fut in queue:
                i = index[fut.key]
                if fut.status == "error":
                    exc = fut.exception()
                    if isinstance(exc, KilledWorker):
                        attempts[i] += 1
                        if attempts[i] > self.retries:
                            raise WorkerLost(f"batch {i}: its worker died {attempts[i]} times "
                                             f"(last: {_short(exc)}); giving up after "
                                             f"{self.retries} re-run(s)") from None
                        self._event(f"worker lost running batch {i} ({_short(exc)}): "
                                    f"re-submitting it (attempt {attempts[i] + 1} of "
                                    f"{self.retries + 1})")
                        pending.pop(fut.key, None)
                        fut.release()
                        again = self._submit(fn, batch[i], i, attempts[i])
                        index[again.key] = i
                        pending[again.key] = again
                        queue.add(again)
                        continue
                    fut.result()  # re-raises fn's own exception with its traceback
                if fut.status == "cancelled":
                    raise CampaignError(f"batch {i}: cancelled by the scheduler "
                                       f"{self.scheduler or '(LocalCluster)'}")
                result = fut.result()
                pending.pop(fut.key, None)
                fut.release()
                yield i, result
        finally:
            # Ctrl-C, an error (its erred future too), or a consumer that stopped early:
            # nothing keeps running or stays held on the scheduler
            if pending:
                self._client.cancel(list(pending.values()))

    def close(self) -> None:
        """Close the client and, when this backend started it, the ``LocalCluster``."""
        client, cluster = self._client, self._cluster
        self._client = self._cluster = None
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()

    def __enter__(self) -> DaskBackend:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _collect_quietly() -> None:
    """Collect a failed Dask client now, without the 'Exception ignored' its ``__del__`` prints
    (it times out closing a connection that never opened)."""
    import gc
    import sys

    hook = sys.unraisablehook
    sys.unraisablehook = lambda _unraisable: None
    try:
        gc.collect()
    finally:
        sys.unraisablehook = hook


def _probe(scheduler: str, timeout: float) -> None:
    """Refuse a ``tcp://HOST:PORT`` nobody listens on before Dask's client tries (its failed
    client would otherwise linger until garbage collection)."""
    from urllib.parse import urlsplit

    if "://" in scheduler and not scheduler.startswith(("tcp://", "tls://")):
        return  # inproc://, ucx://, ...: left to Dask
    try:
        parts = urlsplit(scheduler if "://" in scheduler else f"tcp://{scheduler}")
        host, port = parts.hostname, parts.port
    except ValueError as exc:
        raise CampaignError(f"--scheduler {scheduler}: not an address ({exc}; expected "
                           "tcp://HOST:PORT)") from None
    if not host or port is None:
        raise CampaignError(f"--scheduler {scheduler}: not an address (expected tcp://HOST:PORT)")
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        raise CampaignError(f"--scheduler {scheduler}: cannot reach the Dask scheduler "
                           f"({exc.strerror or type(exc).__name__})") from None


def _short(exc: BaseException) -> str:
    if type(exc).__name__ == "KilledWorker":
        return "KilledWorker"
    text = " ".join(str(exc).split())
    text = text if len(text) <= 120 else text[:117] + "..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
