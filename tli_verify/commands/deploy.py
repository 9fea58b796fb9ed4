"""Deployment commands: ``tli export`` (the certified policy as an artifact a controller runs).

``tli export PROJECT_OR_MODEL -o POLICY.tli.json`` gates the model's project
(:func:`tli_verify.deploy.gate.run_gate`; a blocked project is refused, exit 1, one line naming
the first blocker) and writes the artifact and its text form for the C evaluator
(:mod:`tli_verify.deploy.export`). Exit 0 prints the two paths and the content hash.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from tli_verify.commands import int_range, output_path
from tli_verify.errors import ExportError

__all__ = ["register"]


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register ``export``."""
    p = sub.add_parser(
        "export", help="write a gated policy as an artifact a C/C++ controller runs",
        description="Run the deployment gate on the model's project, then write the policy "
        "(task automaton, per-DS GMM, A_k, b_k, x*, P, cuts, modulation constants, control "
        "period, SHA-256 of spec, model, certificate, task and evidence) as POLICY.tli.json "
        "and its hash-bound text form POLICY.tli.txt for the C evaluator "
        "(tli_verify/deploy/c). A model the gate blocks is refused (exit 1).")
    p.add_argument("source", type=Path, metavar="PROJECT_OR_MODEL",
                   help="a project directory (with one model under models/, or name it with "
                   "--model) or a model file under a project's models/")
    p.add_argument("--model", default=None, metavar="NAME",
                   help="which model of the project (NAME or NAME.model.json under models/)")
    p.add_argument("-o", "--output", "--out", dest="output", type=output_path, required=True,
                   metavar="POLICY.tli.json", help="the artifact to write (the text form goes "
                   "next to it, .json replaced by .txt)")
    p.add_argument("--rerun", type=int_range(1, 100_000), default=None, metavar="N",
                   help="size of the gate's re-run per model: examples, or physical trials "
                   "for physical evidence (default: the gate's, 50 examples or 1 trial)")
    p.add_argument("--max-online-cuts", type=int_range(0, 63), default=16, metavar="N",
                   help="cuts the C evaluator may add per DS at run time (fixed storage; "
                   "default 16)")
    p.set_defaults(handler=_export)


def _model_of(source: Path, name: str | None) -> Path:
    """The model file a ``source`` argument names."""
    if source.is_file():
        if name is not None:
            raise ExportError(f"{source}: --model is for a project directory, not a model file")
        return source
    if not source.is_dir():
        raise ExportError(f"{source}: no such project directory or model file")
    models = source / "models"
    if name is not None:
        for cand in (models / name, models / f"{name}.model.json", models / f"{name}.json"):
            if cand.is_file():
                return cand
        raise ExportError(f"{source}: no model {name!r} under {models}/")
    found = sorted(models.glob("*.json")) if models.is_dir() else []
    if len(found) != 1:
        names = ", ".join(f.name for f in found) or "none"
        raise ExportError(f"{source}: name the model with --model ({len(found)} under "
                          f"{models}/: {names})")
    return found[0]


def _export(args: argparse.Namespace) -> int:
    from tli_verify.deploy.export import export_policy

    model = _model_of(args.source, args.model)
    out = export_policy(model, args.output, rerun=args.rerun,
                        max_online_cuts=args.max_online_cuts)
    checked = "loaded by the C evaluator" if out.c_loaded else \
        "not loaded in C here: no C compiler"
    sys.stdout.write(f"exported {model}: {out.json_path} and {out.text_path} "
                     f"(content sha256 {out.content_sha256}; {checked})\n")
    return 0
