"""Issue 30's side-by-side: the generated tasks (tests/support/awkward.py) learned with and
without the offline hand-off step, each run through a 500-run random-start campaign (the
task's default pushes, and none), through the commands a user runs.

Usage: python scripts/handoff_side_by_side.py OUT_DIR [--examples N]
Writes OUT_DIR/handoff_side_by_side.md (one row per task, step and push setting).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.support.awkward import TASKS, write_project


def _tli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(Path(sys.executable).parent / "tli"), *args], cwd=cwd, text=True,
                          capture_output=True, check=False)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--examples", type=int, default=500)
    a = ap.parse_args()
    rows = ["| task | offline step | pushes | runs | satisfied | looping | undecided | "
            "violations | cuts in the model | cuts online | cuts per run |",
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name in TASKS:
        for step in ("on", "off"):
            root = a.out / f"{name}-{step}"
            write_project(root, name)
            _tli("demos", f"tasks/{name}.toml", cwd=root)
            demos = sorted(str(p.relative_to(root)) for p in (root / "demos").glob("*.csv"))
            learn = ["learn", *demos, "--spec", f"specs/{name}.toml", "-o",
                     f"models/{name}.model.json"]
            if step == "off":
                learn.append("--no-handoff")
            r = _tli(*learn, cwd=root)
            if r.returncode:
                sys.stderr.write(r.stderr)
                return 1
            _tli("certify", f"models/{name}.model.json", cwd=root)
            model = json.loads((root / "models" / f"{name}.model.json").read_text())
            in_model = sum(len(m.get("cuts", [])) for m in model["modes"].values())
            for pushes in ("0", "default"):
                cmd = ["verify", "--spec", f"specs/{name}.toml", "--examples",
                       str(a.examples), "--random-starts", "--out",
                       f"out/{pushes}", "--no-shrink"]
                if pushes == "0":
                    cmd += ["--max-pushes", "0"]
                _tli(*cmd, cwd=root)
                rec = json.loads((root / "out" / pushes / "campaign.json").read_text())
                v = rec["violations"]
                rows.append(f"| {name} | {step} | {pushes} | {rec['runs']} | "
                            f"{rec['task_satisfied']} | {v.get('looping', 0)} | "
                            f"{rec['inconclusive']} | {rec['violating_runs']} | {in_model} | "
                            f"{rec['cuts_added']} | "
                            f"{rec['cuts_added'] / max(rec['runs'], 1):.3f} |")
                print(rows[-1], flush=True)
    (a.out / "handoff_side_by_side.md").write_text("\n".join(rows) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
