"""Specs written for other GR(1) tools, translated to our TOML spec format.

Three formats are read (``tli spec import``):

* **Spectra** (``.spectra``; Maoz and Ringert, SoSyM 2021), the GR(1) subset: ``env``/``sys``
  variables of type ``boolean``, ``Int(lo..hi)`` or an enumeration ``{A, B, C}``;
  ``type Name = ...;`` aliases of these types; ``define name := expr;`` macros without
  parameters; ``asm``/``assumption`` and
  ``gar``/``guarantee`` constraints (optionally labelled ``name:``), each an initial constraint
  (no temporal operator, or ``ini``/``initially``), a safety constraint (``G``/``alw``/
  ``always``, with ``next(...)``) or a justice constraint (``GF``/``alwEv``/
  ``alwaysEventually``);
* **structured slugs** (``.structuredslugs``): sections ``[INPUT]``, ``[OUTPUT]``,
  ``[ENV|SYS_INIT|TRANS|LIVENESS]``, Boolean variables and integers ``a:lo...hi``, infix
  formulas with ``'`` for the next value, ``+``/``-`` and comparisons between integers;
* **slugsin** (``.slugsin``): the same sections over Boolean variables, formulas in prefix
  notation with memory buffers (``$ n ...``, ``? i``).

Integers and enumerations are bit-blasted: a variable with domain ``lo..hi`` becomes the
Boolean variables ``name_0``, ``name_1``, ... holding ``value - lo`` in binary, least
significant bit first (enumeration values are numbered from 0 in declaration order). When the
domain does not fill its bits, the domain constraint is added to the side that owns the
variable: an initial condition and ``G(X dom)`` (an assumption for inputs, a guarantee for
outputs). Names are lower-cased (our AP names are lower-case identifiers); a clash is refused.

Every construct that the GR(1) TOML cannot express is refused by name, with the file and line:
Spectra's patterns, monitors, counters, predicates, triggers, weights (energy), regular
expressions, arrays, quantifiers and past-time operators
(``PREV``, ``Y``, ``H``, ``O``, ``S``), defines with parameters; ``next`` of a system variable
inside an assumption; ``next`` inside an initial condition or a liveness goal; nested ``next``;
multiplication and division; temporal operators other than the slot's own. ``import`` lines
(Spectra's pattern libraries) are skipped: a pattern used is refused where it is used.

The translation keeps each constraint's text in the slot it was written in. Which reading of
``G(phi)`` at time 0 decides the game is the spec's ``semantics`` setting
(``docs/explanation/logic.md``, "Two readings of safety at time 0").
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tli_verify.errors import SpecError
from tli_verify.io import read_text

__all__ = ["FORMATS", "ImportedSpec", "import_spec_file", "import_spec_text"]

FORMATS = {".spectra": "spectra", ".structuredslugs": "structuredslugs",
           ".slugsin": "slugsin"}
"""File suffix -> format name."""

# --------------------------------------------------------------------------------------------
# Expression trees (tuples): ("const", bool) ("num", int) ("id", name, primed)
# ("not", a) ("and"|"or"|"xor"|"imp"|"iff", a, b) ("next", a) ("cmp", op, a, b)
# ("add"|"sub", a, b) ("G", a) ("GF", a)

Node = tuple


@dataclass(slots=True)
class _Var:
    name: str  # the name in the source
    ap: str  # our AP name (bool) or bit-name stem (int)
    side: str  # "env" or "sys"
    lo: int = 0
    hi: int = 1
    boolean: bool = True
    values: tuple[str, ...] = ()  # enumeration literals

    @property
    def width(self) -> int:
        return max(1, (self.hi - self.lo).bit_length())

    def bits(self) -> list[str]:
        return [self.ap] if self.boolean else [f"{self.ap}_{k}" for k in range(self.width)]


@dataclass(slots=True)
class _Constraint:
    side: str  # "assume" or "guarantee"
    slot: str  # "init", "safety", "liveness"
    body: Node
    line: int


@dataclass(slots=True)
class ImportedSpec:
    """A foreign spec after translation: variables and constraints, ready to write as TOML."""

    name: str
    source: str
    fmt: str
    variables: list[_Var] = field(default_factory=list)
    constraints: list[_Constraint] = field(default_factory=list)

    def inputs(self) -> list[str]:
        return [b for v in self.variables if v.side == "env" for b in v.bits()]

    def outputs(self) -> list[str]:
        return [b for v in self.variables if v.side == "sys" for b in v.bits()]


def _fail(where: str, line: int, msg: str) -> SpecError:
    return SpecError(f"{where}:{line}: {msg}")


# --------------------------------------------------------------------------------------------
# Tokenizer and Pratt parser shared by Spectra and structured slugs

_TOKEN = re.compile(r"\s*(?:(?P<num>\d+)|(?P<id>[A-Za-z_][A-Za-z0-9_@.]*)"
                    r"|(?P<op><-->|-->|<->|->|\.\.\.|\.\.|&&|\|\||/\\|\\/|!=|<=|>=|:=|\[\]|<>"
                    r"|[!~&|^=<>+\-*/%()'{},;:\[\]?$#@]))")


def _tokens(text: str, where: str, line: int) -> list[str]:
    out: list[str] = []
    pos = 0
    text = text.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            rest = text[pos:].strip()
            if not rest:
                break
            raise _fail(where, line, f"unexpected character {rest[0]!r}")
        out.append(m.group("num") or m.group("id") or m.group("op"))
        pos = m.end()
    return out


_BINARY = {  # token -> (precedence, node kind); higher binds tighter
    "<->": (1, "iff"), "<-->": (1, "iff"), "iff": (1, "iff"),
    "->": (2, "imp"), "-->": (2, "imp"), "implies": (2, "imp"),
    "^": (3, "xor"), "xor": (3, "xor"),
    "|": (4, "or"), "||": (4, "or"), "\\/": (4, "or"), "or": (4, "or"),
    "&": (5, "and"), "&&": (5, "and"), "/\\": (5, "and"), "and": (5, "and"),
    "=": (7, "cmp"), "!=": (7, "cmp"), "<": (7, "cmp"), "<=": (7, "cmp"), ">": (7, "cmp"),
    ">=": (7, "cmp"),
    "+": (8, "add"), "-": (8, "sub"),
    "*": (9, "unsupported"), "/": (9, "unsupported"), "%": (9, "unsupported"),
    "mod": (9, "unsupported"),
}


class _Parser:
    """Infix formulas: Spectra and structured slugs (``dialect``)."""

    def __init__(self, toks: list[str], *, where: str, line: int, dialect: str,
                 refuse: Mapping[str, str]) -> None:
        self.toks, self.i = toks, 0
        self.where, self.line, self.dialect, self.refuse = where, line, dialect, refuse

    def fail(self, msg: str) -> SpecError:
        return _fail(self.where, self.line, msg)

    def peek(self) -> str | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self, expected: str | None = None) -> str:
        tok = self.peek()
        if tok is None:
            raise self.fail("unexpected end of formula"
                            + (f" (expected {expected!r})" if expected else ""))
        if expected is not None and tok != expected:
            raise self.fail(f"expected {expected!r}, found {tok!r}")
        self.i += 1
        return tok

    def parse(self) -> Node:
        node = self.expr(0)
        if self.peek() is not None:
            raise self.fail(f"unexpected {self.peek()!r} after the formula")
        return node

    def expr(self, min_prec: int) -> Node:
        left = self.unary()
        while True:
            tok = self.peek()
            if tok is None or tok not in _BINARY:
                return left
            prec, kind = _BINARY[tok]
            if prec < min_prec:
                return left
            self.take()
            if kind == "unsupported":
                raise self.fail(f"arithmetic operator {tok!r} is not supported (only + and -)")
            # implication is right-associative, the rest left-associative
            right = self.expr(prec if kind == "imp" else prec + 1)
            left = ("cmp", tok, left, right) if kind == "cmp" else (kind, left, right)

    def unary(self) -> Node:
        tok = self.take()
        if tok in self.refuse:
            raise self.fail(self.refuse[tok])
        if tok in ("!", "~", "not"):
            return ("not", self.unary())
        if tok == "-":
            inner = self.unary()
            if inner[0] != "num":
                raise self.fail("unary minus applies to numbers only")
            return ("num", -inner[1])
        if tok in ("G", "[]", "alw", "always"):
            if self.peek() in ("F", "<>"):
                self.take()
                return ("GF", self.unary())
            return ("G", self.unary())
        if tok in ("GF", "alwEv", "alwaysEventually"):
            return ("GF", self.unary())
        if tok in ("F", "<>", "U", "W", "eventually"):
            raise self.fail(f"temporal operator {tok!r} outside GF is not GR(1)")
        if tok in ("next", "X", "()") or (tok == "(" and self.peek() == ")"):
            if tok == "(":
                self.take(")")
            return self.postfix(("next", self.unary()))
        if tok == "(":
            node = self.expr(0)
            self.take(")")
            return self.postfix(node)
        if tok.isdigit():
            return ("num", int(tok))
        if tok in ("TRUE", "true"):
            return ("const", True)
        if tok in ("FALSE", "false"):
            return ("const", False)
        if re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", tok):
            if self.peek() == "[":
                raise self.fail(f"array {tok}[...] is not supported")
            if self.peek() == "(":
                if tok in _PAST:
                    raise self.fail(f"past-time operator {tok} is not supported")
                raise self.fail(f"{tok}(...): predicates, patterns and functions are not "
                                "supported")
            return self.postfix(("id", tok, False))
        raise self.fail(f"unexpected {tok!r}")

    def postfix(self, node: Node) -> Node:
        while self.peek() == "'":
            self.take()
            node = ("next", node)
        return node


# --------------------------------------------------------------------------------------------
# From trees to Spot formulas (with bit-blasting)


class _Translator:
    def __init__(self, spec: ImportedSpec, where: str,
                 defines: Mapping[str, tuple[Node, int]] | None = None) -> None:
        self.spec, self.where = spec, where
        self.vars = {v.name: v for v in spec.variables}
        self.defines = dict(defines or {})
        self.literals: dict[str, set[int]] = {}
        for v in spec.variables:
            for k, lit in enumerate(v.values):
                self.literals.setdefault(lit, set()).add(k)

    def formula(self, c: _Constraint) -> str:
        body = c.body
        if c.slot == "safety":
            body = body[1] if body[0] == "G" else body
        elif c.slot == "liveness":
            body = body[1] if body[0] == "GF" else body
        text = self.btext(body, primed=False, c=c, stack=())
        if c.slot == "safety":
            return f"G({text})"
        if c.slot == "liveness":
            return f"GF({text})"
        return text

    def fail(self, c: _Constraint, msg: str) -> SpecError:
        return _fail(self.where, c.line, msg)

    def btext(self, n: Node, *, primed: bool, c: _Constraint, stack: tuple[str, ...]) -> str:
        kind = n[0]
        if kind == "const":
            return "true" if n[1] else "false"
        if kind == "not":
            return f"!({self.btext(n[1], primed=primed, c=c, stack=stack)})"
        if kind in ("and", "or"):
            parts = [self.btext(m, primed=primed, c=c, stack=stack) for m in _flatten(n, kind)]
            op = " & " if kind == "and" else " | "
            return "(" + op.join(parts) + ")"
        if kind in ("xor", "imp", "iff"):
            op = {"xor": "^", "imp": "->", "iff": "<->"}[kind]
            a = self.btext(n[1], primed=primed, c=c, stack=stack)
            b = self.btext(n[2], primed=primed, c=c, stack=stack)
            return f"(({a}) {op} ({b}))"
        if kind == "next":
            if primed:
                raise self.fail(c, "nested next (next of a next value) is not GR(1)")
            if c.slot != "safety":
                what = "an initial condition" if c.slot == "init" else "a liveness goal"
                raise self.fail(c, f"next inside {what} is not expressible in GR(1) (only in "
                                "safety constraints)")
            return self.btext(n[1], primed=True, c=c, stack=stack)
        if kind in ("G", "GF"):
            raise self.fail(c, f"temporal operator {kind} nested inside a formula is not GR(1)")
        if kind == "cmp":
            return self.compare(n, primed=primed, c=c, stack=stack)
        if kind == "id":
            name = n[1]
            if name in self.defines:
                return self.btext(self.define(name, c, stack), primed=primed, c=c,
                                 stack=(*stack, name))
            var = self.vars.get(name)
            if var is None:
                raise self.fail(c, f"unknown identifier {name!r}")
            if not var.boolean:
                raise self.fail(c, f"{name!r} is not Boolean; compare it (e.g. {name} = ...)")
            return self.ap(var, primed, c)
        if kind in ("num", "add", "sub"):
            raise self.fail(c, "an integer expression where a Boolean one is expected")
        raise self.fail(c, f"unsupported construct {kind!r}")

    def define(self, name: str, c: _Constraint, stack: tuple[str, ...]) -> Node:
        if name in stack:
            raise self.fail(c, f"define {name!r} refers to itself")
        return self.defines[name][0]

    def ap(self, var: _Var, primed: bool, c: _Constraint, bit: str | None = None) -> str:
        name = bit or var.ap
        if primed and var.side == "sys" and c.side == "assume":
            raise self.fail(c, f"next of system variable {var.name!r} inside an assumption "
                            "(assumptions may read the next inputs only)")
        return f"X {name}" if primed else name

    def value_cube(self, var: _Var, k: int, primed: bool, c: _Constraint) -> str:
        code = k - var.lo
        lits = []
        for b, bit in enumerate(var.bits()):
            a = self.ap(var, primed, c, bit)
            lits.append(a if (code >> b) & 1 else f"!{a}")
        return "(" + " & ".join(lits) + ")"

    def domain(self, var: _Var, primed: bool, c: _Constraint) -> str | None:
        if var.boolean or (var.hi - var.lo + 1) == 1 << var.width:
            return None
        return "(" + " | ".join(self.value_cube(var, k, primed, c)
                                for k in range(var.lo, var.hi + 1)) + ")"

    def ints(self, n: Node, *, primed: bool, c: _Constraint, stack: tuple[str, ...],
             enum: _Var | None = None) -> dict[int, str]:
        """``value -> condition`` (Spot text) of an integer-valued expression."""
        kind = n[0]
        if kind == "num":
            return {n[1]: "true"}
        if kind == "next":
            if primed:
                raise self.fail(c, "nested next (next of a next value) is not GR(1)")
            if c.slot != "safety":
                raise self.fail(c, "next outside a safety constraint is not GR(1)")
            return self.ints(n[1], primed=True, c=c, stack=stack, enum=enum)
        if kind == "id":
            name = n[1]
            if name in self.defines:
                return self.ints(self.define(name, c, stack), primed=primed, c=c,
                                 stack=(*stack, name), enum=enum)
            var = self.vars.get(name)
            if var is not None and not var.boolean:
                return {k: self.value_cube(var, k, primed, c) for k in range(var.lo, var.hi + 1)}
            if var is None:
                if enum is not None and name in enum.values:
                    return {enum.values.index(name): "true"}
                if name in self.literals:
                    if len(self.literals[name]) > 1:
                        raise self.fail(c, f"enumeration value {name!r} is ambiguous here")
                    return {next(iter(self.literals[name])): "true"}
                raise self.fail(c, f"unknown identifier {name!r}")
        if kind in ("add", "sub"):
            a = self.ints(n[1], primed=primed, c=c, stack=stack, enum=enum)
            b = self.ints(n[2], primed=primed, c=c, stack=stack, enum=enum)
            out: dict[int, list[str]] = {}
            for va, ca in a.items():
                for vb, cb in b.items():
                    v = va + vb if kind == "add" else va - vb
                    out.setdefault(v, []).append(_and(ca, cb))
            return {v: _or(cs) for v, cs in out.items()}
        # a Boolean expression compared as an integer: true is 1
        text = self.btext(n, primed=primed, c=c, stack=stack)
        return {1: text, 0: f"!({text})"}

    def compare(self, n: Node, *, primed: bool, c: _Constraint, stack: tuple[str, ...]) -> str:
        _, op, lhs, rhs = n
        enum = self.enum_of(lhs, stack) or self.enum_of(rhs, stack)
        a = self.ints(lhs, primed=primed, c=c, stack=stack, enum=enum)
        b = self.ints(rhs, primed=primed, c=c, stack=stack, enum=enum)
        test: Callable[[int, int], bool] = {
            "=": lambda x, y: x == y, "!=": lambda x, y: x != y, "<": lambda x, y: x < y,
            "<=": lambda x, y: x <= y, ">": lambda x, y: x > y, ">=": lambda x, y: x >= y,
        }[op]
        terms = []
        for va, ca in a.items():
            match = [cb for vb, cb in b.items() if test(va, vb)]
            if match:
                terms.append(_and(ca, _or(match)))
        return _or(terms)

    def enum_of(self, n: Node, stack: tuple[str, ...]) -> _Var | None:
        while n[0] == "next":
            n = n[1]
        if n[0] == "id":
            if n[1] in self.defines and n[1] not in stack:
                return self.enum_of(self.defines[n[1]][0], (*stack, n[1]))
            var = self.vars.get(n[1])
            if var is not None and var.values:
                return var
        return None


def _flatten(n: Node, kind: str) -> Iterator[Node]:
    stack = [n]
    while stack:
        m = stack.pop()
        if m[0] == kind:
            stack.extend(reversed(m[1:]))
        else:
            yield m


def _and(a: str, b: str) -> str:
    if a == "true":
        return b
    if b == "true":
        return a
    return f"{a} & {b}"


def _or(parts: Sequence[str]) -> str:
    parts = list(parts)
    if not parts:
        return "false"
    if "true" in parts:
        return "true"
    return "(" + " | ".join(parts) + ")"


# --------------------------------------------------------------------------------------------
# Naming


_AP = re.compile(r"^[a-z_][a-z0-9_]*$")
_RESERVED = frozenset({"true", "false", "xor", "implies", "equiv"})


def _ap_name(name: str) -> str:
    low = re.sub(r"[^a-z0-9_]", "_", name.lower())
    if not _AP.match(low):
        low = "v_" + low
    if low in _RESERVED or (len(low) == 1 and low in "xgfurwm"):
        low = low + "_"
    return low


def _declare(spec: ImportedSpec, var: _Var, where: str, line: int) -> None:
    taken = {b for v in spec.variables for b in v.bits()}
    if any(v.name == var.name for v in spec.variables):
        raise _fail(where, line, f"variable {var.name!r} declared twice")
    if var.lo > var.hi:
        raise _fail(where, line, f"variable {var.name!r}: empty range {var.lo}..{var.hi}")
    if var.hi - var.lo > 1 << 20:
        raise _fail(where, line, f"variable {var.name!r}: range {var.lo}..{var.hi} wider than "
                    "2^20 values")
    clash = sorted(set(var.bits()) & taken)
    if clash:
        raise _fail(where, line, f"variable {var.name!r} becomes AP {clash[0]!r}, which "
                    "another variable already uses (names are lower-cased)")
    spec.variables.append(var)


# --------------------------------------------------------------------------------------------
# Spectra


_PAST = frozenset({"Y", "H", "O", "S", "T", "PREV", "ONCE", "HISTORICALLY", "SINCE"})

_SCAN_REFUSED = frozenset({"pattern", "monitor", "counter", "predicate", "trig", "regexp",
                           "weight", "forall", "exists", "PREV", "ONCE", "HISTORICALLY",
                           "SINCE"})
"""Words that refuse a statement wherever they occur in it."""

_SPECTRA_REFUSED = {
    "pattern": "Spectra patterns are not supported (expand them into GR(1) constraints)",
    "monitor": "Spectra monitors are not supported",
    "counter": "Spectra counters are not supported",
    "predicate": "Spectra predicates are not supported",
    "trig": "Spectra triggers (regular-expression constraints) are not supported",
    "regexp": "Spectra regular expressions are not supported",
    "weight": "Spectra weights (energy games) are not supported: not GR(1)",
    "forall": "Spectra quantifiers (forall) are not supported",
    "exists": "Spectra quantifiers (exists) are not supported",
    "PREV": "past-time operator PREV is not supported",
    "ONCE": "past-time operator ONCE is not supported",
    "HISTORICALLY": "past-time operator HISTORICALLY is not supported",
    "SINCE": "past-time operator SINCE is not supported",
    "keep": "Spectra 'keep' is not supported",
    "aux": "Spectra auxiliary variables (aux) are not supported",
    "var": "Spectra 'var' declarations (of monitors, patterns) are not supported",
    "sum": "Spectra 'sum' is not supported",
    "prod": "Spectra 'prod' is not supported",
}


def _strip_spectra_comments(text: str, where: str) -> str:
    """Drop ``//``, ``--`` line comments and ``/* */`` block comments, keeping line breaks."""
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
            if j < 0:
                raise _fail(where, text.count("\n", 0, i) + 1, "unterminated string")
            out.append(" " * (j + 1 - i))
            i = j + 1
        else:
            out.append(text[i])
            i += 1
    return "".join(out)


def _statements(text: str) -> Iterator[tuple[str, int]]:
    """``;``-terminated statements (and the ``module``/``spec`` header line) with their line."""
    buf: list[str] = []
    start_line = 1
    line = 1
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
            if (re.match(r"^(module|spec)\s+\w+$", stripped) or stripped in ("define",)
                    or re.match(r"^import\s*$", stripped)):  # (its string is blanked)
                yield stripped, start_line
                buf = []
                continue
        if ch == ";":
            yield "".join(buf).strip(), start_line
            buf = []
            continue
        buf.append(ch)
    rest = "".join(buf).strip()
    if rest:
        yield rest, start_line


def _parse_spectra(text: str, where: str, default_name: str) -> tuple[ImportedSpec,
                                                                       dict[str, tuple[Node, int]]]:
    spec = ImportedSpec(name=default_name, source=where, fmt="spectra")
    defines: dict[str, tuple[Node, int]] = {}
    types: dict[str, list[str]] = {}
    in_define = False
    statements = list(_statements(_strip_spectra_comments(text, where)))
    for stmt, line in statements:  # type aliases first: they may follow their first use
        if not re.match(r"^type\b", stmt):
            continue
        toks = _tokens(stmt, where, line)
        if toks:
            if len(toks) < 4 or toks[2] != "=" or not re.match(r"^[A-Za-z_]\w*$", toks[1]):
                raise _fail(where, line, "expected type NAME = boolean | Int(lo..hi) | {A, ...}")
            if toks[1] in types:
                raise _fail(where, line, f"type {toks[1]!r} declared twice")
            types[toks[1]] = toks[3:]
    for stmt, line in statements:
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
            spec.name = toks[1]
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
        if head == "import":
            continue  # a pattern library: a pattern used is refused where it is used
        if head == "type":
            in_define = False
            continue
        if head in _SPECTRA_REFUSED:
            raise _fail(where, line, _SPECTRA_REFUSED[head])
        if head in ("env", "sys"):
            in_define = False
            if len(toks) > 1 and toks[1] in types:
                toks = [toks[0], *types[toks[1]], *toks[2:]]
            _spectra_var(spec, toks, where, line)
            continue
        if head in ("asm", "assumption", "gar", "guarantee"):
            in_define = False
            spec.constraints.append(_spectra_constraint(toks, where, line))
            continue
        if in_define and len(toks) >= 2 and toks[1] == ":=":
            name = toks[0]
            if name in defines:
                raise _fail(where, line, f"define {name!r} twice")
            defines[name] = (_Parser(toks[2:], where=where, line=line, dialect="spectra",
                                     refuse=_SPECTRA_REFUSED).parse(), line)
            continue
        if in_define and len(toks) >= 2 and toks[1] in ("(", "["):
            raise _fail(where, line, f"define {toks[0]!r} with parameters or an array is not "
                        "supported")
        raise _fail(where, line, f"unsupported Spectra statement starting with {head!r}")
    return spec, defines


def _spectra_var(spec: ImportedSpec, toks: list[str], where: str, line: int) -> None:
    side, rest = toks[0], toks[1:]
    values: tuple[str, ...]
    if not rest:
        raise _fail(where, line, f"{side}: missing type")
    if rest[0] == "boolean":
        typ, rest = ("bool",), rest[1:]
        lo, hi, values = 0, 1, ()
    elif rest[0] == "Int":
        m = re.fullmatch(r"\(\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*\)", "".join(rest[1:6]))
        if m is None:
            raise _fail(where, line, f"{side}: expected Int(lo..hi)")
        lo, hi, values, typ, rest = int(m.group(1)), int(m.group(2)), (), ("int",), rest[6:]
    elif rest[0] == "{":
        close = rest.index("}") if "}" in rest else -1
        if close < 0:
            raise _fail(where, line, f"{side}: unterminated enumeration")
        values = tuple(t for t in rest[1:close] if t != ",")
        if not values or len(set(values)) != len(values):
            raise _fail(where, line, f"{side}: enumeration needs distinct values")
        lo, hi, typ, rest = 0, len(values) - 1, ("enum",), rest[close + 1:]
    else:
        raise _fail(where, line, f"{side}: type {rest[0]!r} is not supported (boolean, "
                    "Int(lo..hi) or {A, B, ...})")
    if rest and rest[0] == "[":
        raise _fail(where, line, "arrays of variables are not supported")
    if len(rest) != 1 or not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", rest[0]):
        raise _fail(where, line, f"{side}: expected one variable name after the type")
    name = rest[0]
    var = _Var(name=name, ap=_ap_name(name), side=side, lo=lo, hi=hi,
               boolean=typ == ("bool",), values=values)
    _declare(spec, var, where, line)


def _spectra_constraint(toks: list[str], where: str, line: int) -> _Constraint:
    side = "assume" if toks[0] in ("asm", "assumption") else "guarantee"
    rest = toks[1:]
    if len(rest) >= 2 and rest[1] == ":" and re.match(r"^[A-Za-z_]\w*$", rest[0]):
        rest = rest[2:]  # a label
    if not rest:
        raise _fail(where, line, "empty constraint")
    if rest[0] in ("trig",):
        raise _fail(where, line, _SPECTRA_REFUSED["trig"])
    slot = None
    if rest[0] in ("ini", "initially"):
        slot, rest = "init", rest[1:]
    elif rest[0] in ("trans",):
        slot, rest = "safety", rest[1:]
    elif rest[0] in ("justice",):
        slot, rest = "liveness", rest[1:]
    body = _Parser(rest, where=where, line=line, dialect="spectra",
                   refuse=_SPECTRA_REFUSED).parse()
    if slot is None:
        slot = {"G": "safety", "GF": "liveness"}.get(body[0], "init")
    elif slot == "safety" and body[0] != "G":
        body = ("G", body)
    elif slot == "liveness" and body[0] != "GF":
        body = ("GF", body)
    return _Constraint(side=side, slot=slot, body=body, line=line)


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


# --------------------------------------------------------------------------------------------
# Writing our TOML


def import_spec_file(path: str | Path, *, semantics: str | None = "textbook") -> str:
    """Read a Spectra, structured slugs or slugsin file and return our TOML spec text.

    Parameters
    ----------
    path : path-like
        A ``.spectra``, ``.structuredslugs`` or ``.slugsin`` file.
    semantics : str or None
        The ``semantics`` setting written into the spec (``"textbook"``, the tools' own
        reading, by default; None writes none, i.e. ours).

    Raises
    ------
    SpecError
        On a construct the TOML cannot express, naming it, the file and the line.
    """
    p = Path(path)
    fmt = FORMATS.get(p.suffix)
    if fmt is None:
        raise SpecError(f"{path}: unknown format (expected a file ending in "
                        f"{', '.join(FORMATS)})")
    text = read_text(p, what="spec", error=SpecError)
    return import_spec_text(text, fmt=fmt, where=str(path), default_name=p.stem,
                            semantics=semantics)


def import_spec_text(text: str, *, fmt: str, where: str = "<spec>", default_name: str = "spec",
                     semantics: str | None = "textbook") -> str:
    """Translate the text of a foreign spec (``fmt``: a value of :data:`FORMATS`) to TOML."""
    defines: dict[str, tuple[Node, int]] = {}
    if fmt == "spectra":
        spec, defines = _parse_spectra(text, where, default_name)
    elif fmt == "structuredslugs":
        spec = _parse_structuredslugs(text, where, default_name)
    elif fmt == "slugsin":
        spec = _parse_slugsin(text, where, default_name)
    else:
        raise SpecError(f"{where}: unknown format {fmt!r}")
    if not spec.outputs():
        raise SpecError(f"{where}: no system variable (our specs need at least one output)")
    tr = _Translator(spec, where, defines)
    sections: dict[tuple[str, str], list[tuple[int | None, str]]] = {}
    for c in spec.constraints:
        sections.setdefault((c.side, c.slot), []).append((c.line, tr.formula(c)))
    for var in spec.variables:
        owner = "assume" if var.side == "env" else "guarantee"
        probe = _Constraint(side=owner, slot="safety", body=("const", True), line=0)
        now, nxt = tr.domain(var, False, probe), tr.domain(var, True, probe)
        if now is not None and nxt is not None:
            sections.setdefault((owner, "init"), []).append((None, now))
            sections.setdefault((owner, "safety"), []).append((None, f"G({nxt})"))
    return _toml(spec, sections, semantics)


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
