"""Summarise ``tli sim franka --json`` runs as the tables of benchmarks/results/franka_loop.md.

Usage::

    .venv/bin/python scripts/franka_loop_table.py LABEL=RUN.jsonl [LABEL=RUN.jsonl ...]

Each file is the standard output of one ``tli sim franka ... --json`` (one JSON object per
trial, then the summary). Prints one Markdown row per file: trials, soup delivered, passed the
physics oracle, trials in which the stall rule fired (and its firings), cuts learned, reflex
stops, trials whose measured pose was ever outside a cut of the running mode (and the largest
distance, DS units), the largest limit ratio, and simulated over wall-clock seconds.
"""

from __future__ import annotations

import json
import sys
from typing import Any


def records(path: str) -> list[dict[str, Any]]:
    """The per-trial objects of one run's output (the summary object is left out)."""
    text = open(path, encoding="utf-8").read()
    dec, i, out = json.JSONDecoder(), 0, []
    while i < len(text):
        while i < len(text) and text[i].isspace():
            i += 1
        if i >= len(text):
            break
        try:
            doc, i = dec.raw_decode(text, i)
        except json.JSONDecodeError:
            break
        if isinstance(doc, dict) and "seed" in doc and "mode_sequence" in doc:
            out.append(doc)
    return out


def row(label: str, rs: list[dict[str, Any]]) -> str:
    """One table row."""
    n = len(rs)
    seeds = f"{min(r['seed'] for r in rs)}-{max(r['seed'] for r in rs)}" if rs else "-"
    ok = sum(not r["violations"] for r in rs)
    delivered = sum(bool(r["success"]) for r in rs)
    fired = sum(int(r.get("stalls", 0)) > 0 for r in rs)
    stalls = sum(int(r.get("stalls", 0)) for r in rs)
    cuts = sum(int(r["cuts_added"]) for r in rs)
    stops = sum(r["stopped"] is not None for r in rs)
    out = [r for r in rs if r.get("cut_gap", {}).get("outside_steps", 0)]
    far = max((float(r["cut_gap"]["max_outside"]) for r in out), default=0.0)
    ratio = max((max(r["limit_ratios"].get(k, 0.0) for k in ("torque", "joint_velocity",
                                                            "cartesian_speed"))
                 for r in rs if r["limit_ratios"]), default=0.0)
    sim = sum(float(r["sim_time"]) for r in rs)
    wall = sum(float(r["wall_time"]) for r in rs)
    speed = sim / wall if wall else 0.0
    return (f"| {label} | {seeds} | {n} | {delivered}/{n} | **{ok}/{n}** | {fired} ({stalls}) | "
            f"{cuts} | {stops} | {len(out)} ({far:.2f}) | {ratio:.2f} | {speed:.2f}x |")


def main(argv: list[str]) -> int:
    if not argv or any("=" not in a for a in argv):
        sys.stderr.write("error: usage: franka_loop_table.py LABEL=RUN.jsonl ...\n")
        return 2
    print("| run | seeds | trials | delivered soup | passed the oracle | stall rule fired "
          "(firings) | cuts | reflex stops | outside a cut (max, DS units) | largest limit "
          "ratio | sim/wall |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for arg in argv:
        label, path = arg.split("=", 1)
        print(row(label, records(path)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
