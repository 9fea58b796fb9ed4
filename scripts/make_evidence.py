"""Campaign evidence for every bundled model: ``tli evidence`` on the repository and on the
Franka project (a thin wrapper; the command does the work).

Usage (after any bundled model, certificate, spec or task changed)::

    .venv/bin/python scripts/make_evidence.py [--examples 1000] [--seed 0] [--workers W]
        [--only NAME ...] [--franka [--trials 30] [--robot panda|free-tool] [--no-stall-rule]
        [--sensors franka|ideal] [--controller passive|tracking] [--duration 40]]

is ``tli evidence . [...]`` (every ``models/*.model.json``: a bisimulation campaign on the
model, its certificate, the spec it names and the spec's task), and with ``--franka``
``tli evidence sim/franka [...]`` (the Franka policy's physical campaign of MuJoCo trials).
Exit 0 when every campaign found nothing, 1 when one found a violation (its evidence is written
anyway, as an honest record the gate refuses), 2 on bad arguments or files.
"""

from __future__ import annotations

import sys

from tli_verify.cli import main as tli


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if "--franka" in args:
        args.remove("--franka")
        return tli(["evidence", "sim/franka", *args])
    return tli(["evidence", ".", *args])


if __name__ == "__main__":
    sys.exit(main())
