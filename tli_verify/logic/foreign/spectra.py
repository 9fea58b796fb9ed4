"""The Spectra reader: statements, types, variables, defines, predicates, patterns, monitors,
counters.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.io import read_text
from tli_verify.limits import (
    MAX_IMPORT_CELLS,
)
from tli_verify.logic.foreign.naming import (
    _ap_name,
    _ap_stem,
    _declare,
)
from tli_verify.logic.foreign.parse import (
    _Parser,
    _tokens,
)
from tli_verify.logic.foreign.translate import (
    _ARITH_OPS,
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
# Spectra


_SCAN_REFUSED = frozenset({"trig", "regexp", "weight", "regtest", "GE", "GEF"})
"""Words that refuse a statement wherever they occur in it."""

_SPECTRA_REFUSED = {
    "trig": "Spectra triggers (regular-expression constraints) are not supported",
    "regexp": "Spectra regular expressions are not supported",
    "regtest": "Spectra regular-expression tests (regtest) are not supported",
    "weight": "Spectra weights (energy games) are not supported: not GR(1)",
    "GE": "Spectra existential guarantees (GE) are not supported: not GR(1)",
    "GEF": "Spectra existential guarantees (GEF) are not supported: not GR(1)",
    "keep": "Spectra 'keep' is not supported",
}

_OWNERS = {"env": "env", "input": "env", "in": "env", "envvar": "env",
           "sys": "sys", "output": "sys", "out": "sys", "sysvar": "sys",
           "aux": "sys", "auxvar": "sys"}
"""Spectra variable owners. Auxiliary variables belong to the system: Spectra's game puts
the ``aux`` player's variables and constraints into the system module (spectra-synt,
``BDDGenerator.generateGameModel``)."""

_SLOT_WORDS = {"ini": "init", "initially": "init", "G": "safety", "trans": "safety",
               "alw": "stateinv", "always": "stateinv", "GF": "liveness", "alwEv": "liveness",
               "alwaysEventually": "liveness"}
_ARRAY_FUNCS = ("all", "any", "sum", "prod")


def _strip_spectra_comments(text: str, where: str) -> str:
    """Drop ``//``, ``--`` line comments and ``/* */`` block comments, keeping line breaks
    (and strings: only ``import`` takes one)."""
    out, i, n = [], 0, len(text)
    while i < n:
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            if j < 0:
                raise _fail(where, text.count("\n", 0, i) + 1, "unterminated /* comment")
            out.append("\n" * text.count("\n", i, j))
            i = j + 2
        elif text.startswith("//", i) or (text.startswith("--", i)
                                          and not text.startswith("-->", i)):
            j = text.find("\n", i)
            i = n if j < 0 else j
        elif text[i] == '"':
            j = text.find('"', i + 1)
            if j < 0 or "\n" in text[i:j]:
                raise _fail(where, text.count("\n", 0, i) + 1, "unterminated string")
            out.append(text[i:j + 1])
            i = j + 1
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


def _is_block_head(text: str) -> bool:
    text = text.strip()
    return bool(re.match(r"^(pattern|monitor|counter)\b", text)
                or re.match(r"^predicate\s+\w+\s*(\(.*\))?\s*$", text, re.S))


def _statements(text: str) -> Iterator[tuple[str, int]]:
    """``;``-terminated statements, ``{...}`` blocks (patterns, monitors, counters,
    predicates) and the ``module``/``define``/``import`` header lines, with their line."""
    buf: list[str] = []
    start_line = line = 1
    depth = 0
    block = False
    for ch in text:
        if not buf and ch.isspace():
            if ch == "\n":
                line += 1
            continue
        if not buf:
            start_line = line
        if ch == "\n":
            line += 1
            stripped = "".join(buf).strip()
            if depth == 0 and (re.match(r"^(module|spec)\s+\w+$", stripped)
                               or stripped == "define"
                               or re.match(r'^import\s*"[^"]*"$', stripped)):
                yield stripped, start_line
                buf = []
                continue
        if ch == "{":
            if depth == 0:
                block = _is_block_head("".join(buf))
            depth += 1
        elif ch == "}" and depth > 0:
            depth -= 1
            if depth == 0 and block:
                buf.append(ch)
                yield "".join(buf).strip(), start_line
                buf, block = [], False
                continue
        if ch == ";" and depth == 0:
            yield "".join(buf).strip(), start_line
            buf = []
            continue
        buf.append(ch)
    rest = "".join(buf).strip()
    if rest:
        yield rest, start_line


def _block_body(stmt: str, line: int) -> tuple[list[str], Iterator[tuple[str, int]]]:
    """The header tokens' text and the inner statements (with their lines) of a block."""
    k = stmt.index("{")
    base = line + stmt.count("\n", 0, k)
    inner = stmt[k + 1:stmt.rindex("}")]
    return [stmt[:k]], ((s, base + n - 1) for s, n in _statements(inner) if s)


@dataclass(slots=True)
class _Pattern:
    name: str
    params: tuple[str, ...]
    variables: list[tuple[list[str], str]]  # (type tokens, name)
    constraints: list[tuple[str, Node, int]]  # (slot, body, line)
    where: str


@dataclass(slots=True)
class _Predicate:
    name: str
    params: tuple[str, ...]
    body: Node
    line: int
    where: str


@dataclass(slots=True)
class _SpectraModule:
    spec: ImportedSpec
    where: str
    defines: dict[str, tuple[Any, int, str]] = field(default_factory=dict)
    types: dict[str, tuple[list[str], int, str]] = field(default_factory=dict)
    predicates: dict[str, _Predicate] = field(default_factory=dict)
    patterns: dict[str, _Pattern] = field(default_factory=dict)
    arrays: dict[str, tuple[int, ...]] = field(default_factory=dict)
    constraints: list[_Constraint] = field(default_factory=list)
    imported: set[Path] = field(default_factory=set)
    missing: list[str] = field(default_factory=list)  # imports not found


def _spectra_parser(toks: list[str], where: str, line: int) -> _Parser:
    return _Parser(toks, where=where, line=line, dialect="spectra", refuse=_SPECTRA_REFUSED)


def _parse_spectra(text: str, where: str, default_name: str,
                   base: Path | None = None) -> _SpectraModule:
    mod = _SpectraModule(spec=ImportedSpec(name=default_name, source=where, fmt="spectra"),
                         where=where)
    _read_spectra(mod, text, where, base, library=False)
    return mod


def _read_spectra(mod: _SpectraModule, text: str, where: str, base: Path | None, *,
                  library: bool) -> None:
    """Read one Spectra file into ``mod``; a ``library`` (an import) gives its definitions
    only (types, defines, predicates, patterns), as Spectra's cross-references do."""
    statements = list(_statements(_strip_spectra_comments(text, where)))
    for stmt, line in statements:  # type aliases first: they may follow their first use
        if not re.match(r"^type\b", stmt):
            continue
        toks = _tokens(stmt, where, line)
        if len(toks) < 4 or toks[2] != "=" or not re.match(r"^[A-Za-z_]\w*$", toks[1]):
            raise _fail(where, line, "expected type NAME = boolean | Int(lo..hi) | {A, ...}")
        if toks[1] in mod.types and not library and mod.types[toks[1]][0] != toks[3:]:
            raise _fail(where, line, f"type {toks[1]!r} declared twice, differently")
        mod.types.setdefault(toks[1], (toks[3:], line, where))
    in_define = False
    for stmt, line in statements:
        m = re.match(r'^import\s*"([^"]*)"$', stmt)
        if m:
            _spectra_import(mod, m.group(1), where, line, base)
            continue
        head_word = re.match(r"^\s*(\w+)", stmt)
        head_word_s = head_word.group(1) if head_word else ""
        if head_word_s in ("pattern", "predicate", "monitor", "counter"):
            in_define = False
            if head_word_s == "pattern":
                _spectra_pattern(mod, stmt, where, line)
            elif head_word_s == "predicate":
                _spectra_predicate(mod, stmt, where, line)
            elif library:
                pass
            elif head_word_s == "monitor":
                _spectra_monitor(mod, stmt, where, line)
            else:
                _spectra_counter(mod, stmt, where, line)
            continue
        for word in re.findall(r"[A-Za-z_]\w*", stmt):
            if word in _SCAN_REFUSED:
                raise _fail(where, line, _SPECTRA_REFUSED[word])
        toks = _tokens(stmt, where, line)
        if not toks:
            continue
        head = toks[0]
        if head in ("module", "spec"):
            if len(toks) < 2:
                raise _fail(where, line, f"{head} needs a name")
            if not library:
                mod.spec.name = toks[1]
            in_define = False
            if len(toks) > 2:
                toks = toks[2:]
                head = toks[0]
            else:
                continue
        if head == "define":
            in_define = True
            toks = toks[1:]
            if not toks:
                continue
            head = toks[0]
        if head == "type":
            in_define = False
            continue
        if head in _SPECTRA_REFUSED:
            raise _fail(where, line, _SPECTRA_REFUSED[head])
        if head in _OWNERS:
            in_define = False
            if not library:
                _spectra_var(mod, toks, where, line)
            continue
        if head in ("asm", "assumption", "gar", "guarantee"):
            in_define = False
            if not library:
                mod.constraints.append(_spectra_constraint(toks, where, line))
            continue
        if in_define and len(toks) >= 2 and toks[1] in (":=", "["):
            _spectra_define(mod, toks, where, line)
            continue
        if in_define and len(toks) >= 2 and toks[1] == "(":
            raise _fail(where, line, f"define {toks[0]!r} with parameters is not supported")
        raise _fail(where, line, f"unsupported Spectra statement starting with {head!r}")


def _spectra_import(mod: _SpectraModule, name: str, where: str, line: int,
                    base: Path | None) -> None:
    if base is None:
        return  # no folder to look in: a pattern or predicate used is refused where used
    path = (base / name).resolve()
    if not path.is_file():
        mod.missing.append(name)
        return
    if path in mod.imported:
        return
    mod.imported.add(path)
    text = read_text(path, what="Spectra import", error=SpecError)
    _read_spectra(mod, text, str(path), path.parent, library=True)


def _spectra_define(mod: _SpectraModule, toks: list[str], where: str, line: int) -> None:
    name = toks[0]
    if name in mod.defines:
        raise _fail(where, line, f"define {name!r} twice")
    k = toks.index(":=") if ":=" in toks else -1
    if k < 0:
        raise _fail(where, line, f"define {name!r}: expected ':='")
    if toks[1] == "[":  # an array of expressions: name[n]... := {e, ...}
        value: object = _define_array(toks[k + 1:], where, line)
    else:
        value = _spectra_parser(toks[2:], where, line).parse()
    mod.defines[name] = (value, line, where)


def _define_array(toks: list[str], where: str, line: int) -> tuple[Any, ...]:
    pos = 0

    def items() -> tuple[Any, ...]:
        nonlocal pos
        if toks[pos] != "{":
            raise _fail(where, line, "expected '{' in a define array")
        pos += 1
        out: list[object] = []
        while True:
            if toks[pos] == "{":
                out.append(("array", items()))
            else:
                start, depth = pos, 0
                while depth > 0 or toks[pos] not in (",", "}"):
                    depth += toks[pos] in ("(", "{", "[")
                    depth -= toks[pos] in (")", "}", "]")
                    pos += 1
                out.append(_spectra_parser(toks[start:pos], where, line).parse())
            tok = toks[pos]
            pos += 1
            if tok == "}":
                return tuple(out)
            if tok != ",":
                raise _fail(where, line, "expected ',' or '}' in a define array")

    try:
        value = ("array", items())
    except IndexError:
        raise _fail(where, line, "unterminated define array") from None
    if pos != len(toks):
        raise _fail(where, line, "unexpected tokens after a define array")
    return value


def _param_names(toks: list[str], where: str, line: int) -> tuple[str, ...]:
    """The names of a parameter list's entries (``[type] name``, comma-separated)."""
    names: list[str] = []
    depth = 0
    cur: list[str] = []
    for tok in [*toks, ","]:
        if tok == "," and depth == 0:
            if not cur or not re.match(r"^[A-Za-z_]\w*$", cur[-1]):
                raise _fail(where, line, "expected a parameter name")
            names.append(cur[-1])
            cur = []
            continue
        depth += tok in ("(", "{", "[")
        depth -= tok in (")", "}", "]")
        cur.append(tok)
    return tuple(names)


def _closing(toks: list[str], k: int) -> int:
    """Index of the ``)`` matching the ``(`` at ``toks[k]`` (``len(toks)`` if unclosed)."""
    depth = 0
    while k < len(toks):
        depth += toks[k] == "("
        depth -= toks[k] == ")"
        if depth == 0:
            break
        k += 1
    return k


def _header_params(toks: list[str], where: str, line: int) -> tuple[tuple[str, ...], int]:
    """Parameters of ``name(...)`` starting at ``toks[2]``, and the index after them."""
    if len(toks) < 3 or toks[2] != "(":
        return (), 2
    k = _closing(toks, 2)
    inner = toks[3:k]
    return (_param_names(inner, where, line) if inner else ()), k + 1


def _spectra_predicate(mod: _SpectraModule, stmt: str, where: str, line: int) -> None:
    toks = _tokens(stmt, where, line)
    if len(toks) < 3 or not re.match(r"^[A-Za-z_]\w*$", toks[1]):
        raise _fail(where, line, "expected predicate NAME(params): body;")
    params, k = _header_params(toks, where, line)
    rest = toks[k:]
    if rest and rest[0] == ":":
        body_toks = rest[1:]
    elif rest and rest[0] == "{" and rest[-1] == "}":
        body_toks = rest[1:-1]
    else:
        raise _fail(where, line, f"predicate {toks[1]!r}: expected ':' or '{{' after the "
                    "parameters")
    body = _spectra_parser(body_toks, where, line).parse()
    mod.predicates.setdefault(toks[1], _Predicate(toks[1], params, body, line, where))


def _spectra_pattern(mod: _SpectraModule, stmt: str, where: str, line: int) -> None:
    (head,), inner = _block_body(stmt, line)
    toks = _tokens(head, where, line)
    if len(toks) < 2 or not re.match(r"^[A-Za-z_]\w*$", toks[1]):
        raise _fail(where, line, "expected pattern NAME(params) { ... }")
    params, _ = _header_params(toks, where, line)
    pat = _Pattern(toks[1], params, [], [], where)
    for s, n in inner:
        t = _tokens(s, where, n)
        if t[0] == "var":
            if len(t) < 3:
                raise _fail(where, n, "expected var TYPE NAME")
            pat.variables.append((t[1:-1], t[-1]))
            continue
        slot, body = _slot_and_body(t, where, n, default="init")
        pat.constraints.append((slot, body, n))
    mod.patterns.setdefault(pat.name, pat)


def _spectra_monitor(mod: _SpectraModule, stmt: str, where: str, line: int) -> None:
    """A monitor: an auxiliary (system) variable whose ini/safety constraints are added as
    guarantees (spectra-synt ``MonitorTranslator``)."""
    (head,), inner = _block_body(stmt, line)
    toks = _tokens(head, where, line)
    if len(toks) < 3:
        raise _fail(where, line, "expected monitor TYPE NAME { ... }")
    _spectra_var(mod, ["aux", *toks[1:]], where, line)
    for s, n in inner:
        slot, body = _slot_and_body(_tokens(s, where, n), where, n, default="init")
        if slot == "liveness":
            raise _fail(where, n, "a liveness goal inside a monitor")
        mod.constraints.append(_Constraint("guarantee", slot, body, n))


def _spectra_counter(mod: _SpectraModule, stmt: str, where: str, line: int) -> None:
    """A counter ``counter c(lo..hi) { ini; inc: p; dec: q; reset: r; overflow: m; ... }``:
    an auxiliary (system) integer with guarantees ``p -> (c' = c + 1 | overflow)``,
    ``q -> (c' = c - 1 | underflow)``, ``r -> c' = lo`` and ``!p & !q & !r -> c' = c``;
    overflow ``false`` (the default), ``keep`` (stay at the bound) or ``modulo`` (wrap)
    (spectra-synt ``CounterTranslator``)."""
    (head,), inner = _block_body(stmt, line)
    toks = _tokens(head, where, line)
    if len(toks) < 3 or toks[2] != "(" or toks[-1] != ")":
        raise _fail(where, line, "expected counter NAME(lo..hi) { ... }")
    name = toks[1]
    base, _, _ = _spectra_type(["Int", *toks[2:]], mod, where, line)
    _declare_typed(mod, base, (), name, "sys", where, line)
    lo, hi = ("num", base[1]), ("num", base[2])
    c, c1 = ("id", name, False), ("next", ("id", name, False))
    preds: dict[str, tuple[Node, int]] = {}
    modes = {"overflow": "false", "underflow": "false"}
    for s, n in inner:
        t = _tokens(s, where, n)
        if len(t) >= 2 and t[1] == ":" and t[0] in ("inc", "dec", "reset"):
            preds[t[0]] = (_spectra_parser(t[2:], where, n).parse(), n)
        elif len(t) == 3 and t[1] == ":" and t[0] in modes and t[2] in ("false", "keep",
                                                                          "modulo"):
            modes[t[0]] = t[2]
        elif len(t) >= 2 and t[1] == ":":
            raise _fail(where, n, f"counter {name!r}: unsupported entry {' '.join(t)!r} (inc:, "
                        "dec:, reset:, overflow:/underflow: false|keep|modulo)")
        else:
            mod.constraints.append(_Constraint("guarantee", "init",
                                               _spectra_parser(t, where, n).parse(), n))

    def eq(a: Node, b: Node) -> Node:
        return ("cmp", "=", a, b)

    for op, bound, wrap, mode in (("inc", hi, lo, modes["overflow"]),
                                  ("dec", lo, hi, modes["underflow"])):
        if op in preds:
            pred, n = preds[op]
            step = eq(c1, ("add" if op == "inc" else "sub", c, ("num", 1)))
            edge = {"false": ("const", False), "keep": ("and", eq(c, bound), eq(c1, bound)),
                    "modulo": ("and", eq(c, bound), eq(c1, wrap))}[mode]
            mod.constraints.append(_Constraint("guarantee", "safety",
                                               ("imp", pred, ("or", step, edge)), n))
    if "reset" in preds:
        pred, n = preds["reset"]
        mod.constraints.append(_Constraint("guarantee", "safety", ("imp", pred, eq(c1, lo)), n))
    idle: Node = ("const", True)
    for pred, _ in preds.values():
        idle = ("and", idle, ("not", pred))
    mod.constraints.append(_Constraint("guarantee", "safety", ("imp", idle, eq(c1, c)), line))


def _const(n: Node, mod: _SpectraModule, stack: tuple[str, ...] = ()) -> int | None:
    """The value of a constant integer expression (numbers, defines, arithmetic)."""
    kind = n[0]
    if kind == "num":
        return int(n[1])
    if kind == "id" and n[1] in mod.defines and n[1] not in stack:
        value = mod.defines[n[1]][0]
        if isinstance(value, tuple) and value and value[0] != "array":
            return _const(value, mod, (*stack, n[1]))
        return None
    if kind in _ARITH_OPS:
        a, b = _const(n[1], mod, stack), _const(n[2], mod, stack)
        if a is None or b is None or (kind in ("div", "mod") and b == 0):
            return None
        return _ARITH_OPS[kind](a, b)
    return None


def _const_toks(toks: list[str], mod: _SpectraModule, where: str, line: int,
                what: str) -> int:
    value = _const(_spectra_parser(toks, where, line).parse(), mod) if toks else None
    if value is None:
        raise _fail(where, line, f"{what} {' '.join(toks)!r} is not a constant integer")
    return value


def _spectra_type(toks: list[str], mod: _SpectraModule, where: str, line: int,
                  seen: tuple[str, ...] = ()) -> tuple[tuple[Any, ...], tuple[int, ...],
                                                       list[str]]:
    """``(base, dims, rest)``: base ``("bool",)``, ``("int", lo, hi)`` or
    ``("enum", values)``; array dimensions; the tokens after the type."""
    if not toks:
        raise _fail(where, line, "missing type")
    base: tuple[Any, ...]
    dims: tuple[int, ...] = ()
    if toks[0] == "boolean":
        base, rest = ("bool",), toks[1:]
    elif toks[0] == "Int":
        if len(toks) < 2 or toks[1] != "(":
            raise _fail(where, line, "expected Int(lo..hi)")
        k = _closing(toks, 1)
        inner = toks[2:k]
        if ".." not in inner:
            raise _fail(where, line, "expected Int(lo..hi)")
        d = inner.index("..")
        lo = _const_toks(inner[:d], mod, where, line, "Int bound")
        hi = _const_toks(inner[d + 1:], mod, where, line, "Int bound")
        base, rest = ("int", lo, hi), toks[k + 1:]
    elif toks[0] == "{":
        close = toks.index("}") if "}" in toks else -1
        if close < 0:
            raise _fail(where, line, "unterminated enumeration")
        values = tuple(t for t in toks[1:close] if t != ",")
        if not values or len(set(values)) != len(values):
            raise _fail(where, line, "enumeration needs distinct values")
        base, rest = ("enum", values), toks[close + 1:]
    elif toks[0] in mod.types and toks[0] not in seen:
        alias, aline, awhere = mod.types[toks[0]]
        base, dims, extra = _spectra_type(alias, mod, awhere, aline, (*seen, toks[0]))
        if extra:
            raise _fail(awhere, aline, f"type {toks[0]!r}: unexpected {extra[0]!r}")
        rest = toks[1:]
    else:
        raise _fail(where, line, f"type {toks[0]!r} is not supported (boolean, "
                    "Int(lo..hi), {A, B, ...} or a type name)")
    while rest and rest[0] == "[":
        close = rest.index("]") if "]" in rest else -1
        if close < 0:
            raise _fail(where, line, "unterminated array dimension")
        size = _const_toks(rest[1:close], mod, where, line, "array size")
        if size < 1 or size > 1 << 12:
            raise _fail(where, line, f"array size {size} outside 1..4096")
        dims, rest = (*dims, size), rest[close + 1:]
        cells = 1
        for d in dims:
            cells *= d
        if cells > MAX_IMPORT_CELLS:
            raise _fail(where, line, f"an array of {' x '.join(map(str, dims))} = {cells:,} "
                        f"variables, more than {MAX_IMPORT_CELLS:,} (MAX_IMPORT_CELLS)")
    return base, dims, rest


def _declare_typed(mod: _SpectraModule, base: tuple[Any, ...], dims: tuple[int, ...],
                   name: str, side: str, where: str, line: int) -> None:
    if dims:
        mod.arrays[name] = dims
    for idx in itertools.product(*(range(d) for d in dims)):
        src = name + "".join(f"[{i}]" for i in idx)
        ap = _ap_stem(name) + "".join(f"_{i}" for i in idx)
        if base[0] == "bool":
            ap = _ap_name(ap)
            var = _Var(name=src, ap=ap, side=side)
        elif base[0] == "int":
            var = _Var(name=src, ap=ap, side=side, lo=int(base[1]),
                       hi=int(base[2]), boolean=False)
        else:
            values = tuple(base[1])
            var = _Var(name=src, ap=ap, side=side, lo=0, hi=len(values) - 1, boolean=False,
                       values=values)
        _declare(mod.spec, var, where, line)


def _spectra_var(mod: _SpectraModule, toks: list[str], where: str, line: int) -> None:
    owner = toks[0]
    base, dims, rest = _spectra_type(toks[1:], mod, where, line)
    if len(rest) != 1 or not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", rest[0]):
        raise _fail(where, line, f"{owner}: expected one variable name after the type")
    _declare_typed(mod, base, dims, rest[0], _OWNERS[owner], where, line)


def _slot_and_body(rest: list[str], where: str, line: int, *, default: str | None
                   ) -> tuple[str, Node]:
    slot = None
    if rest and rest[0] in _SLOT_WORDS:
        slot, rest = _SLOT_WORDS[rest[0]], rest[1:]
    if not rest:
        raise _fail(where, line, "empty constraint")
    body = _spectra_parser(rest, where, line).parse()
    if slot is None:
        slot = {"G": "safety", "GF": "liveness"}.get(body[0], default)
        if slot != default:
            body = body[1]
    if slot is None:
        slot = "init"
    return slot, body


def _spectra_constraint(toks: list[str], where: str, line: int) -> _Constraint:
    side = "assume" if toks[0] in ("asm", "assumption") else "guarantee"
    rest = toks[1:]
    if len(rest) >= 2 and rest[1] == "{" and re.match(r"^[A-Za-z_]\w*$", rest[0]):
        raise _fail(where, line, "Spectra constraints with parameters are not supported")
    if len(rest) >= 2 and rest[1] == ":" and re.match(r"^[A-Za-z_]\w*$", rest[0]):
        rest = rest[2:]  # a label
    slot, body = _slot_and_body(rest, where, line, default="init")
    return _Constraint(side=side, slot=slot, body=body, line=line)
