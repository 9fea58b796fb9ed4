"""``tli verify`` (a bisimulation campaign) and ``tli replay`` (a saved counterexample).

Exit codes: ``tli verify`` 0 no violation, 1 a violation (or the certificate does not cover the
model), 2 bad arguments or files, 130 interrupted (a partial report is written first).
``tli replay`` 1 the expected violation reproduces, 0 it no longer does, 2 a bad case file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import DEFAULT_PATH, check_plan, chosen_path, int_range, output_path
from tli_verify.commands.run import add_task_arguments, open_args
from tli_verify.errors import TliError
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.limits import (
    MAX_BATCH_SIZE,
    MAX_CAMPAIGN_STEPS,
    MAX_EXAMPLES,
    MAX_PUSHES,
    MAX_SEED,
    MAX_WORKERS,
)
from tli_verify.testing.junit import write_junit
from tli_verify.verify.evidence import (
    evidence_path_for,
    weaker_than_recorded,
    write_campaign_evidence,
)

__all__ = ["register", "write_report"]


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``tli verify`` and ``tli replay``."""
    p = sub.add_parser(
        "verify", help="bisimulation campaign: generated perturbation sequences vs the oracle",
        description="Draw perturbation sequences with hypothesis (seeded), simulate them in "
        "batches on worker processes, check every run with the oracle (invariance, certified "
        "reachability deadline, automaton run, no looping), shrink the first counterexample "
        "and write a report (campaign.json, campaign.md, campaign.png, counterexample.json). "
        "Exit 0: no violation; 1: a violation.")

    add_task_arguments(p, what="campaign")
    p.add_argument("--examples", type=int_range(1, MAX_EXAMPLES), default=200,
                   help="cases (default 200)")
    p.add_argument("--seed", type=int_range(0, MAX_SEED), default=0, help="seed (default 0)")
    p.add_argument("--no-modulation", action="store_true",
                   help="the ablation without cuts (replanning only)")
    p.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=None,
                   help="worker processes (default: CPU count)")
    p.add_argument("--backend", choices=("process", "dask", "serial"), default="process")
    p.add_argument("--scheduler", default=None, metavar="ADDR",
                   help="Dask scheduler address (--backend dask; default: a LocalCluster)")
    p.add_argument("--batch-size", type=int_range(1, MAX_BATCH_SIZE), default=100,
                   help="runs per batch (default 100)")
    p.add_argument("--max-pushes", type=int_range(0, MAX_PUSHES), default=None,
                   help="perturbations per case, at most (default: the task's, else 3)")
    p.add_argument("--window", type=int_range(1, MAX_CAMPAIGN_STEPS), default=None,
                   help="perturbations happen in steps 1..WINDOW (default: the task's, else "
                   "700)")
    p.add_argument("--force", action="store_true",
                   help="with --evidence: replace evidence of a stronger campaign (more "
                   "examples, random starts, a longer window, more pushes or levels); "
                   "without it such evidence is kept and the command stops before any work")
    p.add_argument("--random-starts", action="store_true", default=None,
                   help="draw start states too (default: the task's first nominal start; a "
                   "task without one draws starts)")
    p.add_argument("--target", type=int_range(0, MAX_EXAMPLES), default=0, metavar="N",
                   help="when nothing is found, N more driver-side examples guided by "
                   "hypothesis.target on the robustness margin")
    p.add_argument("--no-shrink", action="store_true", help="do not shrink")
    p.add_argument("--json", action="store_true", help="print the campaign record as JSON")
    p.add_argument("--evidence", nargs="?", type=output_path, const=DEFAULT_PATH, default=None,
                   metavar="PATH",
                   help="also write campaign evidence for the deployment gate (default "
                   "certificates/<name>.campaign.json of the model's project)")
    p.add_argument("--out", type=output_path, default=Path("out/verify"),
                   help="report directory (default out/verify)")
    p.add_argument("--junit", type=output_path, default=None, metavar="FILE",
                   help="also write the campaign as JUnit XML (one testcase per run: a "
                   "violation is a failure naming the tli replay command of the "
                   "counterexample, an undecided run is skipped), for CI test reports")
    p.set_defaults(handler=_verify)

    r = sub.add_parser(
        "replay", help="replay a saved counterexample (CASE.json) deterministically",
        description="Exit 1: the case's violation reproduces; 0: it no longer does; 2: bad "
        "case file (checked against tli_verify/schemas/case.schema.json, then its files, "
        "their fit to the task and the limits, before anything runs).")
    r.add_argument("case", type=Path, help="a case file (tli verify's counterexample.json)")
    r.add_argument("--modulation", choices=("case", "on", "off"), default="case",
                   help="run as saved (default), or with modulation on/off")
    r.add_argument("--json", action="store_true")
    r.set_defaults(handler=_replay)


def _verify(args: argparse.Namespace) -> int:
    from tli_verify.verify.config import CampaignConfig

    if args.scheduler is not None and args.backend != "dask":
        raise TliError("--scheduler needs --backend dask")
    cfg = CampaignConfig(
        task=args.task, spec=str(args.spec) if args.spec else None,
        model=str(args.model) if args.model else None,
        certificate=str(args.certificate) if args.certificate else None,
        examples=args.examples, seed=args.seed, modulation=not args.no_modulation,
        workers=args.workers, backend=args.backend, scheduler=args.scheduler,
        batch_size=args.batch_size, max_pushes=args.max_pushes, window=args.window,
        random_starts=args.random_starts, lag=args.lag, shrink=not args.no_shrink,
        target_examples=args.target)
    session = open_args(args)  # before any work: the files, the task, their fit, read once
    filled = session.campaign_config(cfg)
    out: Path = args.out
    evidence = None
    if args.evidence is not None:
        evidence = chosen_path(args.evidence) or evidence_path_for(session.files.model)
        keep_stronger(evidence, filled, force=args.force)
    check_plan(inputs=session.files.inputs,
               outputs=[(out / "campaign.json", "campaign record"),
                        (out / "campaign.md", "campaign report"),
                        (out / "campaign.png", "campaign picture"),
                        (out / "counterexample.json", "counterexample case"),
                        (out / "counterexample.png", "counterexample picture"),
                        (evidence, "campaign evidence"),
                        (args.junit, "JUnit report")])
    progress = not args.json and sys.stderr.isatty()

    def note(text: str) -> None:
        if not args.json:
            sys.stderr.write(f"note: {text}\n")

    result = session.campaign(cfg, progress=progress, on_event=note)
    # a partial result never replaces a complete one: an interrupted campaign's report goes
    # to OUT/partial/, and it writes no evidence
    report_dir = out / "partial" if result.partial else out
    report_dir.mkdir(parents=True, exist_ok=True)
    record = result.to_dict()
    files = write_report(result, report_dir)
    record["report"] = [str(f) for f in files]
    if args.evidence is not None and not result.partial:

        target, _ = write_campaign_evidence(result.config, result, path=evidence)
        record["evidence"] = str(target)
    if args.junit is not None and not result.partial:

        ce_path = report_dir / "counterexample.json"
        record["junit"] = str(write_junit(
            result, args.junit,
            counterexample=ce_path if result.counterexample is not None else None))
    atomic_write_text(report_dir / "campaign.json", canonical_json(record))
    if args.json:
        sys.stdout.write(canonical_json(record))
    else:
        sys.stdout.write(_summary(result, [report_dir / "campaign.json", *files]))
        if "evidence" in record:
            sys.stdout.write(f"wrote evidence {record['evidence']}\n")
        if "junit" in record:
            sys.stdout.write(f"wrote JUnit report {record['junit']}\n")
    if result.partial:
        kept = (f"; no evidence written ({evidence} is unchanged)"
                if args.evidence is not None else "")
        if args.junit is not None:
            kept += f"; no JUnit report written ({args.junit} is unchanged)"
        sys.stderr.write(f"error: interrupted after {result.runs} of {cfg.examples} runs; "
                         f"partial report written to {report_dir / 'campaign.md'}{kept}\n")
        return 130
    return 1 if result.counterexample is not None else 0


def _summary(result: Any, files: list[Path]) -> str:
    c = result.config
    bad = {k: n for k, n in result.violations.items() if n}
    lines = [f"{result.task_name} ({'LTL-DS' if c.modulation else 'no modulation'}, seed "
             f"{c.seed}): "
             f"{result.runs} runs in {result.seconds:.1f} s, task satisfied in "
             f"{result.task_satisfied}, {result.cuts_added} cut(s) added"]
    if result.counterexample is None:
        bound = result.failure_bound
        lines.append("no violation found" + (f"; failure probability <= {bound:.3g} at 95% "
                                             "(3/N)" if bound is not None else ""))
    else:
        ce = result.counterexample
        pert = ", ".join(f"step {p['step']}: {p['level']} "
                         "(" + ", ".join(f"{v:.3g}" for v in p["displacement"]) + ")"
                         + (f" -> {p['target']}" if p["target"] else "")
                         for p in ce["perturbations"]) or "none"
        lines.append("violations: " + ", ".join(f"{k} {n}" for k, n in bad.items()))
        lines.append(f"first counterexample after {result.first_counterexample_at} "
                     f"simulation(s); {'shrunk' if ce['shrunk'] else 'not shrunk'} to "
                     f"{len(ce['perturbations'])} perturbation(s) [{pert}]: "
                     f"{ce['expected']['violation']} (modes "
                     f"{ce['expected']['oracle_modes'][:40]})")
    lines.append("wrote " + ", ".join(str(f) for f in files))
    return "\n".join(lines) + "\n"


def write_report(result: Any, out: Path) -> list[Path]:
    """``campaign.md``, ``campaign.png`` (outcomes per run, coverage) and, with a
    counterexample, ``counterexample.json`` + ``counterexample.png`` (Fig. 7 style: the
    counterexample's run, and the same case under LTL-DS when it was found without
    modulation). All written atomically."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from tli_verify.plotting import save_figure
    from tli_verify.verify.oracle import PRIORITY

    c = result.config
    files: list[Path] = []
    # --- the picture: outcomes per run + coverage
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10.0, 3.6),
                                   gridspec_kw={"width_ratios": [2.2, 1.0]})
    colors = {"ok": "tab:green", "invariance": "tab:orange", "repeated-exit": "tab:red",
              "reachability": "tab:purple", "automaton": "black", "looping": "tab:blue"}
    groups: dict[str, list[tuple[int, int]]] = {}
    for o in result.outcomes:
        k = o.verdict.primary.value if o.verdict.primary else "ok"
        groups.setdefault(k, []).append((o.index, o.steps))
    for k in ["ok", *[p.value for p in PRIORITY]]:
        pts = groups.get(k)
        if pts:
            a = np.array(pts)
            ax1.scatter(a[:, 0], a[:, 1], s=8, color=colors[k], label=f"{k} ({len(pts)})")
    ax1.set_yscale("log")
    ax1.set_xlabel("run (generation order)")
    ax1.set_ylabel("steps")
    ax1.set_title(f"outcomes per run: {result.runs} runs"
                  + (" (PARTIAL)" if result.partial else ""), fontsize=9)
    if groups:
        ax1.legend(fontsize=7, loc="best")
    else:  # interrupted before a run finished: nothing to label (and no matplotlib warning)
        ax1.text(0.5, 0.5, "no run finished", ha="center", va="center",
                 transform=ax1.transAxes, fontsize=9)
    cov = result.coverage
    names = ["automaton edges", "mode edges", "modes perturbed", "cut faces touched"]
    got = [cov["automaton_edges"]["exercised"], cov["mode_edges"]["exercised"],
           len(cov["modes_perturbed"]["perturbed"]), cov["cut_faces"]["touched"]]
    tot = [cov["automaton_edges"]["total"], cov["mode_edges"]["total"],
           len(cov["modes_perturbed"]["modes"]), cov["cut_faces"]["total"]]
    frac = [g / t if t else 0.0 for g, t in zip(got, tot, strict=True)]
    ax2.barh(names, frac, color="tab:blue")
    for i, (g, t) in enumerate(zip(got, tot, strict=True)):
        ax2.text(min(frac[i], 0.75) + 0.02, i, f"{g}/{t}", va="center", fontsize=8)
    ax2.set_xlim(0, 1.05)
    ax2.set_title("coverage", fontsize=9)
    ax2.tick_params(labelsize=7)
    fig.tight_layout()
    png = out / "campaign.png"
    save_figure(fig, png, dpi=90)
    files.append(png)
    # --- the counterexample
    ce = result.counterexample
    if ce is not None:
        cj = out / "counterexample.json"
        atomic_write_text(cj, canonical_json(ce))
        files.append(cj)
        try:
            files.append(_plot_case(result, cj, out / "counterexample.png"))
        except TliError as exc:  # a picture must not lose the campaign's results
            sys.stderr.write(f"note: counterexample picture not drawn ({exc})\n")
    # --- Markdown
    md = out / "campaign.md"
    lines = [f"# Bisimulation campaign: {result.task_name}"
             + (" (PARTIAL: interrupted)" if result.partial else ""), "",
             f"{result.runs} of {c.examples} runs, seed {c.seed}, "
             f"{'LTL-DS (modulation on)' if c.modulation else 'without modulation'}, "
             f"up to {c.max_pushes} perturbations in steps 1..{c.window} (levels "
             f"{', '.join(c.levels)}), backend {c.backend}; {result.seconds:.1f} s.", "",
             "| check | runs violating |", "|---|---:|"]
    lines += [f"| {k} | {n} |" for k, n in result.violations.items()]
    lines += ["", f"Task satisfied in {result.task_satisfied} of {result.runs} runs; "
              f"{result.cuts_added} cut(s) added; {result.inconclusive} run(s) with "
              "reachability undecided (ended early).", ""]
    beyond = sum(1 for o in result.outcomes if o.verdict.beyond_workspace)
    if beyond:
        lines += [f"**{beyond} run(s) left the workspace box** (a bound of the task: joint "
                  "limits in a joint-space task); the pictures show the box, not beyond it.",
                  ""]
    lines += _cuts_table(result)
    cov = result.coverage
    lines += ["## Coverage", "",
              f"- automaton edges exercised: {cov['automaton_edges']['exercised']} of "
              f"{cov['automaton_edges']['total']}",
              f"- mode edges: {cov['mode_edges']['exercised']} of "
              f"{cov['mode_edges']['total']} ({', '.join(cov['mode_edges']['list'])})",
              f"- modes perturbed: {', '.join(cov['modes_perturbed']['perturbed']) or 'none'}"
              f" (of {', '.join(cov['modes_perturbed']['modes'])})",
              f"- cut faces touched: {cov['cut_faces']['touched']} of "
              f"{cov['cut_faces']['total']}", "", "![campaign](campaign.png)", ""]
    lines += ["## Counterexample", ""]
    if ce is None:
        lines.append("None found" + (f": the failure probability is at most "
                                     f"{result.failure_bound:.3g} at 95 % confidence (3/N)."
                                     if result.failure_bound is not None else "."))
    else:
        lines += [f"First found after {result.first_counterexample_at} simulation(s) "
                  f"(generation order); {'shrunk' if ce['shrunk'] else 'not shrunk'} "
                  f"({result.shrink_steps} shrinking simulations). Violation: "
                  f"**{ce['expected']['violation']}**; oracle modes "
                  f"`{ce['expected']['oracle_modes'][:60]}`.", "",
                  f"Start {ce['start']}; perturbations:", ""]
        lines += [f"- step {p['step']}: {p['level']} displacement {p['displacement']}"
                  + (f" into {p['target']}" if p["target"] else "")
                  for p in ce["perturbations"]] or ["- none"]
        lines += ["", *[f"> {m}" for m in ce["expected"]["messages"]], "",
                  "Replay: `tli replay counterexample.json`.", "",
                  "![counterexample](counterexample.png)", ""]
    if result.events:
        lines += ["## Events", "", *[f"- {e}" for e in result.events], ""]
    atomic_write_text(md, "\n".join(lines) + "\n")
    files.insert(0, md)
    return files


def _cuts_table(result: Any) -> list[str]:
    """campaign.md's "Cuts per mode": the model's cuts (offline, with its hand-off claim) and
    the cuts the runs learned online."""
    from tli_verify.model.serialize import load_model

    online = result.cuts_by_mode()
    path = result.files.get("model", {}).get("path")
    claims: dict[str, dict[str, Any]] = {}
    model_cuts: dict[str, int] = {}
    if path:
        try:
            model = load_model(path)
        except TliError:
            model = None
        if model is not None:
            for mode in sorted({mm.mode for mm in model.modes.values()}):
                model_cuts[mode] = len(model.region_cuts(mode))
            rec = (model.source or {}).get("handoff") or {}
            for c in rec.get("claims", []) if isinstance(rec, dict) else []:
                if isinstance(c, dict) and "mode" in c:
                    claims.setdefault(str(c["mode"]), c)
    modes = sorted(set(model_cuts) | set(online))
    if not modes:
        return []
    out = ["## Cuts per mode", "",
           "| mode | cuts in the model | hand-off | cuts learned online | runs cutting | most "
           "in one run |", "|---|---:|---|---:|---:|---:|"]
    for m in modes:
        c = claims.get(m)
        how = "online only" if c is None else (
            "proved" if c.get("established") == "proved" else
            f"sampled ({c.get('samples')} states, {c.get('exits')} exits)")
        o = online.get(m, {"total": 0, "runs": 0, "max_per_run": 0})
        out.append(f"| {m} | {model_cuts.get(m, 0)} | {how} | {int(o['total'])} | "
                   f"{int(o['runs'])} | {int(o['max_per_run'])} |")
    return [*out, ""]


def _plot_case(result: Any, case_path: Path, png: Path) -> Path:
    from dataclasses import replace

    from tli_verify.verify.cases import read_case
    from tli_verify.verify.simulate import load, simulate
    from tli_verify.viz.episodes import plot_episodes

    _, spec, case = read_case(case_path)
    ld = load(spec)
    (_, res), = simulate(spec, [case])
    panels = [("no modulation" if not spec.modulation else "LTL-DS", res)]
    if not spec.modulation:
        (_, fixed), = simulate(replace(spec, modulation=True), [case])
        panels.append(("same case, LTL-DS", fixed))
    (_, nominal), = simulate(spec, [replace(case, pushes=())])
    plot_episodes(ld.task, panels, png, nominal=nominal,
                  title=f"counterexample ({case_path.name}): "
                        f"{'LTL-DS' if spec.modulation else 'no modulation'}"
                        + (" (left) vs LTL-DS (right)" if len(panels) > 1 else ""))
    return png


def _replay(args: argparse.Namespace) -> int:
    from tli_verify.verify.cases import replay_case

    mod = None if args.modulation == "case" else args.modulation == "on"
    # a bad case file is one error line (exit 2) before anything runs (read_case: the schema,
    # the limits, the files and their fit to the task)
    doc, verdict, reproduced, notes = replay_case(args.case, modulation=mod)
    for n in notes:
        sys.stderr.write(f"note: {n}\n")
    want = doc["expected"]["violation"]  # validated: a violation kind
    kinds = sorted(k.value for k in verdict.kinds)
    record = {"case": str(args.case), "expected": want, "reproduced": reproduced,
              "violations": kinds,
              "messages": [v.message for v in verdict.violations][:5],
              "diagnosis": verdict.diagnosis,
              "oracle_modes": verdict.oracle_modes[:200], "files_changed": notes}
    if args.json:
        sys.stdout.write(canonical_json(record))
    else:
        sys.stdout.write(
            f"{args.case}: expected {want}: "
            + ("REPRODUCED" if reproduced else "does not reproduce")
            + f" (violations now: {', '.join(kinds) or 'none'}; modes "
            f"{verdict.oracle_modes[:40]})\n")
        if verdict.diagnosis:
            sys.stdout.write(f"{verdict.diagnosis}\n")
    return 1 if reproduced else 0


def keep_stronger(path: Path, config: Any, *, force: bool) -> None:
    """Refuse (exit 2, before any work) to replace the evidence of a stronger campaign, unless
    ``force``; with ``force``, say on stderr what is being replaced.

    Raises
    ------
    TliError
        The evidence at ``path`` records a stronger campaign than ``config``'s.
    """
    why = weaker_than_recorded(path, config)
    if why is None:
        return
    if not force:
        raise TliError(f"{path}: holds evidence of a stronger campaign ({why}): not replaced; "
                       "--force replaces it")
    sys.stderr.write(f"note: {path}: replacing evidence of a stronger campaign ({why}) "
                     "(--force)\n")
