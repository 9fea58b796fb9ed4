"""The report of the scoop experiment: ``scoop.json``, ``scoop.md`` and ``scoop_success.png``.

:func:`write_report` writes the totals per policy variant of
:func:`tli_verify.experiments.scoop.run_all` as canonical JSON, a Markdown table (with the Fig. 7
text and picture when the search ran) and a bar chart of the success rates.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 and appendix "Multi-modal Experiments".
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from tli_verify.experiments.fig7 import FIG7_MIN_ROUNDS
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.plotting import save_figure
from tli_verify.runtime.setup import VARIANTS

__all__ = [
    "write_report",
]


def write_report(summary: Mapping[str, Any], out: Path, *, fig7: Mapping[str, Any] | None,
                 fig7_png: Path | None) -> list[Path]:
    """``scoop.json``, ``scoop.md`` and ``scoop_success.png`` under ``out`` (atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    cfg = summary["config"]
    tot = summary["totals"]
    lines = [
        "# Multi-modal soup-scooping experiment (paper Sec. 7.2, appendix \"Multi-modal "
        "Experiments\")", "",
        f"{cfg['experiments']} experiments (each: LPV-DS learned and certified at dt = 1/100 "
        f"from 1-3 seeded demonstrations of the scoop world), {cfg['episodes']} perturbed "
        f"episodes per experiment and variant, 1-{cfg['max_perturbations']} perturbations per "
        "episode in uniformly random directions with magnitudes uniform up to the workspace "
        f"size (16), step budget {cfg['steps']} (dt = 0.01 s), sensor lag {cfg['lag']}, "
        f"seed {cfg['seed']}. Wall time {summary['seconds']:.1f} s on {summary['workers']} "
        "worker(s).", "",
        "| variant | success | episodes | success % | per experiment (%) | Fig. 7 loops |",
        "|---|---:|---:|---:|---|---:|",
    ]
    for v in VARIANTS:
        t = tot[v]
        per = ", ".join(f"{p:.0f}" for p in t["per_experiment"])
        lines.append(f"| {v} | {t['success']} | {t['episodes']} | {t['percent']:.1f} | {per} "
                     f"| {t['loops']} |")
    lines += ["", "Variants: **LTL-DS** = task automaton + certified DS per mode + cuts "
              "learned online + replanning; **no-modulation** = the same without cuts; "
              "**no-replan** = the demonstrated mode sequence run open loop (cuts kept); "
              "**BC** = the paper's MLP per mode under the automaton (replanning, cuts). "
              f"**Fig. 7 loops**: episodes still looping a -> b -> a ... (>= {FIG7_MIN_ROUNDS} "
              "b -> a invariance failures) when the step budget ran out.", ""]
    if fig7 is not None:
        lines += ["## Fig. 7", "", fig7["text"], ""]
        if fig7_png is not None:
            lines += [f"![Fig. 7]({fig7_png.name})", ""]
    md = out / "scoop.md"
    js = out / "scoop.json"
    png = out / "scoop_success.png"
    atomic_write_text(md, "\n".join(lines) + "\n")
    atomic_write_text(js, canonical_json(dict(summary)))
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    vals = [tot[v]["percent"] for v in VARIANTS]
    ax.bar(VARIANTS, vals, color=["tab:blue", "tab:orange", "tab:green", "tab:red"])
    for i, v in enumerate(vals):
        ax.text(i, v + 1, f"{v:.0f}%", ha="center", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_ylabel("success %")
    ax.set_title("scoop: perturbed episodes reaching d", fontsize=9)
    fig.tight_layout()
    save_figure(fig, png, dpi=90)
    return [md, js, png]
