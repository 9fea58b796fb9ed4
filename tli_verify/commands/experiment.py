"""``tli experiment ...``: reproductions of the paper's experiments.

``tli experiment single-mode`` runs the single-mode study of paper Sec. 7.1 (Fig. 6-8): random
convex modes, BC / BC+mod / DS / DS+mod from noisy start states, cuts learned from invariance
failures. See :mod:`tli_verify.experiments.single_mode` and ``docs/boundary.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any, TextIO

from tli_verify.commands import output_path

QUICK_TRIALS = 3
QUICK_BC_EPOCHS = 300


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli experiment`` and its subcommands."""
    p = sub.add_parser("experiment", help="reproduce the paper's experiments")
    esub = p.add_subparsers(dest="experiment", metavar="EXPERIMENT", parser_class=type(p))
    p.set_defaults(handler=lambda args: _missing(p))
    s = esub.add_parser(
        "single-mode",
        help="single-mode study (paper Sec. 7.1): BC / BC+mod / DS / DS+mod vs. start noise",
        description="Random convex modes, 1-3 synthetic demonstrations each, 100 noisy starts "
        "per noise level (0/5/30% of the workspace); cuts learned from invariance failures. "
        "Writes single_mode.json, single_mode.md and PNG figures to --out.",
    )
    s.add_argument("--trials", type=int, default=None,
                   help="random modes (default 50; 3 with --quick)")
    s.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    s.add_argument("--quick", action="store_true",
                   help=f"{QUICK_TRIALS} trials and a short BC training (under a minute)")
    s.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    s.add_argument("--out", type=output_path, default=Path("out/single-mode"),
                   help="output directory (default out/single-mode)")
    s.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: min(2, CPUs)); results do not depend on it")
    s.add_argument("--max-cuts", type=int, default=20, help="cap on cuts per policy and noise")
    s.add_argument("--cut-constraints", choices=("entries", "paper"), default="entries",
                   help="states a new cut keeps inside: every observed entry state (default) "
                   "or only the failure's own x^0 (appendix F as written)")
    s.add_argument("--ds-eps", type=float, default=1e-3,
                   help="LPV-DS stability margin eps in A_k^T P + P A_k <= -eps I (default 1e-3)")
    s.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    s.set_defaults(handler=_single_mode)


def _missing(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


class _Progress:
    """A progress bar on stderr (one line per 10% when stderr is not a terminal)."""

    def __init__(self, stream: TextIO, label: str) -> None:
        self.stream = stream
        self.label = label
        self.start = time.perf_counter()
        self.tty = stream.isatty()
        self.last_decile = -1

    def __call__(self, done: int, total: int) -> None:
        elapsed = time.perf_counter() - self.start
        if self.tty:
            width = 30
            fill = int(width * done / max(total, 1))
            eta = elapsed / done * (total - done) if done else float("nan")
            self.stream.write(f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] "
                              f"{done}/{total} trials  {elapsed:5.0f}s"
                              + (f"  eta {eta:4.0f}s" if done else ""))
            if done == total:
                self.stream.write("\n")
        else:
            decile = int(10 * done / max(total, 1))
            if decile != self.last_decile or done == total:
                self.last_decile = decile
                self.stream.write(f"{self.label}: {done}/{total} trials, {elapsed:.0f}s\n")
        self.stream.flush()


def _config(args: argparse.Namespace) -> Any:
    from tli_verify.errors import TliError
    from tli_verify.experiments.single_mode import SingleModeConfig

    trials = args.trials if args.trials is not None else (QUICK_TRIALS if args.quick else 50)
    if trials < 1:
        raise TliError(f"--trials must be >= 1, got {trials}")
    if args.seed < 0:
        raise TliError(f"--seed must be >= 0, got {args.seed}")
    if args.max_cuts < 0:
        raise TliError(f"--max-cuts must be >= 0, got {args.max_cuts}")
    cfg = SingleModeConfig(
        trials=trials, seed=args.seed, max_cuts=args.max_cuts,
        cut_constraints=args.cut_constraints, ds_eps=args.ds_eps,
        bc_max_epochs=QUICK_BC_EPOCHS if args.quick else 5000,
    )
    cfg.validate()
    return cfg


def _single_mode(args: argparse.Namespace) -> int:
    from tli_verify.errors import TliError
    from tli_verify.experiments.single_mode import run, summarize, write_outputs
    from tli_verify.io import canonical_json

    cfg = _config(args)
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    if workers < 1:
        raise TliError(f"--workers must be >= 1, got {workers}")
    out: Path = args.out  # checked by tli_verify.cli.check_paths before this handler
    t0 = time.perf_counter()
    trials, record = run(cfg, workers=workers, progress=_Progress(sys.stderr, "single-mode"),
                         record_trial=None if args.no_figures else 0)
    summary = summarize(trials, cfg, seconds=time.perf_counter() - t0, workers=workers)
    files = write_outputs(summary, record, out, figures=not args.no_figures)
    if args.json:
        sys.stdout.write(canonical_json(summary))
    else:
        sys.stdout.write(_table(summary))
        sys.stdout.write("wrote " + ", ".join(str(f) for f in files) + "\n")
    return 0


def _table(summary: dict[str, Any]) -> str:
    noises = [str(p) for p in summary["config"]["noise_percent"]]
    lines = ["policy    " + "".join(f"{'noise ' + k + '%':>12}" for k in noises)]
    for p, row in summary["success"].items():
        lines.append(f"{p:<10}" + "".join(f"{100 * row[k]:>11.1f}%" for k in noises))
    cuts = summary["cuts"]["DS+mod"]
    lines.append("DS+mod cuts (mean/max): "
                 + ", ".join(f"{k}%: {cuts[k]['mean']:.1f}/{cuts[k]['max']:.0f}" for k in noises))
    return "\n".join(lines) + "\n"


def demo_stage(out: Path) -> list[str]:
    """Run a quick single-mode study for ``make demo``; return one summary line per result."""
    from tli_verify.experiments.single_mode import SingleModeConfig, run, summarize, write_outputs

    cfg = SingleModeConfig(trials=2, bc_max_epochs=QUICK_BC_EPOCHS)
    t0 = time.perf_counter()
    trials, record = run(cfg, workers=min(2, os.cpu_count() or 1))
    summary = summarize(trials, cfg, seconds=time.perf_counter() - t0,
                        workers=min(2, os.cpu_count() or 1))
    files = write_outputs(summary, record, out / "single-mode")
    s = summary["success"]
    row = " | ".join(f"{p} " + "/".join(f"{100 * s[p][k]:.0f}" for k in ("0", "5", "30"))
                     for p in s)
    return [f"single-mode study (2 quick trials, success % at noise 0/5/30): {row}",
            f"single-mode report: {files[1]}"]
