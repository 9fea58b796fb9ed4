"""Draw the Franka policy turning a rolled or yawed ladle back (issue 35, item 6).

Four trials of the bundled 6-D policy on the Panda (the measured law, the robot's sensors, no
push), each started with the tray turned 0.4 rad about its front axis (``rx``, +-) or its
normal (``rz``, +-) at the demonstrations' start position (``run_trial(start=...)``). One panel
per trial: the measured roll and yaw and the impedance law's target over the first 4 s, the
running mode shaded. The target is the DS's, integrated from the measured pose on its leash:
no orientation is held fixed anywhere in the loop.

Usage (from the repository root; ``docs/howto/regenerate.md``)::

    .venv/bin/python scripts/franka_pose_recovery.py [--out docs/img/franka_pose_recovery.png]
        [--seed 1]

Exit 0 when written, 2 with one ``error:`` line otherwise.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import numpy as np

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_bytes

SECONDS = 4.0
TURNS = ((3, 0.4), (3, -0.4), (5, 0.4), (5, -0.4))
"""(pose column, angle): roll (rx) and yaw (rz) starts."""


def main(argv: list[str] | None = None) -> int:
    """Run the four trials and write the picture."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/img/franka_pose_recovery.png"))
    parser.add_argument("--seed", type=int, default=1, help="bead placement (default 1)")
    args = parser.parse_args(argv)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        from tli_verify.sim.demos import scoop_waypoints
        from tli_verify.sim.franka_project import load_policy
        from tli_verify.sim.loop import TraceStep, run_trial

        fig, axes = plt.subplots(1, len(TURNS), figsize=(4.2 * len(TURNS), 3.6), sharey=True)
        shades = {"a": "0.93", "b": "#fde9c9", "c": "#f9d0d0", "d": "#d7efd7"}
        for ax, (col, angle) in zip(axes, TURNS, strict=True):
            start = scoop_waypoints()[0, 1:].copy()
            start[col] = angle
            trace: list[TraceStep] = []
            res = run_trial(load_policy("LTL-DS"), args.seed, perturbations=[], trace=trace,
                            start=start)
            steps = [s for s in trace if s.time <= SECONDS]
            t = np.array([s.time for s in steps])
            z = np.array([s.measured for s in steps])
            ref = np.array([s.target for s in steps])
            for k, s in enumerate(steps):
                ax.axvspan(s.time, s.time + 0.02, color=shades.get(s.mode, "white"), lw=0)
                if k == 0 or steps[k - 1].mode != s.mode:
                    ax.text(s.time + 0.03, 0.42, s.mode, fontsize=9)
            ax.plot(t, z[:, 3], color="tab:blue", lw=1.6, label="roll rx (measured)")
            ax.plot(t, ref[:, 3], color="tab:blue", lw=1.0, ls="--", label="rx target")
            ax.plot(t, z[:, 5], color="tab:red", lw=1.6, label="yaw rz (measured)")
            ax.plot(t, ref[:, 5], color="tab:red", lw=1.0, ls="--", label="rz target")
            ax.axhline(0.0, color="k", lw=0.5)
            name = "roll" if col == 3 else "yaw"
            ax.set_title(f"start {name} {angle:+.1f} rad: {res.mode_sequence()}, "
                         f"{res.delivered} bead(s)", fontsize=9)
            ax.set_xlabel("time (s)")
            ax.set_ylim(-0.5, 0.5)
        axes[0].set_ylabel("rad")
        axes[0].legend(loc="lower right", fontsize=7)
        fig.suptitle("The Franka's 6-D policy turns a rolled or yawed ladle back (Panda, measured "
                     "law, robot's sensors, no push; dashed: the impedance target)", fontsize=10)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=110)
        plt.close(fig)
        atomic_write_bytes(args.out, buf.getvalue())
    except (TliError, OSError) as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    sys.stdout.write(f"wrote {args.out}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
