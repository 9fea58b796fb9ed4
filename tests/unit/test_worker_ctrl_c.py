"""A campaign's worker processes are born with Ctrl-C ignored (issue 32, part 5): under load, a
SIGINT that reached a worker forked from multiprocessing's fork server before its initializer
ran printed a KeyboardInterrupt traceback on the user's terminal, and `make test` failed
`test_ctrl_c_before_any_run_finished_is_one_line`. The fork server is started with SIGINT
ignored, the disposition a worker it forks is born with; the driver keeps its own handler.
Checked in a fresh interpreter (the fork server is one per process)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.support.cli import interactive_signals

PROBE = """
import signal
from concurrent.futures import ProcessPoolExecutor
import multiprocessing as mp
import tli_verify.verify.backends as b
if {fixed}:
    b._start_forkserver_without_ctrl_c()
with ProcessPoolExecutor(1, mp_context=mp.get_context("forkserver")) as pool:
    born = pool.submit(signal.getsignal, signal.SIGINT).result()  # no initializer
print(born is signal.SIG_IGN, signal.getsignal(signal.SIGINT) is signal.default_int_handler,
      signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, set()))
"""


@pytest.mark.skipif(sys.platform == "win32", reason="no fork server")
@pytest.mark.parametrize("fixed", [True, False])
def test_a_worker_is_born_ignoring_ctrl_c_and_the_driver_keeps_its_handler(fixed: bool) -> None:
    out = subprocess.run([sys.executable, "-c", PROBE.format(fixed=fixed)], capture_output=True,
                         text=True, timeout=120, check=True,
                         preexec_fn=interactive_signals).stdout.split()
    # without the start-up step a worker is born with Python's KeyboardInterrupt handler
    assert out == [str(fixed), "True", "False"], out
