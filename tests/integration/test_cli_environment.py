"""``tli`` in a hostile environment: closed or full standard streams, an encoding that cannot
show a path, a bogus ``MPLBACKEND``, a deleted working directory, SIGTERM.

Each case runs the real command in a subprocess (``python -m tli_verify.cli``, from a temporary
folder) and expects what :mod:`tli_verify.cli` documents: exit 2 and one ``error:`` line, or
the command's normal result; never exit 70, a traceback, a hang or a file left behind. Ctrl-C
(SIGINT) and ``| head -c 1`` are regression guards of behaviour that was already right.
"""

from __future__ import annotations

import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.support.cli import interactive_signals

REPO = Path(__file__).resolve().parents[2]
SPEC = REPO / "specs" / "scoop.toml"
TASK = REPO / "tasks" / "scoop.toml"
TIMEOUT = 120.0
CHEAP = [("spec", "check", str(SPEC)), ("--help",), ("task", "list")]
"""Cheap commands that print to standard output."""
FULL = "error: cannot write standard output: No space left on device\n"


def _env(*, buffered: bool = True, **extra: str) -> dict[str, str]:
    """This environment with the checkout first on the path; ``buffered``: no
    ``PYTHONUNBUFFERED`` (a user's default), else set."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONUNBUFFERED", "MPLBACKEND", "PYTHONIOENCODING")}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    if not buffered:
        env["PYTHONUNBUFFERED"] = "1"
    env.update(extra)
    return env


def _tli(*args: str | bytes, cwd: Path, env: dict[str, str] | None = None,
         stdout: int | None = subprocess.PIPE) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([sys.executable, "-m", "tli_verify.cli", *args], cwd=cwd,
                          env=_env() if env is None else env, stdout=stdout,
                          stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, timeout=TIMEOUT,
                          check=False)


def _sh(script: str, *args: str, cwd: Path, env: dict[str, str] | None = None
        ) -> subprocess.CompletedProcess[bytes]:
    """``sh -c script`` where ``$TLI`` runs ``python -m tli_verify.cli`` (redirections need a
    shell: ``subprocess.DEVNULL`` is an open descriptor, not a closed one)."""
    tli = f"{shlex.quote(sys.executable)} -m tli_verify.cli"
    return subprocess.run(["sh", "-c", script.replace("$TLI", tli), "sh", *args], cwd=cwd,
                          env=_env() if env is None else env, capture_output=True,
                          stdin=subprocess.DEVNULL, timeout=TIMEOUT, check=False)


def _one_error_line(stderr: bytes) -> str:
    text = stderr.decode("utf-8", "backslashreplace")
    assert text.startswith("error: ") and text.count("\n") == 1, text
    assert "Traceback" not in text and "internal error" not in text, text
    return text


@pytest.mark.parametrize("args", CHEAP, ids=lambda a: " ".join(a[:2]))
def test_closed_stdout_is_refused_before_any_work(args: tuple[str, ...], tmp_path: Path) -> None:
    done = _sh('exec $TLI "$@" >&-', *args, cwd=tmp_path)
    line = _one_error_line(done.stderr)
    assert done.returncode == 2, line
    assert line.startswith("error: standard output is closed")


@pytest.mark.parametrize("buffered", [True, False], ids=["buffered", "unbuffered"])
@pytest.mark.parametrize("args", CHEAP, ids=lambda a: " ".join(a[:2]))
def test_full_stdout_is_exit_2_not_a_failed_final_flush(args: tuple[str, ...], buffered: bool,
                                                        tmp_path: Path) -> None:
    with open("/dev/full", "wb") as full:
        done = _tli(*args, cwd=tmp_path, env=_env(buffered=buffered), stdout=full.fileno())
    assert _one_error_line(done.stderr) == FULL
    assert done.returncode == 2


def test_closed_or_full_stderr_keeps_the_exit_code(tmp_path: Path) -> None:
    for redirect in ("2>&-", "2>/dev/full"):
        done = _sh(f'exec $TLI spec check missing.toml {redirect}', cwd=tmp_path)
        assert done.returncode == 2, (redirect, done.stderr)
        assert done.stdout == b""


def test_broken_pipe_is_exit_0_without_a_traceback(tmp_path: Path) -> None:
    """The reader left before anything was written (buffered output used to fail at the
    interpreter's exit: 120 and "Exception ignored"); ``| head -c 1`` is a guard."""
    read, write = os.pipe()
    os.close(read)
    try:
        for args in (("spec", "check", str(SPEC)), ("--help",)):
            done = _tli(*args, cwd=tmp_path, stdout=write)
            assert (done.returncode, done.stderr) == (0, b""), args
    finally:
        os.close(write)
    tli = subprocess.Popen([sys.executable, "-m", "tli_verify.cli", "spec", "check", str(SPEC)],
                           cwd=tmp_path, env=_env(), stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    assert tli.stdout is not None and tli.stderr is not None
    head = subprocess.run(["head", "-c", "1"], stdin=tli.stdout, capture_output=True,
                          timeout=TIMEOUT, check=False)
    tli.stdout.close()
    err = tli.stderr.read()
    tli.stderr.close()
    assert (tli.wait(timeout=TIMEOUT), err, head.stdout) == (0, b"", b"/")


def test_a_non_ascii_path_under_an_ascii_encoding(tmp_path: Path) -> None:
    shutil.copy(SPEC, tmp_path / "spéc.toml")
    env = _env(PYTHONIOENCODING="ascii")
    done = _tli("spec", "check", "spéc.toml", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(b"sp\\xe9c.toml: realizable"), done.stdout
    done = _tli("spec", "automaton", str(SPEC), "--output", "été.json", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    assert done.stdout == b"wrote \\xe9t\\xe9.json\n"
    assert (tmp_path / "été.json").is_file()


def test_a_file_name_that_is_not_utf8(tmp_path: Path) -> None:
    name = b"sp\xe9c.toml"  # Latin-1: undecodable under UTF-8 (a surrogate escape in argv)
    shutil.copyfile(os.fsencode(SPEC), os.path.join(os.fsencode(tmp_path), name))
    done = _tli("spec", "check", name, cwd=tmp_path, env=_env(PYTHONIOENCODING="utf-8"))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(b"sp\\udce9c.toml: realizable"), done.stdout


_PICTURE = """\
import sys
from tli_verify.cli import main
code = main(sys.argv[1:])
import matplotlib
sys.stderr.write(f"backend {matplotlib.get_backend()}\\n")
sys.exit(code)
"""


def test_matplotlib_is_headless_whatever_mplbackend_says(tmp_path: Path) -> None:
    picture = tmp_path / "task.png"
    done = subprocess.run([sys.executable, "-c", _PICTURE, "task", "check", str(TASK),
                           "--picture", str(picture)], cwd=tmp_path,
                          env=_env(MPLBACKEND="bogus", DISPLAY=""), capture_output=True,
                          timeout=TIMEOUT, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stderr.decode().splitlines()[-1].lower() == "backend agg"
    assert picture.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")


@pytest.mark.parametrize("args", [("spec", "check", str(SPEC)), ("task", "list")],
                         ids=["spec check", "task list"])
def test_a_deleted_working_directory_is_refused(args: tuple[str, ...], tmp_path: Path) -> None:
    gone = tmp_path / "gone"
    gone.mkdir()
    done = _sh('cd "$1" && rmdir "$1" && shift && exec $TLI "$@"', str(gone), *args,
               cwd=tmp_path)
    line = _one_error_line(done.stderr)
    assert done.returncode == 2, line
    assert line.startswith("error: the working directory no longer exists ("), line
    assert done.stdout == b""


def _wait_for(condition: Callable[[], bool], proc: subprocess.Popen[bytes], what: str,
              timeout: float = 90.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"tli exited ({proc.returncode}) before {what}: "
                        f"{proc.communicate()[1].decode()[-2000:]}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"no {what} within {timeout:g} s")
        time.sleep(0.05)


def test_sigterm_stops_a_campaign_like_ctrl_c(tmp_path: Path) -> None:
    """In the driver process (``--backend serial``): a worker pool stopped while its workers
    still start can print a worker's traceback (multiprocessing's, not tli's)."""
    out = tmp_path / "OUT"
    log = tmp_path / "stderr.txt"
    with open(log, "wb") as err:
        proc = subprocess.Popen([sys.executable, "-m", "tli_verify.cli", "verify", "--task",
                                 "scoop", "--examples", "100000", "--backend", "serial",
                                 "--out", str(out)], cwd=tmp_path, env=_env(),
                                stdout=subprocess.DEVNULL, stderr=err,
                                stdin=subprocess.DEVNULL)
        try:
            _wait_for(lambda: b"note: drawing" in log.read_bytes(), proc, "the campaign")
            time.sleep(1.0)  # simulating
            proc.send_signal(signal.SIGTERM)
            code = proc.wait(timeout=TIMEOUT)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    text = log.read_text()
    assert code == 130, text
    assert text.splitlines()[-1].startswith("error: interrupted"), text
    assert "Traceback" not in text
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert not [n for n in left if n.rsplit("/", 1)[-1].startswith(".") or n.endswith(".tmp")]
    assert any(n.endswith("campaign.json") for n in left), left  # the partial report


_SIGNAL = """\
import signal, sys, time
import tli_verify.cli as cli

def check_paths(args):  # the signal arrives while the command runs
    signal.raise_signal(getattr(signal, sys.argv[1]))
    # the interpreter runs a Python handler between bytecodes, not necessarily at once: the
    # command goes on running (as a real one would) until it does, for up to a minute
    end = time.monotonic() + 60.0
    while time.monotonic() < end:
        time.sleep(0.01)
    raise AssertionError("not interrupted")

cli.check_paths = check_paths
sys.exit(cli.main(sys.argv[2:]))
"""


@pytest.mark.parametrize("name", ["SIGTERM", "SIGINT"])
def test_a_signal_is_exit_130_and_one_line(name: str, tmp_path: Path) -> None:
    """SIGINT is a guard (already so); SIGTERM used to kill tli on the spot."""
    done = subprocess.run([sys.executable, "-c", _SIGNAL, name, "spec", "check", str(SPEC)],
                          cwd=tmp_path, env=_env(), capture_output=True, timeout=TIMEOUT,
                          check=False, preexec_fn=interactive_signals)
    assert _one_error_line(done.stderr).startswith("error: interrupted")
    assert (done.returncode, done.stdout) == (130, b"")


def test_ctrl_c_before_any_run_finished_is_one_line(tmp_path: Path) -> None:
    """``tli verify`` interrupted before its first batch finished: the partial report has no
    run to plot; stderr holds the notes and one error line (it used to print matplotlib's
    'No artists with labels found' warning first)."""
    log = tmp_path / "stderr.txt"
    with open(log, "wb") as err:
        proc = subprocess.Popen([sys.executable, "-m", "tli_verify.cli", "verify", "--task",
                                 "scoop", "--examples", "5000", "--workers", "1",
                                 "--out", str(tmp_path / "OUT")],
                                cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                                stderr=err, stdin=subprocess.DEVNULL,
                                preexec_fn=interactive_signals)
        try:
            _wait_for(lambda: b"note: drawing" in log.read_bytes(), proc, "the campaign")
            time.sleep(0.5)  # the worker starts; its first batch of 100 takes seconds
            proc.send_signal(signal.SIGINT)
            code = proc.wait(timeout=TIMEOUT)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    lines = log.read_text().strip().splitlines()
    assert code == 130, lines
    assert lines[-1].startswith("error: interrupted"), lines
    assert all(line.startswith(("note:", "error:")) for line in lines), lines


_IGNORING = """\
import signal, sys
import pytest
signal.signal(signal.SIGINT, signal.SIG_IGN)  # as in `make test &`: SIGINT ignored
sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", "-p", "no:xdist", sys.argv[1] + "::"
                      "test_a_signal_is_exit_130_and_one_line"]))
"""


def test_the_signal_test_holds_where_sigint_is_ignored(tmp_path: Path) -> None:
    """The signal test itself, run by a pytest whose SIGINT is ignored (the environment it
    failed in): it passes, both signals."""
    done = subprocess.run([sys.executable, "-c", _IGNORING, __file__], cwd=REPO, env=_env(),
                          capture_output=True, timeout=4 * TIMEOUT, check=False,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert done.returncode == 0, done.stdout.decode()[-3000:]
    assert b"2 passed" in done.stdout


@pytest.fixture(scope="module")
def egl() -> None:
    """MuJoCo renders here with ``MUJOCO_GL=egl`` (else the test is skipped)."""
    pytest.importorskip("mujoco")
    pytest.importorskip("imageio_ffmpeg")
    from tli_verify.sim import render

    if not render.probe_backend("egl").ok:
        pytest.skip("no EGL rendering on this machine")


@pytest.mark.sim
@pytest.mark.usefixtures("egl")
def test_sigterm_during_a_video_leaves_no_temporary_file(tmp_path: Path) -> None:
    """SIGTERM used to kill tli with the video half written in its temporary folder."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    video = tmp_path / "OUT.mp4"
    proc = subprocess.Popen([sys.executable, "-m", "tli_verify.cli", "sim", "franka",
                             "--no-perturb", "--video", str(video)], cwd=tmp_path,
                            env=_env(MUJOCO_GL="egl", TMPDIR=str(tmp)),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL)
    try:
        _wait_for(lambda: any(tmp.glob("tli-video-*/video.mp4")), proc, "the recording")
        time.sleep(0.5)  # frames are being encoded
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    text = err.decode()
    assert proc.returncode == 130, text
    assert text.splitlines()[-1].startswith("error: interrupted"), text
    assert "Traceback" not in text
    assert list(tmp.iterdir()) == []
    assert not video.exists()


_RECORDING = """\
import os, sys, tempfile
from pathlib import Path
import mujoco
from tli_verify.sim.render import Recorder

model = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 1"/><geom size=".1"/></worldbody></mujoco>')

class Rig:
    model = model
    calls = 0

    @property
    def data(self):
        Rig.calls += 1
        if Rig.calls == 4:
            raise KeyboardInterrupt  # Ctrl-C (or SIGTERM in tli) while a frame is rendered
        return mujoco.MjData(model)

rec = Recorder(every=1, size=(64, 64))
try:
    for _ in range(10):
        rec.frame(Rig())
except KeyboardInterrupt:
    pass
print(rec.count, sorted(os.listdir(tempfile.gettempdir())))
"""


@pytest.mark.sim
@pytest.mark.usefixtures("egl")
def test_an_interrupted_recording_removes_its_temporary_file_at_once(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-c", _RECORDING], cwd=tmp_path,
                          env=_env(MUJOCO_GL="egl", TMPDIR=str(tmp_path)),
                          capture_output=True, text=True, timeout=TIMEOUT, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "3 []\n"  # three frames, then nothing left behind
