"""Where a campaign's batches run: in the driver, in local processes, or on Dask.

Runs are independent, so a campaign sends *batches* of runs (100-1,000, vectorised episodes)
to a :class:`Backend`, never one tiny task per run (Dask costs about 1-6 ms a task).
:meth:`Backend.map_unordered` yields ``(index, result)`` as batches complete.

* ``"serial"`` -- :class:`SerialBackend`, in the calling process (tests, debugging);
* ``"process"`` -- :class:`ProcessBackend`, a :class:`~concurrent.futures.ProcessPoolExecutor`.
  A worker that dies (``BrokenProcessPool``) is reported through ``on_event``, the pool is
  rebuilt and the unfinished batches re-run, up to 2 times per batch; then
  :class:`~tli_verify.errors.WorkerLost`;
* ``"dask"`` -- ``tli_verify.verify.dask_backend.DaskBackend`` (the ``[cluster]`` extra),
  imported only when asked for.

Ctrl-C: pending batches are cancelled and ``KeyboardInterrupt`` is re-raised; the campaign
keeps the results it got and writes a partial report.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol, TypeVar

from tli_verify.errors import CampaignError, WorkerLost

__all__ = ["MAX_RETRIES", "Backend", "ProcessBackend", "SerialBackend", "make_backend",
           "unguarded_main_call"]

T = TypeVar("T")
R = TypeVar("R")
MAX_RETRIES = 2
"""A batch whose worker died is re-run at most this many times."""


class Backend(Protocol):
    """An executor of independent batches."""

    def map_unordered(self, fn: Callable[[T], R], items: Sequence[T]
                      ) -> Iterator[tuple[int, R]]:  # pragma: no cover - protocol
        """Run ``fn`` on every item; yield ``(index, result)`` as each completes."""
        ...

    def close(self) -> None:  # pragma: no cover - protocol
        """Release workers."""
        ...


class SerialBackend:
    """Run every batch in the calling process, in order."""

    def __init__(self, *, on_event: Callable[[str], None] | None = None) -> None:
        self.on_event = on_event

    def map_unordered(self, fn: Callable[[T], R], items: Sequence[T]
                      ) -> Iterator[tuple[int, R]]:
        """Yield ``(i, fn(items[i]))`` in order."""
        for i, item in enumerate(items):
            yield i, fn(item)

    def close(self) -> None:
        """Nothing to release."""


def _init_worker() -> None:
    """Worker start-up: one BLAS thread (the batches are the parallelism); Ctrl-C is the
    driver's to handle."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import threadpoolctl

        threadpoolctl.threadpool_limits(1)
    except Exception:  # pragma: no cover - threadpoolctl is a dependency
        pass


@contextlib.contextmanager
def _ctrl_c_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the duration: one that arrives meanwhile takes effect, once,
    when the block ends. Starting a worker from the fork server connects to the server and then
    writes the worker's preparation data: an interrupt between the two left a half-born worker
    that printed an ``EOFError`` traceback from ``spawn._main`` on the user's terminal (issue 32,
    part 5). Two layers, because masking the main thread is not enough: the kernel may deliver a
    process-directed signal to any thread that does not block it (the campaign's drawing
    thread), and Python then runs the handler in the main thread regardless of its mask. So
    the signals are blocked in the main thread (threads started meanwhile inherit the mask) and
    their Python handlers are replaced by a recorder, the recorded signal handed to the former
    handler afterwards. A no-op outside the main thread (Python handles signals there only)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    kinds = (signal.SIGINT, signal.SIGTERM)
    seen: list[signal.Signals] = []
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, set(kinds))
    former = {k: signal.getsignal(k) for k in kinds}
    for k in kinds:
        if callable(former[k]):
            signal.signal(k, lambda signum, _frame: seen.append(signal.Signals(signum)))
    try:
        yield
    finally:
        for k in kinds:
            if callable(former[k]):
                signal.signal(k, former[k])
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        if seen:
            handler = former[seen[0]]
            if callable(handler):
                handler(seen[0], None)


def block_signals_in_this_thread() -> None:
    """Let only the main thread take SIGINT and SIGTERM: a helper thread (the campaign's
    drawing thread) calls this first, so the kernel never delivers them to it (see
    :func:`_ctrl_c_deferred`)."""
    import signal

    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})


def _start_forkserver_without_ctrl_c() -> None:
    """Start multiprocessing's fork server with SIGINT ignored, so that every worker forked
    from it starts with SIGINT ignored (a worker restores the server's own SIGINT disposition
    at birth: with Python's default, a Ctrl-C in the instant before :func:`_init_worker` ran
    printed a KeyboardInterrupt traceback from the worker). SIGINT is blocked meanwhile in the
    driver, so a Ctrl-C in that instant stays pending and is handled afterwards (Linux keeps a
    blocked signal pending even while its action is to ignore it). A no-op outside the main
    thread or when the server already runs."""
    import signal
    import threading
    from multiprocessing import forkserver

    if threading.current_thread() is not threading.main_thread():
        return
    from multiprocessing import resource_tracker

    with _ctrl_c_deferred():
        # CPython's resource tracker unblocks SIGINT when it has started, so start it first
        # (a Ctrl-C meanwhile reaches the deferral's recorder) and block again: else SIGINT was
        # unblocked and ignored while the fork server started, and a Ctrl-C then was discarded
        # (seen under load: `tli verify` ran on to exit 0).
        resource_tracker.ensure_running()
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        # Setting SIG_IGN discards a pending SIGINT (POSIX sigaction): look first, raise it
        # again after (blocked still: pending until the deferral ends).
        pending = signal.SIGINT in signal.sigpending()
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            forkserver.ensure_running()
        finally:
            signal.signal(signal.SIGINT, previous)
            if pending:
                # to this thread, which blocks it: pending until the deferral ends (a
                # process-directed kill could be taken by another thread meanwhile)
                signal.pthread_kill(threading.get_ident(), signal.SIGINT)


class ProcessBackend:
    """Batches on local worker processes (:class:`~concurrent.futures.ProcessPoolExecutor`).

    Parameters
    ----------
    workers : int, optional
        Default: the CPU count.
    on_event : callable, optional
        Called with one line per notable event (a worker died, a batch re-run).
    """

    def __init__(self, *, workers: int | None = None,
                 on_event: Callable[[str], None] | None = None) -> None:
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self.on_event = on_event
        self._pool: Any = None

    def _emit(self, text: str) -> None:
        if self.on_event is not None:
            self.on_event(text)

    def _new_pool(self) -> Any:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        where = unguarded_main_call()
        if where is not None:
            raise CampaignError(
                f"{where[0]}:{where[1]}: a campaign on worker processes started from the top "
                "level of a script without an `if __name__ == \"__main__\":` guard: each worker "
                "re-imports the script and would start it again; put the call under the guard "
                "(or use backend=\"serial\")")

        ctx = mp.get_context("spawn" if os.name == "nt" else "forkserver")
        if os.name != "nt":
            _start_forkserver_without_ctrl_c()
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx,
                                   initializer=_init_worker)

    def map_unordered(self, fn: Callable[[T], R], items: Sequence[T]
                      ) -> Iterator[tuple[int, R]]:
        """Yield ``(index, result)`` as batches complete; re-run batches of a dead worker.

        Raises
        ------
        WorkerLost
            (exit 1) A batch's worker died more than :data:`MAX_RETRIES` times.
        KeyboardInterrupt
            After cancelling the pending batches.
        """
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        pending = set(range(len(items)))
        tries = dict.fromkeys(pending, 0)
        try:
            while pending:
                if self._pool is None:
                    self._pool = self._new_pool()
                with _ctrl_c_deferred():  # submit starts the workers: none is left half-born
                    futures = {self._pool.submit(fn, items[i]): i for i in sorted(pending)}
                broken = False
                while futures:
                    done, _ = wait(futures, return_when=FIRST_COMPLETED)
                    for fut in done:
                        i = futures.pop(fut)
                        try:
                            result = fut.result()
                        except BrokenProcessPool:
                            broken = True
                            continue
                        pending.discard(i)
                        yield i, result
                    if broken:
                        break
                if broken:
                    lost = sorted(pending)
                    for fut in futures:
                        fut.cancel()
                    self._pool.shutdown(wait=False, cancel_futures=True)
                    self._pool = None
                    for i in lost:
                        tries[i] += 1
                    over = [i for i in lost if tries[i] > MAX_RETRIES]
                    self._emit(f"worker lost: batch(es) {', '.join(map(str, lost))} re-run "
                               f"on a new pool")
                    if over:
                        raise WorkerLost(f"batch {over[0]}: its worker died "
                                         f"{tries[over[0]]} times (retries: {MAX_RETRIES})")
        except KeyboardInterrupt:
            self._kill()
            raise

    def _kill(self) -> None:
        """Stop the pool now: cancel what is queued and terminate the workers (their running
        batches are abandoned)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list(getattr(pool, "_processes", {}).values())  # no public API before 3.14
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(timeout=5)

    def close(self) -> None:
        """Shut the pool down."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def make_backend(kind: str = "process", *, workers: int | None = None,
                 scheduler: str | None = None, on_event: Callable[[str], None] | None = None
                 ) -> Backend:
    """The backend named ``kind`` (``"serial"``, ``"process"`` or ``"dask"``).

    Raises
    ------
    CampaignError
        (exit 2) Unknown kind; ``scheduler`` without ``"dask"``; dask not installed.
    """
    if kind == "serial":
        if scheduler is not None:
            raise CampaignError("--scheduler needs --backend dask")
        return SerialBackend(on_event=on_event)
    if kind == "process":
        if scheduler is not None:
            raise CampaignError("--scheduler needs --backend dask")
        return ProcessBackend(workers=workers, on_event=on_event)
    if kind == "dask":
        try:
            from tli_verify.verify.dask_backend import DaskBackend  # type: ignore[import-not-found,unused-ignore]
        except ImportError as exc:
            raise CampaignError(f"--backend dask: not available ({exc}); install "
                                "'tli-verify[cluster]'") from exc
        backend: Backend = DaskBackend(scheduler=scheduler, workers=workers, on_event=on_event)
        return backend
    raise CampaignError(f"--backend {kind!r}: unknown backend (serial, process, dask)")


def unguarded_main_call() -> tuple[str, int] | None:
    """Where the running script calls into tli-verify from its top level outside an
    ``if __name__ == "__main__":`` block, or None.

    Worker processes (``forkserver``, ``spawn``) import the main script again before they run
    anything; an unguarded call there would start the campaign again in every worker (which
    dies, and the campaign ends in :class:`~tli_verify.errors.WorkerLost`). The check reads
    the call's line in the script (:mod:`ast`): a line under a top-level ``if`` that tests
    ``__name__ == "__main__"`` is guarded. An interactive session or ``python -c`` has no
    script file and is never refused.

    Returns
    -------
    (str, int) or None
        The script and the line of its top-level statement that made the call.
    """
    import ast
    import sys

    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path or not str(path).endswith(".py") or not os.path.isfile(path):
        return None
    frame = sys._getframe(1)
    line = None
    while frame is not None:
        if frame.f_code.co_name == "<module>" and frame.f_globals is vars(main):
            line = frame.f_lineno
            break
        frame = frame.f_back  # type: ignore[assignment]
    if line is None:
        return None
    try:
        with open(path, encoding="utf-8") as fh:
            tree = ast.parse(fh.read(), filename=str(path))
    except (OSError, SyntaxError, ValueError):
        return None
    for node in tree.body:
        if isinstance(node, ast.If) and _is_main_test(node.test):
            end = getattr(node, "end_lineno", None) or node.lineno
            if node.lineno <= line <= end:
                return None
    return str(path), int(line)


def _is_main_test(test: Any) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    import ast

    if not isinstance(test, ast.Compare) or len(test.ops) != 1 or \
            not isinstance(test.ops[0], ast.Eq):
        return False
    sides = [test.left, test.comparators[0]]
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    consts = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(names) == 1 and len(consts) == 1
