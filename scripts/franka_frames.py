"""Render one Franka scooping trial headless and write a contact sheet of it.

The same path as ``tli sim franka --video`` (:mod:`tli_verify.sim.render`): the OpenGL backend
is chosen before MuJoCo is imported (egl, else osmesa), the first trial is rendered by a
:class:`~tli_verify.sim.render.Recorder` into an MP4 (on the Panda: the whole arm standing on
the table, a person's force drawn as a red arrow), which is decoded again; four frames are
picked and laid out 1 x 4, each titled with its simulated time and what happens:

- nominal (default): the middle of the first run of each mode a, b, c, d (paper Sec. 7.2:
  reach, scoop, transport, pour), evenly spaced ones if fewer modes ran;
- ``--perturb`` (the seeded push and tilt of ``tli sim franka``): the frame of the largest
  force of each perturbation (before the first replan, if that falls within it), the
  executive's first replan (0.6 s after it), and the pour
  after the last perturbation (the middle of the first run of mode d that starts once the
  hands let go; the last frame, beads settled, if none).

The sheet's title names the robot, the seed and the beads delivered.

Usage (from the repository root; the commands of ``docs/howto/regenerate.md``)::

    .venv/bin/python scripts/franka_frames.py [--seed 1] [--duration 40] [--perturb]
        [--robot panda|free-tool] [--out docs/img/franka_frames.png] [--video OUT.mp4]

Exit 0 when written, 2 with one ``error:`` line otherwise.
"""

from __future__ import annotations

import argparse
import io
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

ROOT = Path(__file__).resolve().parents[1]
MODE_NAMES = {"a": "reach", "b": "scoop", "c": "transport", "d": "pour"}
ROBOT_NAMES = {"panda": "Panda", "free-tool": "free tool"}
REPLAN_LAG = 0.6
"""Seconds after a replan at which its frame is shown (the arm has begun to turn back)."""


@dataclass(frozen=True, slots=True)
class Shown:
    """One rendered frame: when, the mode, and the person's force and torque on the ladle.

    Attributes
    ----------
    time : float
        Simulated seconds since the trial's start.
    step : int
        Control steps since the trial's start (the executive's step count).
    mode : str
    force, torque : float
        Magnitudes (N, N m); 0 without a perturbation.
    """

    time: float
    step: int
    mode: str
    force: float = 0.0
    torque: float = 0.0


def decode(path: Path, size: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """The frames of an MP4, shape (n, height, width, 3) (imageio-ffmpeg's ffmpeg)."""
    import imageio_ffmpeg

    dec = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-v", "error", "-i", str(path),
                          "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
                         capture_output=True, timeout=600, check=True)
    h, w = size
    return np.frombuffer(dec.stdout, np.uint8).reshape(-1, h, w, 3)


def _runs(values: list[str] | list[bool]) -> list[tuple[object, int, int]]:
    """Maximal runs of equal values: ``(value, first, end)``, in order."""
    out = []
    i = 0
    while i < len(values):
        j = i
        while j < len(values) and values[j] == values[i]:
            j += 1
        out.append((values[i], i, j))
        i = j
    return out


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
    for mode, a, b in _runs(modes):
        runs.setdefault(str(mode), (a, b))
    chosen = sorted({(a + b - 1) // 2 for a, b in runs.values()})[:n]
    for k in np.linspace(0, len(modes) - 1, n + 2)[1:-1].round().astype(int):
        if len(chosen) >= n:
            break
        if int(k) not in chosen:
            chosen.append(int(k))
    return sorted(chosen)


def pick_perturbed(shown: list[Shown], replans: list[int],
                   hands: list[tuple[str, float]] | None = None, n: int = 4
                   ) -> list[tuple[int, str]]:
    """Frames of a perturbed trial (module doc), with a caption each, in time order.

    Parameters
    ----------
    shown : list of Shown
        The rendered frames.
    replans : list of int
        Control steps at which the executive replanned (its ``Replan`` events).
    hands : list of (str, float), optional
        Each perturbation's kind (``"push"``, ``"tilt"``) and when it was applied (s): a
        run of frames with a hand on the ladle is named after the one applied in it.
    n : int, optional
        At most this many frames: the hands first, then the replan, then the pour.

    Returns
    -------
    list of (int, str)
        ``(frame index, caption)``.
    """
    out: list[tuple[int, str, int]] = []  # (index, caption, priority)
    pushed = [s.force > 0.0 or s.torque > 0.0 for s in shown]
    first_replan = replans[0] if replans else None
    last_touch = -1
    for on, a, b in _runs(pushed):
        if not on:
            continue
        run = range(a, b)
        if first_replan is not None and shown[a].step < first_replan <= shown[b - 1].step:
            run = range(a, max(a + 1, next(i for i in run if shown[i].step >= first_replan)))
        k = max(run, key=lambda i: shown[i].force)
        s = shown[k]
        kinds = [kind for kind, at in hands or []
                 if shown[a].time - 0.1 <= at <= shown[b - 1].time]
        what = " + ".join(kinds) or "hand"
        torque = f", {s.torque:.0f} N m" if s.torque >= 0.5 else ""
        out.append((k, f"{what}: {s.force:.0f} N{torque} (mode {s.mode})", 0))
        last_touch = b - 1
    if first_replan is not None:
        at = first_replan + round(REPLAN_LAG / 0.02)
        k = min(range(len(shown)), key=lambda i: abs(shown[i].step - at))
        before = shown[min(range(len(shown)),
                           key=lambda i: abs(shown[i].step - first_replan + 1))].mode
        out.append((k, f"replanned: mode {before} -> {shown[k].mode}", 1))
    pour = None
    for mode, a, b in _runs([s.mode for s in shown]):
        if mode == "d" and a > last_touch:
            pour = (a + b - 1) // 2
            break
    if pour is not None:
        out.append((pour, f"mode d ({MODE_NAMES['d']})", 2))
    else:
        out.append((len(shown) - 1, "beads settled", 2))
    keep = sorted(out, key=lambda o: o[2])[:n]
    seen: set[int] = set()
    result = []
    for k, caption, _ in sorted(keep):
        if k not in seen:
            seen.add(k)
            result.append((k, caption))
    return result


def short_modes(sequence: str, limit: int = 12) -> str:
    """The mode sequence ``"a b c d ..."``, cut after ``limit`` modes with a count of the
    rest."""
    parts = sequence.split()
    if len(parts) <= limit:
        return sequence
    return f"{' '.join(parts[:limit])} ... ({len(parts) - limit} more)"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=None,
                    help="step budget in simulated seconds (default tli sim franka's, 40)")
    ap.add_argument("--perturb", action="store_true", help="the seeded push and tilt")
    ap.add_argument("--robot", default="panda", choices=sorted(ROBOT_NAMES))
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
    from tli_verify.sim import TRIAL_DURATION
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import run_trial

    policy = load_policy("LTL-DS")
    rec = Recorder()
    shown: list[Shown] = []
    step = [0]

    def frame(rig: object) -> None:
        before = rec.count
        rec.frame(rig)
        step[0] += 1
        if rec.count > before:
            w = getattr(rig, "person_wrench", None)
            f, tq = (0.0, 0.0) if w is None else (float(np.linalg.norm(w[:3])),
                                                   float(np.linalg.norm(w[3:])))
            shown.append(Shown(step[0] * CONTROL_DT, step[0], policy.mode, f, tq))

    duration = TRIAL_DURATION if args.duration is None else args.duration
    res = run_trial(policy, args.seed, perturbations=None if args.perturb else [],
                    duration=duration, frame=frame, robot=args.robot)
    with tempfile.TemporaryDirectory() as tmp:
        mp4 = Path(args.video) if args.video is not None else Path(tmp) / "trial.mp4"
        rec.save(mp4)
        frames = decode(mp4, rec.size)
    n = min(len(frames), len(shown))
    shown = shown[:n]
    if args.perturb:
        replans = [int(e.rsplit(" ", 1)[1]) for e in res.events if e.startswith("Replan at")]
        hands = [(p.kind, a) for p, a in zip(res.perturbations, res.applied, strict=True)
                 if not math.isnan(a)]
        chosen = pick_perturbed(shown, replans, hands)
    else:
        chosen = [(i, f"mode {shown[i].mode} ({MODE_NAMES.get(shown[i].mode, '?')})")
                  for i in pick([s.mode for s in shown])]
    fig, axes = plt.subplots(1, len(chosen), figsize=(3.2 * len(chosen), 2.95))
    for ax, (i, caption) in zip(np.atleast_1d(axes), chosen, strict=True):
        ax.imshow(frames[i])
        ax.set_title(f"t = {shown[i].time:.1f} s: {caption}", fontsize=8.5)
        ax.axis("off")
    perts = ", ".join(f"{p.kind} at {a:.1f} s" for p, a in
                      zip(res.perturbations, res.applied, strict=True) if not math.isnan(a))
    what = f"perturbed ({perts or 'no hand touched the ladle'})" if args.perturb \
        else "nominal"
    verdict = "delivered" if res.success else "FAILED"
    fig.suptitle(f"{ROBOT_NAMES[args.robot]}, seed {args.seed}, {what}: {verdict}, "
                 f"{res.delivered} bead{'' if res.delivered == 1 else 's'} in the target bowl\n"
                 f"modes {short_modes(res.mode_sequence())}; {res.controller} control, "
                 f"{res.sensors} sensors, stall rule fired {res.stalls}x; "
                 f"{res.sim_time:.1f} s simulated, "
                 f"rendered headless ({backend})", fontsize=9.5)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(args.out, buf.getvalue())
    sys.stdout.write(f"{args.out}: frames {', '.join(str(i) for i, _ in chosen)} of {n}; "
                     f"{ROBOT_NAMES[args.robot]} seed {args.seed}: {res.delivered} bead(s) "
                     f"delivered, modes {res.mode_sequence()}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
