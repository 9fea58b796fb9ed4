"""The structured slugs and slugsin readers.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from tli_verify.errors import SpecError
from tli_verify.logic.foreign.naming import (
    _ap_name,
    _declare,
)
from tli_verify.logic.foreign.parse import (
    _Parser,
    _tokens,
)
from tli_verify.logic.foreign.tree import (
    ImportedSpec,
    Node,
    _Constraint,
    _fail,
    _Var,
)

__all__: list[str] = []

# --------------------------------------------------------------------------------------------
# slugs


_SECTIONS = {
    "[ENV_INIT]": ("assume", "init"), "[SYS_INIT]": ("guarantee", "init"),
    "[ENV_TRANS]": ("assume", "safety"), "[SYS_TRANS]": ("guarantee", "safety"),
    "[ENV_LIVENESS]": ("assume", "liveness"), "[SYS_LIVENESS]": ("guarantee", "liveness"),
}
_SLUGS_REFUSED_SECTIONS = ("[OBSERVABLE_INPUT]", "[UNOBSERVABLE_INPUT]",
                           "[CONTROLLABLE_INPUT]")


def _slugs_lines(text: str, where: str) -> Iterator[tuple[str, int, str | None]]:
    """``(line text, line number, section)`` of every non-empty, non-comment line."""
    section: str | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if (line.startswith("[") and line.endswith("]") and line.isupper()) or line in (
                "[INPUT]", "[OUTPUT]"):
            if line in _SLUGS_REFUSED_SECTIONS:
                raise _fail(where, number, f"section {line} (incomplete information) is not "
                            "supported")
            if line not in _SECTIONS and line not in ("[INPUT]", "[OUTPUT]"):
                raise _fail(where, number, f"unknown section {line}")
            section = line
            continue
        if section is None:
            raise _fail(where, number, "a line outside any section")
        yield line, number, section


def _slugs_var(spec: ImportedSpec, line: str, side: str, where: str, number: int,
               *, integers: bool) -> None:
    m = re.fullmatch(r"([A-Za-z_][A-Za-z0-9_]*)\s*(?::\s*(-?\d+)\s*\.\.\.\s*(-?\d+))?", line)
    if m is None or (m.group(2) is not None and not integers):
        raise _fail(where, number, f"bad variable declaration {line!r}")
    name = m.group(1)
    if m.group(2) is None:
        var = _Var(name=name, ap=_ap_name(name), side=side)
    else:
        var = _Var(name=name, ap=_ap_name(name), side=side, lo=int(m.group(2)),
                   hi=int(m.group(3)), boolean=False)
    _declare(spec, var, where, number)


def _parse_structuredslugs(text: str, where: str, default_name: str) -> ImportedSpec:
    spec = ImportedSpec(name=default_name, source=where, fmt="structuredslugs")
    for line, number, section in _slugs_lines(text, where):
        if section in ("[INPUT]", "[OUTPUT]"):
            _slugs_var(spec, line, "env" if section == "[INPUT]" else "sys", where, number,
                       integers=True)
            continue
        assert section is not None
        side, slot = _SECTIONS[section]
        body = None
        if line.split()[0] in ("|", "&", "^", "$", "!"):
            try:  # slugs' compiler passes lines that are slugsin prefix formulas through
                body = _prefix(line.split(), where, number)
            except SpecError:
                body = None
        if body is None:
            body = _Parser(_tokens(line, where, number), where=where, line=number,
                           dialect="structuredslugs", refuse={}).parse()
        if body[0] in ("G", "GF"):
            raise _fail(where, number, f"temporal operator {body[0]} inside a {section} "
                        "line: the section gives the slot (write the formula without it)")
        spec.constraints.append(_Constraint(side=side, slot=slot, body=body, line=number))
    return spec


def _parse_slugsin(text: str, where: str, default_name: str) -> ImportedSpec:
    spec = ImportedSpec(name=default_name, source=where, fmt="slugsin")
    for line, number, section in _slugs_lines(text, where):
        if section in ("[INPUT]", "[OUTPUT]"):
            _slugs_var(spec, line, "env" if section == "[INPUT]" else "sys", where, number,
                       integers=False)
            continue
        assert section is not None
        side, slot = _SECTIONS[section]
        body = _prefix(line.split(), where, number)
        spec.constraints.append(_Constraint(side=side, slot=slot, body=body, line=number))
    return spec


def _prefix(toks: list[str], where: str, number: int) -> Node:
    """A slugsin prefix formula (memory buffers ``$ n f0 .. f(n-1)`` and recalls ``? i``),
    without recursion. Recalled buffer entries stay shared: the tree refers to the same tuple,
    so the text is generated per occurrence but parsed once."""
    pos = 0

    def fail(msg: str) -> SpecError:
        return _fail(where, number, msg)

    # Explicit stack machine: frames are (op, collected children, needed, memory)
    memories: list[list[Node]] = []
    stack: list[list] = []
    result: Node | None = None
    while True:
        if pos >= len(toks):
            raise fail("premature end of line")
        tok = toks[pos]
        pos += 1
        node: Node | None = None
        if tok in ("!", "&", "|", "^"):
            stack.append([tok, [], 1 if tok == "!" else 2])
            continue
        if tok == "$":
            if pos >= len(toks) or not toks[pos].isdigit() or int(toks[pos]) == 0:
                raise fail("expected a positive number of memory elements after '$'")
            n = int(toks[pos])
            pos += 1
            memories.append([])
            stack.append(["$", [], n])
            continue
        if tok == "?":
            if pos >= len(toks) or not toks[pos].isdigit():
                raise fail("expected a number after '?'")
            k = int(toks[pos])
            pos += 1
            if not memories or k >= len(memories[-1]):
                raise fail(f"recall ? {k} of a memory element not stored (yet)")
            node = memories[-1][k]
        elif tok == "1":
            node = ("const", True)
        elif tok == "0":
            node = ("const", False)
        elif re.fullmatch(r"[A-Za-z_][A-Za-z0-9_@.]*'?", tok):
            primed = tok.endswith("'")
            node = ("id", tok.rstrip("'"), False)
            if primed:
                node = ("next", node)
        else:
            raise fail(f"unexpected token {tok!r}")
        while True:
            if not stack:
                result = node
                break
            frame = stack[-1]
            frame[1].append(node)
            if frame[0] == "$":
                memories[-1].append(node)
            if len(frame[1]) < frame[2]:
                break
            stack.pop()
            op, kids = frame[0], frame[1]
            if op == "$":
                memories.pop()
                node = kids[-1]
            elif op == "!":
                node = ("not", kids[0])
            else:
                node = ({"&": "and", "|": "or", "^": "xor"}[op], kids[0], kids[1])
        if result is not None:
            break
    if pos != len(toks):
        raise fail(f"stray tokens after the formula: {' '.join(toks[pos:pos + 3])!r}")
    return result
