"""Render one Franka scooping trial headless and write a contact sheet: one frame per mode.

The same path as ``tli sim franka --video`` (:mod:`tli_verify.sim.render`): the OpenGL backend
is chosen before MuJoCo is imported (egl, else osmesa), the first trial is rendered by a
:class:`~tli_verify.sim.render.Recorder` into an MP4, which is decoded again; four frames are
picked -- the middle of the first run of each mode a, b, c, d (paper Sec. 7.2: reach, scoop,
transport, pour), evenly spaced ones if fewer modes ran -- and laid out 1 x 4, each titled
with its simulated time and mode.

Usage (from the repository root)::

    .venv/bin/python scripts/franka_frames.py [--seed 1] [--duration 14] [--perturb]
        [--out docs/img/franka_frames.png] [--video OUT.mp4]

Exit 0 when written, 2 with one ``error:`` line otherwise.
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
MODE_NAMES = {"a": "reach the bowl", "b": "scoop", "c": "transport", "d": "pour"}


def decode(path: Path, size: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """The frames of an MP4, shape (n, height, width, 3) (imageio-ffmpeg's ffmpeg)."""
    import imageio_ffmpeg

    dec = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path),
                          "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, timeout=600, check=True)
    h, w = size
    return np.frombuffer(dec.stdout, np.uint8).reshape(-1, h, w, 3)


def pick(modes: list[str], n: int = 4) -> list[int]:
    """Indices of ``n`` frames: the middle of the first run of each mode, then evenly spaced
    frames for the rest, sorted.

    Parameters
    ----------
    modes : list of str
        The mode at each rendered frame.
    n : int, optional

    Returns
    -------
    list of int
    """
    runs: dict[str, tuple[int, int]] = {}
    i = 0
    while i < len(modes):
        j = i
        while j < len(modes) and modes[j] == modes[i]:
            j += 1
        runs.setdefault(modes[i], (i, j))
        i = j
    chosen = sorted({(a + b - 1) // 2 for a, b in runs.values()})[:n]
    for k in np.linspace(0, len(modes) - 1, n + 2)[1:-1].round().astype(int):
        if len(chosen) >= n:
            break
        if int(k) not in chosen:
            chosen.append(int(k))
    return sorted(chosen)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=14.0)
    ap.add_argument("--perturb", action="store_true", help="the seeded push and tilt")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "img" / "franka_frames.png")
    ap.add_argument("--video", type=Path, default=None, help="keep the MP4 here too")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from tli_verify.errors import TliError

    try:
        return _run(args)
    except TliError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return exc.exit_code


def _run(args: argparse.Namespace) -> int:
    from tli_verify.sim.render import CONTROL_DT, Recorder, select_backend

    backend = select_backend()  # before MuJoCo is imported (next line)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.io import atomic_write_bytes
    from tli_verify.sim.loop import load_policy, run_trial

    policy = load_policy("LTL-DS")
    rec = Recorder()
    shown: list[tuple[float, str]] = []  # (simulated time, mode) of each rendered frame
    step = [0]

    def frame(rig: object) -> None:
        before = rec.count
        rec.frame(rig)
        step[0] += 1
        if rec.count > before:
            shown.append((step[0] * CONTROL_DT, policy.mode))

    res = run_trial(policy, args.seed, perturbations=None if args.perturb else [],
                    duration=args.duration, frame=frame)
    with tempfile.TemporaryDirectory() as tmp:
        mp4 = Path(args.video) if args.video is not None else Path(tmp) / "trial.mp4"
        rec.save(mp4)
        frames = decode(mp4, rec.size)
    n = min(len(frames), len(shown))
    idx = pick([m for _, m in shown[:n]])
    fig, axes = plt.subplots(1, len(idx), figsize=(3.2 * len(idx), 2.8))
    for ax, i in zip(np.atleast_1d(axes), idx, strict=True):
        t, mode = shown[i]
        ax.imshow(frames[i])
        ax.set_title(f"t = {t:.1f} s: mode {mode} ({MODE_NAMES.get(mode, mode)})", fontsize=9)
        ax.axis("off")
    fig.suptitle(f"tli sim franka --seed {args.seed}{'' if args.perturb else ' --no-perturb'}"
                 f": {'delivered' if res.success else 'FAILED'} ({res.delivered} beads), "
                 f"modes {res.mode_sequence()}; rendered headless ({backend})", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(args.out, buf.getvalue())
    sys.stdout.write(f"{args.out}: frames {', '.join(str(i) for i in idx)} of {n}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
