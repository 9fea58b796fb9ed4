"""``tli experiment ...``: reproductions of the paper's experiments.

``tli experiment scoop`` runs the multi-modal soup-scooping experiment (paper Sec. 7.2 and
appendix "Multi-modal Experiments", Fig. 7): see :mod:`tli_verify.experiments.scoop`.

``tli experiment single-mode`` runs the single-mode study of paper Sec. 7.1 (Figs. 5-6): random
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

from tli_verify.commands import check_plan, float_range, int_range, output_path
from tli_verify.errors import TliError
from tli_verify.io import canonical_json
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_SEED, MAX_WORKERS

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
    s.add_argument("--trials", type=int_range(1, 100_000), default=None,
                   help="random modes (default 50; 3 with --quick)")
    s.add_argument("--seed", type=int_range(0, MAX_SEED), default=0,
                   help="master seed (default 0)")
    s.add_argument("--quick", action="store_true",
                   help=f"{QUICK_TRIALS} trials and a short BC training (under a minute)")
    s.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    s.add_argument("--out", type=output_path, default=Path("out/single-mode"),
                   help="output directory (default out/single-mode)")
    s.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=None,
                   help="worker processes (default: min(2, CPUs)); results do not depend on it")
    s.add_argument("--max-cuts", type=int_range(0, 10_000), default=20,
                   help="cap on cuts per policy and noise")
    s.add_argument("--cut-constraints", choices=("entries", "paper"), default="entries",
                   help="states a new cut keeps inside: every observed entry state (default) "
                   "or only the failure's own x^0 (appendix E.3 as written)")
    s.add_argument("--ds-eps", type=float_range(1e-9, 1e3), default=1e-3,
                   help="LPV-DS stability margin eps in A_k^T P + P A_k <= -eps I (default "
                   "1e-3; 1e-9 to 1e3)")
    s.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    s.set_defaults(handler=_single_mode)
    c = esub.add_parser(
        "scoop",
        help="multi-modal soup scooping (paper Sec. 7.2): LTL-DS / no modulation / no "
        "replanning / BC under random perturbations; Fig. 7",
        description="10 experiments, each an LPV-DS model learned and certified from 1-3 "
        "seeded demonstrations of the scoop world; >= 100 episodes per experiment and variant, "
        "1-3 perturbations each in uniformly random directions with magnitudes up to the "
        "workspace size. Writes scoop.json, scoop.md, scoop_success.png and fig7.png to --out.",
    )
    c.add_argument("--quick", action="store_true",
                   help="2 experiments x 20 episodes, short BC training, a short Fig. 7 search "
                   "(seconds)")
    c.add_argument("--seed", type=int_range(0, MAX_SEED), default=0,
                   help="master seed (default 0)")
    c.add_argument("--experiments", type=int_range(1, 1000), default=None,
                   help="default 10 (2 with --quick)")
    c.add_argument("--episodes", type=int_range(1, 100_000), default=None,
                   help="per experiment and variant (default 100; 20 with --quick)")
    c.add_argument("--lag", type=int_range(0, MAX_CAMPAIGN_STEPS), default=0,
                   help="sensor lag of the task (default 0)")
    c.add_argument("--steps", type=int_range(1, MAX_CAMPAIGN_STEPS), default=None,
                   help="step budget per episode at dt = 1/100 (default 3000; 2000 with --quick)")
    c.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=None,
                   help="worker processes (default: min(2, CPUs)); results do not depend on it")
    c.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    c.add_argument("--out", type=output_path, default=Path("out/scoop"),
                   help="output directory (default out/scoop)")
    c.set_defaults(handler=_scoop)


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
    from tli_verify.experiments.single_mode import run
    from tli_verify.experiments.single_mode_report import summarize, write_outputs

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


def _scoop_config(args: argparse.Namespace) -> Any:
    from tli_verify.experiments.scoop import ExperimentConfig

    q = args.quick
    exps = args.experiments if args.experiments is not None else (2 if q else 10)
    eps = args.episodes if args.episodes is not None else (20 if q else 100)
    steps = args.steps if args.steps is not None else 1
    for name, v, lo in (("--experiments", exps, 1), ("--episodes", eps, 1), ("--steps", steps, 1),
                        ("--seed", args.seed, 0), ("--lag", args.lag, 0)):
        if v < lo:
            raise TliError(f"{name} must be >= {lo}, got {v}")
    return ExperimentConfig(experiments=exps, episodes=eps, bc_epochs=60 if q else 300,
                            steps=args.steps if args.steps is not None else (2000 if q else 3000),
                            seed=args.seed, lag=args.lag)


def _scoop(args: argparse.Namespace) -> int:

    cfg = _scoop_config(args)
    workers = args.workers if args.workers is not None else min(2, os.cpu_count() or 1)
    if workers < 1:
        raise TliError(f"--workers must be >= 1, got {workers}")
    out: Path = args.out  # checked by tli_verify.cli.check_paths before this handler
    from tli_verify.project import open_project

    bundled = open_project(task="scoop", lag=cfg.lag)  # the scoop study's files: its inputs
    check_plan(inputs=bundled.files.inputs,
               outputs=[(out / n, n) for n in ("scoop.md", "scoop.json", "scoop_success.png",
                                               "fig7.png")])
    summary, files = scoop_study(cfg, out, workers=workers, fig7_tries=20 if args.quick else 200)
    if args.json:
        sys.stdout.write(canonical_json(summary))
    else:
        sys.stdout.write(_scoop_table(summary))
        sys.stdout.write("wrote " + ", ".join(str(f) for f in files) + "\n")
    return 0


def scoop_study(cfg: Any, out: Path, *, workers: int, fig7_tries: int
                ) -> tuple[dict[str, Any], list[Path]]:
    """Run the scoop experiment, write its report and figures; return the JSON summary."""
    from tli_verify.experiments.fig7 import fig7_record
    from tli_verify.experiments.fig7_plot import plot_fig7
    from tli_verify.experiments.scoop_report import write_report
    from tli_verify.experiments.scoop_task import scoop_setup

    summary = run_scoop(cfg, workers=workers, fig7_tries=fig7_tries)
    fig7 = summary.pop("fig7")
    png = None
    if fig7 is not None and fig7["found"] is not None:
        png = out / "fig7.png"
        plot_fig7(scoop_setup(lag=fig7["lag"]).task, fig7, png)
    summary["fig7"] = None if fig7 is None else fig7_record(fig7)
    files = write_report(summary, out, fig7=fig7, fig7_png=png)
    return summary, files + ([png] if png is not None else [])


def run_scoop(cfg: Any, *, workers: int, fig7_tries: int) -> dict[str, Any]:
    """:func:`tli_verify.experiments.scoop.run_all` (imported lazily)."""
    from tli_verify.experiments.scoop import run_all

    return run_all(cfg, workers=workers, fig7_tries=fig7_tries)


def _scoop_table(summary: dict[str, Any]) -> str:
    lines = [f"{'variant':<15}{'success':>10}{'episodes':>10}{'success %':>11}"]
    for v, t in summary["totals"].items():
        lines.append(f"{v:<15}{t['success']:>10}{t['episodes']:>10}{t['percent']:>10.1f}%")
    lines.append(f"wall time {summary['seconds']:.1f} s on {summary['workers']} worker(s)")
    if summary.get("fig7"):
        lines.append("Fig. 7: " + summary["fig7"]["text"])
    return "\n".join(lines) + "\n"


def demo_stage(out: Path) -> list[str]:
    """Run a quick single-mode study for ``make demo``; return one summary line per result."""
    from tli_verify.experiments.single_mode import SingleModeConfig, run
    from tli_verify.experiments.single_mode_report import summarize, write_outputs

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
