"""A Ctrl-C pending while the fork server starts is not lost (verify.backends)."""

from __future__ import annotations

import signal
import sys
import threading

import pytest

from tli_verify.verify.backends import _start_forkserver_without_ctrl_c

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="POSIX signal masks")


def test_a_sigint_pending_when_the_fork_server_starts_is_delivered_once() -> None:
    """A Ctrl-C that arrived just before the fork server's start (pending, blocked) reaches
    the handler exactly once: neither discarded by the SIG_IGN the server is started under
    (POSIX discards a pending signal whose action becomes SIG_IGN) nor while CPython's
    resource tracker, started on the way, has unblocked SIGINT under that SIG_IGN (a Ctrl-C
    then used to be lost, and `tli verify` ran on to exit 0)."""
    from multiprocessing import resource_tracker

    # The tracker running already (as after a first campaign): its start, which unblocks
    # SIGINT, would otherwise deliver the pending signal before the path this test is for.
    resource_tracker.ensure_running()
    got: list[int] = []
    former = signal.signal(signal.SIGINT, lambda signum, _frame: got.append(signum))
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        # Directed at this thread: a process-directed kill may be taken by another thread that
        # does not block SIGINT (pytest-xdist's I/O thread), and is then never pending here.
        signal.pthread_kill(threading.get_ident(), signal.SIGINT)  # arrives while blocked
        assert signal.SIGINT in signal.sigpending()
        _start_forkserver_without_ctrl_c()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # delivered now if still pending
        signal.signal(signal.SIGINT, former)
    assert got == [signal.SIGINT]
