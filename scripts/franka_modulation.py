"""Fig. 9-style picture of modulation at work in physics (tli_verify.sim.scenario).

Runs the regression scenario (the pour that sweeps past the bowl, bead seed 0, Panda, nominal,
no retry) without modulation and with LTL-DS, prints each run's exits of the pour mode, cuts
and beads delivered, and draws them side by side::

    .venv/bin/python scripts/franka_modulation.py [--out docs/img/franka_modulation.png]
        [--root DIR] [--controller LAW] [--sensors KIND] [--seed S]

``--root`` the Franka project (default ``tests/support/franka_pour``, the policy the scenario
was found with; ``sim/franka`` is the deployed one, whose pour does not leave its mode);
``--controller`` and ``--sensors`` the loop's (default: the tracking law and the ideal sensors
it was found in); ``--seed`` another bead seed.

An output that cannot be written is one ``error:`` line, exit 2, before any trial runs.
"""

from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    from dataclasses import replace
    from pathlib import Path

    from tli_verify.errors import TliError
    from tli_verify.io import check_output_file
    from tli_verify.sim.scenario import POUR_SCENARIO, plot_scenario, run_scenario

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/img/franka_modulation.png", metavar="OUT.png")
    ap.add_argument("--root", default="tests/support/franka_pour", metavar="DIR",
                    help="the Franka project (default %(default)s)")
    ap.add_argument("--controller", choices=("tracking", "measured", "passive"),
                    default=POUR_SCENARIO.controller)
    ap.add_argument("--sensors", choices=("ideal", "franka"), default=POUR_SCENARIO.sensors)
    ap.add_argument("--seed", type=int, default=None, help="bead seed (default 0)")
    args = ap.parse_args(argv)
    scenario = replace(POUR_SCENARIO, controller=args.controller, sensors=args.sensors,
                       retry=args.sensors == "franka")  # the robot's s needs the stall rule
    if args.seed is not None:
        scenario = replace(scenario, seed=args.seed)
    root = Path(args.root)
    try:
        # before the trials; never over a file of the Franka project the trials read
        read = [f for f in root.rglob("*") if f.is_file()]
        check_output_file(args.out, inputs=read, what="picture")
        runs = [run_scenario(v, scenario, root=root) for v in ("no-modulation", "LTL-DS")]
        for run in runs:
            print(f"{run.variant:14s} modes {run.result.mode_sequence()}: {run.exits} exit(s) "
                  f"of {scenario.mode}, {run.repeats} repeated (beyond an earlier "
                  f"failure's cut), {len(run.cuts)} cut(s), {run.result.delivered} bead(s), "
                  f"success {run.result.success}")
        plot_scenario(runs, args.out)
    except TliError as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
