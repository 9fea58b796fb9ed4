"""Count the hostile inputs issue 31's tests try, per surface, and time the gate's re-run.

Usage::

    python -m benchmarks.hostile_inputs [--no-gate]

Runs the issue's test files with hypothesis statistics: a parametrized case is one input, a
hypothesis test counts the examples it actually ran (passing + failing; invalid ones are not
inputs and are left out); a loop inside one test (several commands on one input) counts once.
Each test is assigned to one surface by its name. Then ``tli gate`` on the repository (every
bundled model, default re-run) and ``tli gate --rerun 50`` per model in a one-model copy of
the project, timed. Prints Markdown tables.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FILES = ["tests/integration/test_hostile_api.py", "tests/integration/test_hostile_files.py",
         "tests/integration/test_hostile_plugin_cases.py", "tests/property/test_parser_depth.py",
         "tests/integration/test_gate_forged_task.py"]
SURFACES = [  # (surface, name patterns), first match wins
    ("gate", r"gate|rerun|settings|start_no_cli|forged|campaign_ran|physical_campaign"),
    ("plug-ins", r"plugin"),
    ("pytest plugin", r"case_files"),
    ("spec import", r"spec_import|foreign|chain_of_one|any_nesting|defines_predicates|"
                    r"pattern_that"),
    ("evidence", r"evidence"),
    ("demos", r"demos|learn_refuses"),
    ("init", r"init_"),
    ("task", r"task_check|path_component"),
    ("task files", r"task_file|task_formula|start_region|polytope|huge_shapes|gr1_spec|"
                   r"huge_integer"),
    ("Python API", r"api|public_call|library|cli_inherits|error_message"),
]


def surface(test: str) -> str:
    for name, pattern in SURFACES:
        if re.search(pattern, test):
            return name
    return "other"


def count_inputs() -> dict[str, dict[str, int]]:
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", *FILES, "-q", "-p", "no:randomly",
         "--hypothesis-show-statistics", "-m", "not slow"],
        cwd=REPO, capture_output=True, text=True, check=False)
    out = proc.stdout
    per: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    # hypothesis: "tests/...py::test_x:", then per phase "N passing, M failing, and K
    # invalid test cases" (the explicit and generate phases both count)
    current = None
    hyp_tests = set()
    for line in out.splitlines():
        m = re.match(r"^(tests/\S+::(test_\w+)):\s*$", line.strip())
        if m:
            current = m.group(2)
            hyp_tests.add(current)
            continue
        m = re.search(r"(\d+) passing, (\d+) failing", line)
        if m and current:
            per[surface(current)]["hypothesis examples"] += int(m.group(1)) + int(m.group(2))
    ids = subprocess.run([sys.executable, "-m", "pytest", *FILES, "--collect-only", "-q",
                          "-p", "no:randomly", "-m", "not slow"], cwd=REPO,
                         capture_output=True, text=True, check=False).stdout
    for line in ids.splitlines():
        m = re.match(r"^\S+::(test_\w+)(\[.*\])?$", line)
        if m and m.group(1) not in hyp_tests:
            per[surface(m.group(1))]["parametrized cases"] += 1
    summary = re.findall(r"(\d+ passed.*) in [\d.]+s", out)
    per["_run"]["passed"] = int(summary[-1].split()[0]) if summary else -1
    return per


def _project(models: list[str], root: Path) -> Path:
    for rel in ("tasks", "specs"):
        shutil.copytree(REPO / rel, root / rel)
    (root / "models").mkdir()
    (root / "certificates").mkdir()
    for m in models:
        shutil.copy(REPO / "models" / f"{m}.model.json", root / "models")
        for suffix in (".cert.json", ".campaign.json"):
            shutil.copy(REPO / "certificates" / f"{m}{suffix}", root / "certificates")
    return root


def time_gate(args: list[str], cwd: Path) -> tuple[float, int]:
    t0 = time.perf_counter()
    proc = subprocess.run([str(REPO / ".venv" / "bin" / "tli"), "gate", *args], cwd=cwd,
                          capture_output=True, text=True, check=False)
    return time.perf_counter() - t0, proc.returncode


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--no-gate", action="store_true")
    a = p.parse_args()
    per = count_inputs()
    print("| surface | parametrized cases | hypothesis examples | total |")
    print("|---|---|---|---|")
    total = 0
    for name, _ in SURFACES:
        c = per.get(name, {})
        n = c.get("parametrized cases", 0) + c.get("hypothesis examples", 0)
        total += n
        print(f"| {name} | {c.get('parametrized cases', 0)} | "
              f"{c.get('hypothesis examples', 0)} | {n} |")
    print(f"| **all** | | | **{total}** |")
    print(f"\n(tests passed: {per['_run']['passed']})\n")
    if a.no_gate:
        return
    secs, code = time_gate([], REPO)
    print(f"`tli gate` on the repository (all models, default re-run): {secs:.1f} s, "
          f"exit {code}\n")
    print("| model | `tli gate --rerun 50` (s) | exit |")
    print("|---|---|---|")
    for m in sorted(x.name[:-len(".model.json")] for x in (REPO / "models").glob("*.model.json")):
        with tempfile.TemporaryDirectory() as d:
            root = _project([m], Path(d) / "p")
            secs, code = time_gate([".", "--rerun", "50"], root)
            base, _ = time_gate([".", "--rerun", "1"], root)
        print(f"| {m} | {secs:.1f} (re-run alone ~{max(secs - base, 0):.1f}) | {code} |")


if __name__ == "__main__":
    main()
