"""Cuts until no exit, per mode: the offline hand-off step (tli_verify.runtime.handoff) on the
bundled models and on the generated tasks of tests/support/awkward.py (learned here).

Usage: python scripts/handoff_cuts.py OUT.md [--samples N]
A convex box or polytope mode needs at most one cut per facet (its facets that keep the
attractor inside are made cuts at once); the table measures the others.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.support.awkward import TASKS, write_project  # noqa: E402
from tli_verify.model.serialize import load_model  # noqa: E402
from tli_verify.runtime.handoff import context_for_spec, learn_handoffs  # noqa: E402


def _rows(name: str, model_path: Path, samples: int) -> list[str]:
    model = load_model(model_path)
    ctx = context_for_spec(model.spec_path)
    if ctx is None:
        return [f"| {name} | - | online only | | | | | |"]
    t = time.perf_counter()
    rep = learn_handoffs(ctx.task, ctx.automaton, model, dt=ctx.task.dt,
                         goal_modes=ctx.goal_modes, samples=samples)
    secs = time.perf_counter() - t
    out = []
    for c in rep.claims:
        out.append(f"| {name} | {c.key} | {c.established} | {c.cuts_offline} | {c.face_cuts} | "
                   f"{c.rounds} | {c.exits} of {c.samples} | {secs:.1f} |")
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--samples", type=int, default=1000)
    a = ap.parse_args()
    rows = ["| task | DS | hand-off | cuts until no exit | face cuts | rounds with an exit | "
            "exits in the final draw | seconds (all DS) |",
            "|---|---|---|---:|---:|---:|---:|---:|"]
    for path in sorted((ROOT / "models").glob("*.model.json")):
        rows += _rows(path.name.removesuffix(".model.json"), path, a.samples)
        print(rows[-1], flush=True)
    tli = str(Path(sys.executable).parent / "tli")
    with tempfile.TemporaryDirectory() as tmp:
        for name in TASKS:
            root = write_project(Path(tmp) / name, name)
            subprocess.run([tli, "demos", f"tasks/{name}.toml"], cwd=root, check=True,
                           capture_output=True)
            demos = sorted(str(p.relative_to(root)) for p in (root / "demos").glob("*.csv"))
            subprocess.run([tli, "learn", *demos, "--spec", f"specs/{name}.toml", "-o",
                            f"models/{name}.model.json", "--no-handoff"], cwd=root, check=True,
                           capture_output=True)
            rows += _rows(f"{name} (generated)", root / "models" / f"{name}.model.json",
                          a.samples)
            print(rows[-1], flush=True)
    a.out.write_text("\n".join(rows) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
