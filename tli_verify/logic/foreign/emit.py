"""Writing our TOML spec text from an imported spec.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

from tli_verify.logic.foreign.expand import (
    _has,
)
from tli_verify.logic.foreign.tree import (
    ImportedSpec,
    Node,
    _Constraint,
    _Var,
)

__all__: list[str] = []


def _primed_justice(spec: ImportedSpec) -> None:
    """A liveness goal that reads next values, ``GF phi(v, v')`` (a goal over steps, as
    Spectra and slugs allow), becomes ``GF j`` with a fresh system variable ``j``: false at
    time 0, then ``j' <-> phi`` (spectra-synt ``PrimesInJusticeTranslator``)."""
    for k, c in enumerate(list(spec.constraints)):
        if c.slot != "liveness" or not _has(c.body, "next"):
            continue
        taken = {b for v in spec.variables for b in v.bits()}
        n = 0
        while f"primed_justice_{n}" in taken:
            n += 1
        j = _Var(name=f"PRIMED_JUSTICE_{n}", ap=f"primed_justice_{n}", side="sys")
        spec.variables.append(j)
        ref: Node = ("id", j.name, False)
        spec.constraints[k] = _Constraint(c.side, "liveness", ref, c.line, c.where)
        spec.constraints += [
            _Constraint("guarantee", "init", ("not", ref), c.line, c.where),
            _Constraint("guarantee", "safety", ("iff", ("next", ref), c.body), c.line, c.where)]


def _toml_str(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    return f'"{out}"'


def _toml(spec: ImportedSpec, sections: Mapping[tuple[str, str], list[tuple[int | None, str]]],
          semantics: str | None) -> str:
    src = Path(spec.source).name
    name = re.sub(r"[\x00-\x1f\x7f]", "", spec.name) or "imported"
    lines = [f"# Imported from {src} ({spec.fmt}) by tli spec import.",
             f"name = {_toml_str(name)}",
             f"description = {_toml_str(f'imported from {src} ({spec.fmt})')}"]
    if semantics is not None:
        lines.append(f"semantics = {_toml_str(semantics)}")
    for var in spec.variables:
        if var.boolean and var.ap == var.name:
            continue
        if var.boolean:
            lines.append(f"# {var.side} {var.name}: boolean, AP {var.ap}")
            continue
        kind = ("{" + ", ".join(var.values) + "}") if var.values else f"{var.lo}..{var.hi}"
        lines.append(f"# {var.side} {var.name}: {kind}, bits {', '.join(var.bits())} "
                     f"(value - {var.lo}, least significant first)")
    lines.append(f"inputs = [{', '.join(_toml_str(b) for b in spec.inputs())}]")
    lines.append(f"outputs = [{', '.join(_toml_str(b) for b in spec.outputs())}]")
    for side in ("assume", "guarantee"):
        lines += ["", f"[{side}]"]
        for slot in ("init", "safety", "liveness"):
            items = sections.get((side, slot), [])
            if not items:
                continue
            lines.append(f"{slot} = [")
            for line, text in items:
                origin = f"{src}:{line}" if line is not None else "domain constraint"
                lines.append(f"  # {origin}")
                lines.append(f"  {_toml_str(text)},")
            lines.append("]")
    return "\n".join(lines) + "\n"
