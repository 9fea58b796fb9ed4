"""The policy artifact's format: its text form, its content hash and its check.

Shared by the exporter (:mod:`tli_verify.deploy.export`, which writes artifacts) and the gate
(:mod:`tli_verify.deploy.gate`, which checks a deployed artifact against the project and the
campaign that tested it). The format itself is described in :mod:`tli_verify.deploy.export`
and ``docs/howto/deploy-to-robot.md``.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tli_verify.errors import ExportError, TliError, bad_input
from tli_verify.io import read_json, validate_schema
from tli_verify.runtime.stall import STALL_PARAMETERS, StallRule

__all__ = ["FORMAT", "MAX_C_BITS", "SCHEMA_VERSION", "TEXT_MAGIC", "check_artifact",
           "content_hash", "render_text", "text_path_for"]

FORMAT = "tli-policy"
"""The artifact's ``format`` field."""
SCHEMA_VERSION = 2
"""The artifact's ``schema_version`` (the C loader refuses any other). 2: the stall rule
(``stall``)."""
TEXT_MAGIC = "tli-policy-text"
"""First token of the text form."""
MAX_C_BITS = 64
"""Most sensors and most modes the C evaluator takes (one 64-bit mask each)."""


def text_path_for(json_path: str | os.PathLike[str]) -> Path:
    """``policy.tli.txt`` next to ``policy.tli.json`` (``.json`` replaced, else ``.txt``
    appended)."""
    p = Path(json_path)
    return p.with_suffix(".txt") if p.suffix == ".json" else p.with_name(p.name + ".txt")


def _hex(text: str) -> str:
    return text.encode("utf-8").hex() or "-"


def _mask(names: Sequence[str], order: Sequence[str]) -> int:
    index = {n: i for i, n in enumerate(order)}
    out = 0
    for n in names:
        out |= 1 << index[n]
    return out


def _nums(values: Any) -> str:
    return " ".join(repr(float(v)) for v in np.asarray(values, dtype=np.float64).ravel())


def render_text(art: dict[str, Any]) -> str:
    """The text form's body (no ``sha256`` line) of an artifact's content.

    Whitespace-separated tokens, one record per line; names hex-encoded UTF-8 (``-`` for the
    empty name); floats as Python's shortest round-trip ``repr`` (``strtod`` reads them back
    bit for bit); masks as unsigned decimal integers, bit ``i`` = ``inputs[i]`` (or
    ``modes[i]``). Layout: ``docs/howto/deploy-to-robot.md``.

    Raises
    ------
    KeyError, TypeError, ValueError
        On content that does not follow the schema (callers validate first).
    """
    aut = art["automaton"]
    inputs, modes = aut["inputs"], aut["modes"]
    mode_ix = {m: i for i, m in enumerate(modes)}
    keys = [d["key"] for d in art["ds"]]
    key_ix = {k: i for i, k in enumerate(keys)}
    n = int(art["dim"])
    total_k = sum(len(d["priors"]) for d in art["ds"])
    total_cuts = sum(len(d["cuts"]) for d in art["ds"])
    mod = art["modulation"]
    stall = art["stall"]
    dwell_steps = window = 0
    if stall is not None:  # the executive's own step counts
        rule = StallRule(**{k: float(stall[k]) for k in STALL_PARAMETERS})
        dwell_steps, window = rule.periods(float(art["dt"]))
    lines = [
        f"{TEXT_MAGIC} {int(art['schema_version'])}",
        f"name {_hex(art['name'])}",
        f"sizes {n} {len(inputs)} {len(modes)} {len(aut['states'])} {len(aut['initial'])} "
        f"{len(aut['edges'])} {len(keys)} {total_k} {total_cuts} {int(mod['max_online_cuts'])} "
        f"{window}",
        f"dt {float(art['dt'])!r}",
        "modulation " + _nums([mod["barrier_rate"], mod["degenerate_tol"],
                               mod["boundary_tol"], mod["guard_tol"]]),
    ]
    if stall is None:
        lines.append("stall 0")
    else:
        lines.append(f"stall 1 {_nums([stall['radius'], stall['progress']])} {dwell_steps} "
                     f"{window}")
    for what in ("spec", "model", "certificate", "task", "evidence"):
        src = art["sources"].get(what)
        lines.append(f"source {what} {src['sha256'] if src else '-'}")
    lines += [f"input {_hex(v)}" for v in inputs]
    lines.append(f"free {_mask(aut['free_inputs'], inputs)}")
    goal_set = set(aut["goal_modes"])
    for m in modes:
        lines.append(f"mode {_hex(m)} {_mask(aut['progress'].get(m, []), modes)} "
                     f"{int(m in goal_set)}")
    lines.append(f"goal_inputs {_mask(aut['goal_inputs'], inputs)}")
    for s in aut["states"]:
        planned = -1 if s["planned"] is None else mode_ix[s["planned"]]
        lines.append(f"state {int(s['id'])} {mode_ix[s['mode']]} {int(s['goal'])} "
                     f"{_mask(s['inputs'], inputs)} {key_ix[s['ds']]} {planned}")
    lines.append("initial " + " ".join(str(int(i)) for i in aut["initial"]))
    for e in aut["edges"]:
        lines.append(f"edge {int(e['from'])} {int(e['to'])} {_mask(e['on'], inputs)} "
                     f"{_mask(e['off'], inputs)}")
    for d in art["ds"]:
        k = len(d["priors"])
        nxt = -1 if d["next_mode"] is None else mode_ix.get(d["next_mode"], -1)
        lines.append(f"ds {_hex(d['key'])} {mode_ix[d['mode']]} {nxt} {k} {len(d['cuts'])}")
        lines.append(f"attractor {_nums(d['attractor'])}")
        lines.append(f"P {_nums(d['P'])}")
        lines.append(f"priors {_nums(d['priors'])}")
        lines.append(f"means {_nums(d['means'])}")
        lines.append(f"covs {_nums(d['covs'])}")
        lines.append(f"center {_nums(d['gmm']['center'])}")
        for q, lin, c in zip(d["gmm"]["quadratic"], d["gmm"]["linear"], d["gmm"]["constant"],
                             strict=True):
            lines.append(f"component {_nums([*q, *lin, c])}")
        lines.append(f"A {_nums(d['A'])}")
        lines.append(f"b {_nums(d['b'])}")
        for c in d["cuts"]:
            lines.append(f"cut {_nums([*c['normal'], *c['point']])}")
    if stall is not None:
        if len(stall["levels"]) != len(keys) or len(stall["reentry"]) != len(modes):
            raise ValueError(f"stall: {len(stall['levels'])} levels for {len(keys)} DS and "
                             f"{len(stall['reentry'])} re-entries for {len(modes)} modes")
        lines.append(f"levels {_nums(stall['levels'])}")
        lines.append("reentry " + " ".join(str(-1 if k is None else key_ix[k])
                                           for k in stall["reentry"]))
    lines.append("end")
    return "\n".join(lines) + "\n"


def content_hash(art: dict[str, Any]) -> str:
    """SHA-256 (hex) of the text form's body: the artifact's ``content_sha256``."""
    return hashlib.sha256(render_text(art).encode("utf-8")).hexdigest()


def check_artifact(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Load a JSON artifact and check it: schema and its own hash.

    Returns
    -------
    dict
        The artifact.

    Raises
    ------
    ExportError
        Unreadable, not the schema, or ``content_sha256`` is not the hash of its content
        (exit 2).
    """
    data = read_json(path, what="policy artifact", error=ExportError)
    if isinstance(data, dict) and data.get("format") == FORMAT:
        version = data.get("schema_version")
        if isinstance(version, int) and not isinstance(version, bool) and \
                version != SCHEMA_VERSION:
            raise bad_input(ExportError, f"{path}: a policy artifact of schema version "
                            f"{version}; this tli-verify reads version {SCHEMA_VERSION} "
                            "(re-export it with tli export)")
    validate_schema(data, "policy.schema.json", where=str(path), error=ExportError)
    body = {k: v for k, v in data.items() if k != "content_sha256"}
    try:
        digest = content_hash(body)
    except (KeyError, TypeError, ValueError, TliError) as exc:
        raise bad_input(ExportError, f"{path}: inconsistent artifact: {exc}") from None
    if digest != data["content_sha256"]:
        raise bad_input(ExportError, f"{path}: content_sha256 {data['content_sha256']} is not "
                        f"the hash of its content ({digest}): the file was edited")
    return dict(data)

