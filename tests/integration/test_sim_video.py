"""``tli sim franka --video``: headless rendering and the MP4.

Every rendering runs in a subprocess: MuJoCo fixes its OpenGL backend when it is imported,
and this test process imported it without one. Skipped when no headless backend (EGL,
OSMesa) renders on this machine.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("imageio_ffmpeg")

from tli_verify.errors import TliError
from tli_verify.sim import render

pytestmark = pytest.mark.sim

REPO = Path(__file__).resolve().parents[2]
DURATION = 0.5  # the shortest --duration: 25 control steps, then 1 s (50 steps) of settling
SETTLE = 1.0  # run_trial's default
EVERY = 2  # Recorder's default: one control step in two


def _env(tmp: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    env.update(MPLBACKEND="Agg", TMPDIR=str(tmp),
               PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])]))
    env.update(extra)
    return env


def _tli(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tli_verify.cli", *args], env=env,
                          capture_output=True, text=True, timeout=300, check=False)


def _decode(path: Path, size: tuple[int, int]) -> np.ndarray:
    """The frames of an MP4, shape (n, height, width, 3), decoded by imageio-ffmpeg's ffmpeg
    (imageio's own reader leaves the decoder's pipes open, which pytest reports)."""
    import imageio_ffmpeg

    dec = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path),
                          "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, timeout=120, check=True)
    h, w = size
    assert dec.stdout and len(dec.stdout) % (h * w * 3) == 0
    nframes, secs = imageio_ffmpeg.count_frames_and_secs(str(path))
    frames = np.frombuffer(dec.stdout, np.uint8).reshape(-1, h, w, 3)
    assert nframes == len(frames)
    assert abs(nframes / secs - 1 / (0.02 * EVERY)) < 0.5  # 25 frames/s: real time
    return frames


@pytest.fixture(scope="module")
def backend() -> str:
    """The headless backend tli would choose here (or the module is skipped)."""
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    try:
        return render.choose_backend(env)
    except TliError as exc:
        pytest.skip(f"no headless OpenGL on this machine: {exc}")


@pytest.fixture(scope="module")
def video(backend: str, tmp_path_factory: pytest.TempPathFactory
          ) -> tuple[subprocess.CompletedProcess[str], Path, np.ndarray]:
    """One nominal trial rendered by the CLI, and its frames read back (n, h, w, 3)."""
    tmp = tmp_path_factory.mktemp("video")
    out = tmp / "out.mp4"
    (tmp / "t").mkdir()
    proc = _tli("sim", "franka", "--trials", "1", "--duration", str(DURATION),
                "--no-perturb", "--video", str(out), env=_env(tmp / "t"))
    frames = np.zeros((0, 0, 0, 3), dtype=np.uint8)
    if out.exists():
        frames = _decode(out, (360, 480))
    return proc, out, frames


def test_the_mp4_has_one_frame_per_two_control_steps(
        video: tuple[subprocess.CompletedProcess[str], Path, np.ndarray]) -> None:
    from tli_verify.sim.demos import CONTROL_DT

    proc, out, frames = video
    assert proc.returncode in (0, 1), proc.stderr  # half a second may deliver nothing
    assert proc.stderr == ""  # no OpenGL teardown noise at exit
    assert f"video {out}" in proc.stdout
    steps = round(DURATION / CONTROL_DT) + round(SETTLE / CONTROL_DT)
    assert abs(len(frames) - math.ceil(steps / EVERY)) <= 1
    assert frames.shape[1:] == (360, 480, 3)
    assert not list(out.parent.glob(".out.mp4.*"))  # no temporary file left by the write
    assert not list((out.parent / "t").iterdir())  # the encoder's private directory removed


def test_the_frames_show_the_scene_moving(
        video: tuple[subprocess.CompletedProcess[str], Path, np.ndarray]) -> None:
    _, _, frames = video
    assert len(frames) > 10
    f = frames.astype(np.float32)
    assert float(f.std(axis=(1, 2, 3)).min()) > 5.0  # every frame shows something
    # the ladle moves: the first frame differs from the last, and motion is spread over
    # several frames (not one cut)
    assert float(np.abs(f[0] - f[-1]).mean()) > 0.5
    steps = np.abs(np.diff(f, axis=0)).mean(axis=(1, 2, 3))
    assert int((steps > 0.1).sum()) >= 5


def test_the_probe_tells_a_working_backend_from_a_bogus_one(backend: str) -> None:
    assert render.probe_backend(backend).ok
    bad = render.probe_backend("bogus")
    assert not bad.ok and "bogus" in bad.detail


@pytest.mark.parametrize("existing", [False, True])
def test_a_backend_that_fails_leaves_no_file(existing: bool, tmp_path: Path) -> None:
    out = tmp_path / "out.mp4"
    if existing:
        out.write_bytes(b"an earlier video")
    proc = _tli("sim", "franka", "--duration", "0.5", "--no-perturb", "--video", str(out),
                env=_env(tmp_path, MUJOCO_GL="bogus"))
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: --video: MUJOCO_GL=bogus")
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "libegl1" in proc.stderr and "libosmesa6" in proc.stderr
    assert proc.stdout == ""  # refused before any trial ran
    if existing:
        assert out.read_bytes() == b"an earlier video"
    else:
        assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == (["out.mp4"] if existing else [])


def test_a_bogus_backend_without_video_is_a_clear_error(tmp_path: Path) -> None:
    """Not exit 70: MuJoCo raises on import with an unknown MUJOCO_GL, video or not."""
    proc = _tli("sim", "franka", "--duration", "0.5", "--no-perturb",
                env=_env(tmp_path, MUJOCO_GL="bogus"))
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.startswith("error: MuJoCo refused to load with MUJOCO_GL='bogus'")
    assert proc.stderr.count("\n") == 1


_FAIL_MID_VIDEO = """
import sys
import tli_verify.sim.loop as loop
from tli_verify.cli import main
from tli_verify.errors import TliError

real = loop.run_trial

def failing(*args, frame=None, **kwargs):
    calls = [0]

    def counted(rig):
        frame(rig)
        calls[0] += 1
        if calls[0] == 12:
            raise TliError("forced failure after 12 rendered steps")

    return real(*args, frame=counted, **kwargs)

loop.run_trial = failing
sys.exit(main(sys.argv[1:]))
"""


def test_a_trial_failing_mid_video_leaves_no_file(backend: str, tmp_path: Path) -> None:
    """Frames were rendered and encoded, then the trial failed: nothing at the output, the
    encoder's temporary directory removed, one error line."""
    out = tmp_path / "out.mp4"
    (tmp_path / "t").mkdir()
    proc = subprocess.run(
        [sys.executable, "-c", _FAIL_MID_VIDEO, "sim", "franka", "--duration", "0.5",
         "--no-perturb", "--video", str(out)],
        env=_env(tmp_path / "t", MUJOCO_GL=backend), capture_output=True, text=True,
        timeout=300, check=False)
    assert proc.returncode == 2
    assert proc.stderr == "error: forced failure after 12 rendered steps\n"
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t"]
    assert not list((tmp_path / "t").iterdir())


def test_the_recorder_runs_at_the_control_period() -> None:
    from tli_verify.sim.demos import CONTROL_DT

    assert render.CONTROL_DT == CONTROL_DT
    assert render.Recorder().fps == round(1 / (CONTROL_DT * EVERY))
