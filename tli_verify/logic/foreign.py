"""Specs written for other GR(1) tools, translated to our TOML spec format.

Three formats are read (``tli spec import``):

* **Spectra** (``.spectra``; Maoz and Ringert, SoSyM 2021): ``env``/``sys``/``aux``
  variables of type ``boolean``, ``Int(lo..hi)``, an enumeration ``{A, B, C}`` or a ``type``
  alias, also as arrays (``boolean[N] x``); ``define`` macros and arrays of expressions;
  ``asm``/``gar`` constraints (optionally labelled) in the slots ``ini``, ``G``/``trans``,
  ``alw`` (a state invariant) and ``GF``/``alwEv``; and Spectra's derived constructs, expanded
  as spectra-synt's translators expand them (:class:`_Expander`): predicates, patterns (also
  from ``import``-ed files), monitors, counters, past operators, quantifiers, ``in``, array
  functions (``docs/explanation/logic.md``, "Specs from Spectra and slugs");
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
Spectra's triggers, regular expressions, weights (energy), existential guarantees,
constraints with parameters, defines with parameters; ``next`` of a system variable inside an
assumption; ``next`` inside an initial condition; nested ``next``; temporal operators other
than the slot's own. A liveness goal that reads next values gets a fresh system variable.

The translation keeps each constraint's text in the slot it was written in. Which reading of
``G(phi)`` at time 0 decides the game is the spec's ``semantics`` setting
(``docs/explanation/logic.md``, "Two readings of safety at time 0").
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.io import read_text
from tli_verify.limits import (
    MAX_FORMULA_DEPTH,
    MAX_FORMULA_NODES,
    MAX_IMPORT_CELLS,
    MAX_INPUT_BYTES,
)

__all__ = ["FORMATS", "ImportedSpec", "import_spec_file", "import_spec_text"]

FORMATS = {".spectra": "spectra", ".structuredslugs": "structuredslugs",
           ".slugsin": "slugsin"}
"""File suffix -> format name."""

# --------------------------------------------------------------------------------------------
# Expression trees (tuples): ("const", bool) ("num", int) ("id", name, primed)
# ("not", a) ("and"|"or", a, b, ...) ("xor"|"imp"|"iff", a, b) ("next", a) ("cmp", op, a, b)
# ("add"|"sub", a, b) ("G", a) ("GF", a)

Node = tuple

_CHAINS = ("and", "or")
"""The associative operators whose chains (``a & b & c``) are one n-ary node: one level of
nesting, however long (parsed, expanded and written without recursion per operand)."""


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
    slot: str  # "init", "safety", "liveness" (Spectra before expansion: also "stateinv")
    body: Node
    line: int
    where: str = ""  # the file, when not the spec's own (a Spectra import)


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

_TOKEN = re.compile(r"\s*(?:(?P<num>\d+)|(?P<id>[A-Za-z_][A-Za-z0-9_@]*(?:\.[A-Za-z_]\w*)*)"
                    r"|(?P<op><-->|-->|<->|->|\.\.\.|\.\.|&&|\|\||/\\|\\/|!=|<=|>=|:=|\[\]|<>"
                    r"|[!~&|^=<>+\-*/%()'{},;:\[\]?$#@.]))")


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


_ARITH = {"+": "add", "-": "sub", "*": "mul", "/": "div", "%": "mod", "mod": "mod"}

_BINARY = {  # slugs: token -> (precedence, node kind); higher binds tighter
    "<->": (1, "iff"), "<-->": (1, "iff"), "iff": (1, "iff"),
    "->": (2, "imp"), "-->": (2, "imp"), "implies": (2, "imp"),
    "^": (3, "xor"), "xor": (3, "xor"),
    "|": (4, "or"), "||": (4, "or"), "\\/": (4, "or"), "or": (4, "or"),
    "&": (5, "and"), "&&": (5, "and"), "/\\": (5, "and"), "and": (5, "and"),
    "=": (7, "cmp"), "!=": (7, "cmp"), "<": (7, "cmp"), "<=": (7, "cmp"), ">": (7, "cmp"),
    ">=": (7, "cmp"),
    "+": (8, "arith"), "-": (8, "arith"),
    "*": (9, "arith"), "/": (9, "arith"), "%": (9, "arith"), "mod": (9, "arith"),
}
"""structured slugs (grammar.wi of slugs' StructuredSlugsParser): ``<->`` binds loosest,
then ``->`` (left-associative), xor, or, and."""

_SPECTRA_BINARY = {  # Spectra.xtext: implication loosest (right-associative), then iff
    "->": (1, "imp"), "implies": (1, "imp"),
    "<->": (2, "iff"), "iff": (2, "iff"),
    "|": (4, "or"), "or": (4, "or"), "xor": (4, "xor"),
    "&": (5, "and"), "and": (5, "and"),
    "=": (7, "cmp"), "!=": (7, "cmp"), "<": (7, "cmp"), "<=": (7, "cmp"), ">": (7, "cmp"),
    ">=": (7, "cmp"),
    "mod": (8, "arith"), "%": (8, "arith"),
    "+": (9, "arith"), "-": (9, "arith"),
    "*": (10, "arith"), "/": (10, "arith"),
    "S": (11, "since"), "SINCE": (11, "since"), "T": (11, "triggered"),
    "TRIGGERED": (11, "triggered"),
}

_PAST_UNARY = {"Y": "PREV", "PREV": "PREV", "H": "HISTORICALLY", "HISTORICALLY": "HISTORICALLY",
               "O": "ONCE", "ONCE": "ONCE"}


class _Parser:
    """Infix formulas: Spectra and structured slugs (``dialect``).

    Spectra's extra nodes (resolved by :class:`_Expander`): ``("call", name, args)``,
    ``("index", name, indices)``, ``("past", op, args)``, ``("in", a, values, negated)``,
    ``("quant", op, name, type tokens, body)``."""

    def __init__(self, toks: list[str], *, where: str, line: int, dialect: str,
                 refuse: Mapping[str, str]) -> None:
        self.toks, self.i = toks, 0
        self.where, self.line, self.dialect, self.refuse = where, line, dialect, refuse
        self.table = _SPECTRA_BINARY if dialect == "spectra" else _BINARY
        self.depth = 0

    def enter(self) -> None:
        """One more level of nesting (a parenthesis, a prefix operator, a right operand):
        refused past ``MAX_FORMULA_DEPTH``, the one depth limit of every formula parser."""
        self.depth += 1
        if self.depth > MAX_FORMULA_DEPTH:
            raise self.fail(f"formula nested deeper than {MAX_FORMULA_DEPTH} levels "
                            "(MAX_FORMULA_DEPTH)")

    def fail(self, msg: str) -> SpecError:
        return _fail(self.where, self.line, msg)

    def peek(self, ahead: int = 0) -> str | None:
        k = self.i + ahead
        return self.toks[k] if k < len(self.toks) else None

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
        self.enter()
        try:
            return self._expr(min_prec)
        finally:
            self.depth -= 1

    def _expr(self, min_prec: int) -> Node:
        if (self.dialect == "spectra" and self.peek() in ("forall", "exists")
                and self.peek(2) == "in"):
            return self.quantifier()
        left = self.unary()
        while True:
            tok = self.peek()
            if min_prec == 0 and self.dialect == "spectra" and (
                    tok == "in" or (tok == "not" and self.peek(1) == "in")):
                left = self.in_set(left)
                continue
            if tok is None or tok not in self.table:
                return left
            prec, kind = self.table[tok]
            if prec < min_prec:
                return left
            self.take()
            right_assoc = kind == "imp" and self.dialect == "spectra"
            right = self.expr(prec if right_assoc else prec + 1)
            if kind == "cmp":
                left = ("cmp", tok, left, right)
            elif kind == "arith":
                left = (_ARITH[tok], left, right)
            elif kind in ("since", "triggered"):
                left = ("past", kind.upper(), (left, right))
            elif kind in _CHAINS:  # a chain of one associative operator: one n-ary node
                parts = [left, right]
                while (self.peek() or "") in self.table and \
                        self.table[self.peek() or ""] == (prec, kind):
                    self.take()
                    parts.append(self.expr(prec + 1))
                left = (kind, *parts)
            else:
                left = (kind, left, right)

    def in_set(self, left: Node) -> Node:
        negated = self.take() == "not"
        if negated:
            self.take("in")
        self.take("{")
        values: list[Node] = []
        while True:
            tok = self.take()
            if tok in ("TRUE", "true", "FALSE", "false"):
                values.append(("const", tok.lower() == "true"))
            elif tok.isdigit():
                if self.peek() == "-" and (self.peek(1) or "").isdigit():
                    self.take()
                    hi = int(self.take())
                    values += [("num", k) for k in range(int(tok), hi + 1)]
                else:
                    values.append(("num", int(tok)))
            else:
                values.append(("id", tok, False))
            if self.take() == "}":
                return ("in", left, tuple(values), negated)
            if self.toks[self.i - 1] != ",":
                raise self.fail("expected ',' or '}' in the set of an 'in'")

    def quantifier(self) -> Node:
        op, name = self.take(), self.take()
        self.take("in")
        typ: list[str] = []
        depth = 0
        while True:
            tok = self.take()
            if tok == "." and depth == 0:
                break
            depth += tok in ("(", "{", "[")
            depth -= tok in (")", "}", "]")
            typ.append(tok)
        return ("quant", op, name, tuple(typ), self.expr(0))

    def args(self) -> tuple[Node, ...]:
        self.take("(")
        out: list[Node] = []
        if self.peek() == ")":
            self.take()
            return ()
        while True:
            out.append(self.expr(0))
            if self.take() == ")":
                return tuple(out)
            if self.toks[self.i - 1] != ",":
                raise self.fail("expected ',' or ')' in an argument list")

    def unary(self) -> Node:
        self.enter()
        try:
            return self._unary()
        finally:
            self.depth -= 1

    def _unary(self) -> Node:
        tok = self.take()
        if tok in self.refuse:
            raise self.fail(self.refuse[tok])
        spectra = self.dialect == "spectra"
        if tok in ("!", "~", "not"):
            return ("not", self.unary())
        if tok == "-":
            inner = self.unary()
            if inner[0] == "num":
                return ("num", -inner[1])
            return ("sub", ("num", 0), inner)
        if spectra and tok in _PAST_UNARY:
            return ("past", _PAST_UNARY[tok], (self.unary(),))
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
        if re.match(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_]\w*)?$", tok):
            if self.peek() == "(" and spectra:
                return self.postfix(("call", tok, self.args()))
            if self.peek() == "[" and spectra:
                idx: list[Node] = []
                while self.peek() == "[":
                    self.take("[")
                    idx.append(self.expr(0))
                    self.take("]")
                return self.postfix(("index", tok, tuple(idx)))
            if self.peek() == "[":
                raise self.fail(f"array {tok}[...] is not supported")
            if self.peek() == "(":
                raise self.fail(f"{tok}(...): functions are not supported")
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
        self.written = 0  # characters of the translation so far (all constraints)
        self.memo: dict[tuple[str, bool, str], dict[int, str]] = {}  # see cubes(); read-only

    def budget(self, c: _Constraint, size: int) -> None:
        """Stop as soon as the text being built exceeds what any reader accepts: the
        translation is never larger than ``MAX_INPUT_BYTES``, and never costs much more."""
        if self.written + size > MAX_INPUT_BYTES:
            raise self.fail(c, f"the translation would exceed {MAX_INPUT_BYTES:,} bytes of "
                            "TOML, more than any reader accepts (MAX_INPUT_BYTES): stopped "
                            "here, nothing written (integer comparisons and quantifiers are "
                            "written out bit by bit)")

    def formula(self, c: _Constraint) -> str:
        body = c.body
        if c.slot == "safety":
            body = body[1] if body[0] == "G" else body
        elif c.slot == "liveness":
            body = body[1] if body[0] == "GF" else body
        text = self.btext(body, primed=False, c=c, stack=())
        self.budget(c, len(text))
        self.written += len(text)
        if c.slot == "safety":
            return f"G({text})"
        if c.slot == "liveness":
            return f"GF({text})"
        return text

    def fail(self, c: _Constraint, msg: str) -> SpecError:
        return _fail(c.where or self.where, c.line, msg)

    def btext(self, n: Node, *, primed: bool, c: _Constraint, stack: tuple[str, ...]) -> str:
        kind = n[0]
        if kind == "const":
            return "true" if n[1] else "false"
        if kind == "raw":  # a formula over bits, already in our syntax
            return str(n[1])
        if kind == "not":
            return f"!({self.btext(n[1], primed=primed, c=c, stack=stack)})"
        if kind in ("and", "or"):
            parts, total = [], 0
            for m in _flatten(n, kind):
                parts.append(self.btext(m, primed=primed, c=c, stack=stack))
                total += len(parts[-1]) + 3
                self.budget(c, total)
            op = " & " if kind == "and" else " | "
            return "(" + op.join(parts) + ")"
        if kind in ("xor", "imp", "iff"):
            op = {"xor": "^", "imp": "->", "iff": "<->"}[kind]
            a = self.btext(n[1], primed=primed, c=c, stack=stack)
            b = self.btext(n[2], primed=primed, c=c, stack=stack)
            self.budget(c, len(a) + len(b))
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
            text = self.compare(n, primed=primed, c=c, stack=stack)
            self.budget(c, len(text))
            return text
        if kind == "select":  # ("select", ((condition, value), ...)): an array read
            return _or([_and(self.btext(k, primed=primed, c=c, stack=stack),
                             self.btext(v, primed=primed, c=c, stack=stack)) for k, v in n[1]])
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
        if kind == "num" or kind in _ARITH_OPS:
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

    def cubes(self, var: _Var, primed: bool, c: _Constraint) -> dict[int, str]:
        """``value -> cube`` of an integer variable, made once per variable, time step and
        side (a formula comparing one wide variable with many constants reads it each time:
        without the memo each comparison costs the variable's whole domain)."""
        key = (var.name, primed, c.side)
        got = self.memo.get(key)
        if got is None:
            got = {k: self.value_cube(var, k, primed, c) for k in range(var.lo, var.hi + 1)}
            self.memo[key] = got
        return got

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
                return self.cubes(var, primed, c)
            if var is None:
                if enum is not None and name in enum.values:
                    return {enum.values.index(name): "true"}
                if name in self.literals:
                    if len(self.literals[name]) > 1:
                        raise self.fail(c, f"enumeration value {name!r} is ambiguous here")
                    return {next(iter(self.literals[name])): "true"}
                raise self.fail(c, f"unknown identifier {name!r}")
        if kind == "select":
            sel: dict[int, list[str]] = {}
            for k, v in n[1]:
                cond = self.btext(k, primed=primed, c=c, stack=stack)
                for val, cv in self.ints(v, primed=primed, c=c, stack=stack, enum=enum).items():
                    sel.setdefault(val, []).append(_and(cond, cv))
            return {val: _or(cs) for val, cs in sel.items()}
        if kind in _ARITH_OPS:
            a = self.ints(n[1], primed=primed, c=c, stack=stack, enum=enum)
            b = self.ints(n[2], primed=primed, c=c, stack=stack, enum=enum)
            if kind in ("div", "mod") and 0 in b:
                raise self.fail(c, "division or remainder by an expression that can be 0")
            if len(a) * len(b) > 1 << 16:
                raise self.fail(c, "integer expression with more than 2^16 value pairs")
            out: dict[int, list[str]] = {}
            for va, ca in a.items():
                for vb, cb in b.items():
                    out.setdefault(_ARITH_OPS[kind](va, vb), []).append(_and(ca, cb))
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
        if op in _FLIP and len(a) * len(b) > _PAIRS:
            # an order between two wide operands: one side's bits as a comparator, not the
            # disjunction of the value pairs (which grows as the product of the domains)
            right = self.bitvector(rhs, primed=primed, c=c, stack=stack)
            left = None if right is not None else self.bitvector(lhs, primed=primed, c=c,
                                                                 stack=stack)
            if right is not None or left is not None:
                vec, other, rel = (right, a, _FLIP[op]) if right is not None else (left, b, op)
                assert vec is not None
                bits, lo = vec
                conds = [(cond, _value_cmp(bits, lo, rel, v)) for v, cond in other.items()]
                return _or([_and(cond, t) for cond, t in conds if t != "false"])
        if op == "=" and (len(a) == 1 or len(b) == 1):  # against one value: a look-up
            (vb, cb), = b.items() if len(b) == 1 else a.items()
            ca = (a if len(b) == 1 else b).get(vb)
            return _or([] if ca is None else
                       [_and(ca, _or([cb])) if len(b) == 1 else _and(cb, _or([ca]))])
        terms = []
        for va, ca in a.items():
            match = [cb for vb, cb in b.items() if test(va, vb)]
            if match:
                terms.append(_and(ca, _or(match)))
        return _or(terms)

    def bitvector(self, n: Node, *, primed: bool, c: _Constraint,
                  stack: tuple[str, ...]) -> tuple[list[str], int] | None:
        """The bits (least significant first) and lower bound of ``n`` if it is an integer
        variable (or its next value) whose domain fills its bits, else None."""
        while True:
            if n[0] == "next":
                primed, n = True, n[1]
            elif n[0] == "id" and n[1] in self.defines:
                n, stack = self.define(n[1], c, stack), (*stack, n[1])
            else:
                break
        var = self.vars.get(n[1]) if n[0] == "id" else None
        if var is None or var.boolean or var.values or var.hi - var.lo + 1 != 1 << var.width:
            return None
        return [self.ap(var, primed, c, bit) for bit in var.bits()], var.lo

    def enum_of(self, n: Node, stack: tuple[str, ...]) -> _Var | None:
        while n[0] in ("next", "select"):
            n = n[1] if n[0] == "next" else n[1][0][1]
        if n[0] == "id":
            if n[1] in self.defines and n[1] not in stack:
                return self.enum_of(self.defines[n[1]][0], (*stack, n[1]))
            var = self.vars.get(n[1])
            if var is not None and var.values:
                return var
        return None


_ARITH_OPS: dict[str, Callable[[int, int], int]] = {
    "add": lambda x, y: x + y, "sub": lambda x, y: x - y, "mul": lambda x, y: x * y,
    # Java's (Spectra's) integer division and remainder truncate toward zero
    "div": lambda x, y: abs(x) // abs(y) * (1 if (x >= 0) == (y >= 0) else -1),
    "mod": lambda x, y: x - y * (abs(x) // abs(y) * (1 if (x >= 0) == (y >= 0) else -1)),
}


def _flatten(n: Node, kind: str) -> Iterator[Node]:
    stack = [n]
    while stack:
        m = stack.pop()
        if m[0] == kind:
            stack.extend(reversed(m[1:]))
        else:
            yield m


_PAIRS = 256
"""An order comparison whose operands have more value pairs than this is written with a
comparator over one operand's bits (:meth:`_Translator.bitvector`)."""

_FLIP = {"<": ">", "<=": ">=", ">": "<", ">=": "<="}
"""``x op y`` is ``y _FLIP[op] x``."""


def _code_at_least(bits: Sequence[str], t: int) -> str:
    """``sum(bit_i * 2**i) >= t`` over the literals ``bits`` (least significant first)."""
    if t <= 0:
        return "true"
    if t >= 1 << len(bits):
        return "false"
    out = "true"
    for i, bit in enumerate(bits):
        if (t >> i) & 1:  # this bit must be 1 and the lower bits reach t's
            out = bit if out == "true" else f"({bit} & {out})"
        elif out != "true":  # this bit 1 suffices, else the lower bits decide
            out = f"({bit} | {out})"
    return out


def _value_cmp(bits: Sequence[str], lo: int, op: str, k: int) -> str:
    """``value op k`` for the integer ``lo + code(bits)`` (``op`` one of < <= > >=)."""
    at_least = _code_at_least(bits, k - lo + (op in (">", "<=")))
    if op in (">", ">="):
        return at_least
    return {"true": "false", "false": "true"}.get(at_least, f"!{at_least}")


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


def _ap_stem(name: str) -> str:
    """The lower-cased stem of a variable's bits or array elements (``name_k``)."""
    low = re.sub(r"[^a-z0-9_]", "_", name.lower())
    return low if _AP.match(low) else "v_" + low


def _ap_name(name: str) -> str:
    low = _ap_stem(name)
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


# --------------------------------------------------------------------------------------------
# Spectra's derived constructs, expanded into plain GR(1) over fresh auxiliary variables


class _Expander:
    """Resolves defines, predicates, arrays, quantifiers and ``in``; instantiates patterns
    and past-time operators with fresh auxiliary (system) variables and their constraints,
    as spectra-synt's translators do (``PredicateInstanceTranslator``,
    ``PatternConstraintTranslator``, ``PastLTLTranslator``, ``StateInvTranslator``,
    ``PrimesInJusticeTranslator``)."""

    def __init__(self, mod: _SpectraModule) -> None:
        self.mod = mod
        self.vars = {v.name: v for v in mod.spec.variables}
        self.past: dict[Node, str] = {}
        self.out: list[_Constraint] = []
        self.fresh_count = 0
        self.scale = 1  # how many times the enclosing quantifiers expand what is expanded now
        self.level = 0  # nesting of the formula being expanded, defines and patterns inlined
        self.instantiating: tuple[str, ...] = ()  # the patterns being instantiated, outermost first

    def run(self) -> list[_Constraint]:
        for c in self.mod.constraints:
            self.constraint(c)
        return self.out

    def fail(self, c: _Constraint, msg: str) -> SpecError:
        return _fail(c.where or self.mod.where, c.line, msg)

    def fresh(self, stem: str, base: tuple[Any, ...], c: _Constraint) -> str:
        taken = {b for v in self.mod.spec.variables for b in v.bits()}
        while True:
            name = f"{stem}_{self.fresh_count}"
            self.fresh_count += 1
            var_ap = _ap_name(name)
            if var_ap not in taken and not any(b.startswith(var_ap + "_") for b in taken):
                break
        _declare_typed(self.mod, base, (), name, "sys", c.where or self.mod.where, c.line)
        self.vars[name] = self.mod.spec.variables[-1]
        return name

    def emit(self, side: str, slot: str, body: Node, c: _Constraint) -> None:
        self.out.append(_Constraint(side, slot, body, c.line, c.where))

    def constraint(self, c: _Constraint, env: Mapping[str, Node] | None = None) -> None:
        body = c.body
        if body[0] == "call" and body[1] in self.mod.patterns:
            # Spectra ignores a temporal keyword before a pattern (Spectra2GameInputTranslator:
            # a constraint that references a pattern is a pattern constraint)
            self.pattern(c, body, dict(env or {}))
            return
        body = self.ex(body, dict(env or {}), c, ())
        if c.slot == "stateinv":
            if _has(body, "next") or (c.side == "assume" and self.reads_sys(body)):
                self.emit(c.side, "safety", body, c)
            else:
                self.emit(c.side, "init", body, c)
                self.emit(c.side, "safety", ("next", body), c)
            return
        self.emit(c.side, c.slot, body, c)

    def reads_sys(self, n: Node) -> bool:
        return any(m[0] == "id" and m[1] in self.vars and self.vars[m[1]].side == "sys"
                   for m in _nodes(n))

    def deeper(self, c: _Constraint, what: str) -> None:
        """One more level of expansion: refused past ``MAX_FORMULA_DEPTH``, the depth limit of
        the parsers, applied to the formula as defines, predicates and patterns inline it (a
        chain of them, each within the limit, nests deeper than any one of them)."""
        self.level += 1
        if self.level > MAX_FORMULA_DEPTH:
            raise self.fail(c, f"{what} nested deeper than {MAX_FORMULA_DEPTH} levels once "
                            "defines, predicates and patterns are expanded (MAX_FORMULA_DEPTH)")

    def pattern(self, c: _Constraint, call: Node, env: dict[str, Node] | None = None) -> None:
        """Instantiate the pattern ``call`` names; its arguments are read in ``env`` (the
        parameters and variables of the pattern instantiating it, if any)."""
        if call[1] in self.instantiating:
            chain = " -> ".join((*self.instantiating[self.instantiating.index(call[1]):],
                                 call[1]))
            raise self.fail(c, f"pattern {call[1]!r} instantiates itself ({chain})")
        self.deeper(c, "patterns")
        outer = self.instantiating
        self.instantiating = (*outer, call[1])
        try:
            self._pattern(c, call, env or {})
        finally:
            self.instantiating = outer
            self.level -= 1

    def _pattern(self, c: _Constraint, call: Node, outer: dict[str, Node]) -> None:
        pat = self.mod.patterns[call[1]]
        args = call[2]
        if len(args) != len(pat.params):
            raise self.fail(c, f"pattern {pat.name!r} takes {len(pat.params)} arguments, "
                            f"{len(args)} given")
        env: dict[str, Node] = {p: self.ex(a, outer, c, ()) for p, a in zip(pat.params, args,
                                                                             strict=True)}
        for type_toks, vname in pat.variables:
            base, dims, rest = _spectra_type(type_toks, self.mod, pat.where, c.line)
            if dims or rest:
                raise self.fail(c, f"pattern {pat.name!r}: variable {vname!r} must be a "
                                "scalar")
            env[vname] = ("id", self.fresh(f"{pat.name}_{vname}", base, c), False)
        for slot, body, _ in pat.constraints:
            side = c.side if slot == "liveness" else "guarantee"
            self.constraint(_Constraint(side, slot, body, c.line, c.where), env)

    def ex(self, n: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
           ) -> Node:
        """``n`` with defines, predicates, arrays, quantifiers and ``in`` resolved, and
        past-time operators replaced by auxiliary variables."""
        self.deeper(c, "formula")
        try:
            return self._ex(n, env, c, stack)
        finally:
            self.level -= 1

    def _ex(self, n: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
            ) -> Node:
        kind = n[0]
        if kind in ("const", "num"):
            return n
        if kind == "id":
            return self.ident(n, env, c, stack)
        if kind == "index":
            return self.index(n, env, c, stack)
        if kind == "call":
            return self.call(n, env, c, stack)
        if kind == "past":
            return self.past_op(n[1], tuple(self.ex(a, env, c, stack) for a in n[2]), c)
        if kind == "in":
            lhs = self.ex(n[1], env, c, stack)
            terms = [("cmp", "=", lhs, self.ex(v, env, c, stack)) for v in n[2]]
            node: Node = _chain("or", terms)
            return ("not", node) if n[3] else node
        if kind == "quant":
            return self.quantifier(n, env, c, stack)
        if kind == "select":
            return n
        if kind == "cmp":
            return ("cmp", n[1], self.ex(n[2], env, c, stack), self.ex(n[3], env, c, stack))
        return (kind, *(self.ex(m, env, c, stack) for m in n[1:]))

    def ident(self, n: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
              ) -> Node:
        name = n[1]
        if "." in name and name.split(".", 1)[0] in env:
            head, tail = name.split(".", 1)
            if env[head][0] == "arrayref":
                name = f"{env[head][1]}.{tail}"
        if name in env:
            if env[name][0] == "arrayref":
                raise self.fail(c, f"array {env[name][1]!r} used without an index")
            return env[name]
        if name in self.mod.defines:
            if name in stack:
                raise self.fail(c, f"define {name!r} refers to itself")
            value = self.mod.defines[name][0]
            if not isinstance(value, tuple) or value[0] == "array":
                raise self.fail(c, f"define array {name!r} used without an index")
            return self.ex(value, {}, c, (*stack, name))
        if "." in name:
            arr, func = name.rsplit(".", 1)
            if func in _ARRAY_FUNCS and (arr in self.mod.arrays or arr in self.mod.defines):
                elems = self.elements(arr, env, c, stack)
                op = {"all": "and", "any": "or", "sum": "add", "prod": "mul"}[func]
                if op in _CHAINS:
                    return _chain(op, elems)
                node = elems[0]
                for e in elems[1:]:
                    node = (op, node, e)
                return node
            raise self.fail(c, f"{name!r}: unknown identifier or array function (only "
                            ".all, .any, .sum, .prod)")
        if name in self.mod.arrays:
            raise self.fail(c, f"array {name!r} used without an index")
        return n

    def elements(self, arr: str, env: dict[str, Node], c: _Constraint,
                 stack: tuple[str, ...]) -> list[Node]:
        if arr in self.mod.arrays:
            return [("id", arr + "".join(f"[{i}]" for i in idx), False) for idx in
                    itertools.product(*(range(d) for d in self.mod.arrays[arr]))]
        flat: list[Node] = []
        todo = [self.mod.defines[arr][0]]
        while todo:
            v = todo.pop(0)
            if isinstance(v, tuple) and v and v[0] == "array":
                todo = list(v[1]) + todo
            else:
                flat.append(self.ex(v, {}, c, (*stack, arr)))
        return flat

    def index(self, n: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
              ) -> Node:
        name = n[1]
        if name in env and env[name][0] == "arrayref":
            name = env[name][1]
        idx: list[int] = []
        for pos, i in enumerate(n[2]):
            e = self.ex(i, env, c, stack)
            value = _const(e, self.mod)
            if value is not None:
                idx.append(value)
                continue
            # an index that depends on variables: a case split over the index's values
            # (Spectra's VarIndexesTranslator splits over the index variable's values)
            dims = self.mod.arrays.get(name)
            if dims is None or pos >= len(dims):
                raise self.fail(c, f"{name}[...]: a define array indexed by a non-constant "
                                "expression is not supported")
            cases = []
            for k in range(dims[pos]):
                sub = ("index", name, (*(("num", j) for j in idx), ("num", k), *n[2][pos + 1:]))
                cases.append((("cmp", "=", e, ("num", k)), self.index(sub, env, c, stack)))
            return ("select", tuple(cases))
        if name in self.mod.arrays:
            dims = self.mod.arrays[name]
            if len(idx) != len(dims) or any(not 0 <= i < d for i, d in zip(idx, dims,
                                                                             strict=True)):
                raise self.fail(c, f"index {name}{idx} outside the array's {list(dims)}")
            return ("id", name + "".join(f"[{i}]" for i in idx), False)
        if name in self.mod.defines:
            dvalue: Any = self.mod.defines[name][0]
            for i in idx:
                if not (isinstance(dvalue, tuple) and dvalue[0] == "array"
                        and 0 <= i < len(dvalue[1])):
                    raise self.fail(c, f"index {name}{idx} outside the define array")
                dvalue = dvalue[1][i]
            if isinstance(dvalue, tuple) and dvalue[0] == "array":
                raise self.fail(c, f"define array {name} indexed by too few indices")
            return self.ex(dvalue, {}, c, (*stack, name))
        raise self.fail(c, f"{name}[...]: {name!r} is not an array")

    def call(self, n: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
             ) -> Node:
        name, args = n[1], n[2]
        if name in self.mod.patterns:
            raise self.fail(c, f"pattern {name!r} used inside a formula (a pattern is a "
                            "whole assumption or guarantee)")
        pred = self.mod.predicates.get(name)
        if pred is None:
            note = (f"; import {self.mod.missing[0]!r} not found" if self.mod.missing
                    else "")
            raise self.fail(c, f"{name}(...): unknown predicate or pattern (not defined in "
                            f"the file or its imports{note})")
        if name in stack:
            raise self.fail(c, f"predicate {name!r} calls itself")
        if len(args) != len(pred.params):
            raise self.fail(c, f"predicate {name!r} takes {len(pred.params)} arguments, "
                            f"{len(args)} given")
        inner = {p: self.arg(a, env, c, stack) for p, a in zip(pred.params, args, strict=True)}
        return self.ex(pred.body, inner, c, (*stack, name))

    def arg(self, a: Node, env: dict[str, Node], c: _Constraint, stack: tuple[str, ...]
            ) -> Node:
        """A predicate's argument: a whole array is passed by reference."""
        if a[0] == "id" and a[1] in env and env[a[1]][0] == "arrayref":
            return env[a[1]]
        if a[0] == "id" and (a[1] in self.mod.arrays or (
                a[1] in self.mod.defines and isinstance(self.mod.defines[a[1]][0], tuple)
                and self.mod.defines[a[1]][0][0] == "array")):
            return ("arrayref", a[1])
        return self.ex(a, env, c, stack)

    def quantifier(self, n: Node, env: dict[str, Node], c: _Constraint,
                   stack: tuple[str, ...]) -> Node:
        _, op, name, typ, body = n
        base, dims, rest = _spectra_type(list(typ), self.mod, c.where or self.mod.where,
                                         c.line)
        if dims or rest:
            raise self.fail(c, f"quantifier over {' '.join(typ)!r}: expected a scalar type")
        values: list[Node]
        count = (2 if base[0] == "bool" else int(base[2]) - int(base[1]) + 1
                 if base[0] == "int" else len(base[1]))
        scale = self.scale * max(count, 1)  # nested quantifiers multiply
        if scale > MAX_IMPORT_CELLS:
            raise self.fail(c, f"{op} over {' '.join(typ)!r}: expands its body {scale:,} "
                            f"times (nested quantifiers multiply), more than "
                            f"{MAX_IMPORT_CELLS:,} (MAX_IMPORT_CELLS), refused before "
                            "expanding it")
        if base[0] == "bool":
            values = [("const", False), ("const", True)]
        elif base[0] == "int":
            values = [("num", k) for k in range(int(base[1]), int(base[2]) + 1)]
        else:
            values = [("id", v, False) for v in base[1]]
        outer, self.scale = self.scale, scale
        try:
            parts = [self.ex(body, {**env, name: v}, c, stack) for v in values]
        finally:
            self.scale = outer
        return _chain("and" if op == "forall" else "or", parts)

    def past_op(self, op: str, args: tuple[Node, ...], c: _Constraint) -> Node:
        key = (op, *args)
        if key in self.past:
            return ("id", self.past[key], False)
        m = self.fresh(f"{op}_aux", ("bool",), c)
        self.past[key] = m
        aux, nxt = ("id", m, False), ("next", ("id", m, False))
        if op == "PREV":  # false at time 0, then the argument's previous value
            self.emit("guarantee", "init", ("not", aux), c)
            self.emit("guarantee", "safety", ("iff", nxt, args[0]), c)
        elif op == "ONCE":
            self.emit("guarantee", "init", ("iff", aux, args[0]), c)
            self.emit("guarantee", "safety", ("iff", nxt, ("or", aux, ("next", args[0]))), c)
        elif op == "HISTORICALLY":
            self.emit("guarantee", "init", ("iff", aux, args[0]), c)
            self.emit("guarantee", "safety", ("iff", nxt, ("and", aux, ("next", args[0]))),
                      c)
        else:  # SINCE (a S b), TRIGGERED (a T b)
            a, b = args
            first = b if op == "SINCE" else ("or", a, b)
            self.emit("guarantee", "init", ("iff", aux, first), c)
            self.emit("guarantee", "safety", ("iff", nxt, ("or", ("next", b),
                                                           ("and", aux, ("next", a)))), c)
        return aux


def _nodes(n: object) -> Iterator[Node]:
    """Every node of a tree (also inside the pairs of a ``select`` and argument tuples)."""
    todo = [n]
    while todo:
        m = todo.pop()
        if not isinstance(m, tuple):
            continue
        if m and isinstance(m[0], str):
            yield m
            todo.extend(m[1:])
        else:
            todo.extend(m)


def _chain(kind: str, parts: Sequence[Node]) -> Node:
    """``parts[0] kind parts[1] kind ...`` as one n-ary node (``kind``: ``and`` or ``or``;
    one part is itself)."""
    return parts[0] if len(parts) == 1 else (kind, *parts)


def _has(n: Node, kind: str) -> bool:
    return any(m[0] == kind for m in _nodes(n))


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
                            semantics=semantics, base=p.parent)


def import_spec_text(text: str, *, fmt: str, where: str = "<spec>", default_name: str = "spec",
                     semantics: str | None = "textbook", base: Path | None = None) -> str:
    """Translate the text of a foreign spec (``fmt``: a value of :data:`FORMATS`) to TOML."""
    try:
        return _import(text, fmt=fmt, where=where, default_name=default_name,
                       semantics=semantics, base=base)
    except RecursionError:  # the backstop of the depth checks: never an internal error
        raise SpecError(f"{where}: formulas nested too deeply to translate (a prefix chain, "
                        f"parentheses, or a recursive pattern or define; the limit is "
                        f"{MAX_FORMULA_DEPTH} levels, MAX_FORMULA_DEPTH)") from None


def _check_depth(constraints: Sequence[_Constraint], where: str) -> None:
    """Refuse a constraint whose tree nests deeper than ``MAX_FORMULA_DEPTH`` (a chain of one
    associative operator, ``a & b & c``, counts as one level, as our specs count n-ary
    ``&``/``|``), or that written out (a shared sub-formula at every use, as the TOML repeats
    it) has more than ``MAX_FORMULA_NODES`` nodes; iterative and linear in the shared tree
    (slugsin's memory buffers), so a file whose buffers double 40 times is refused at once."""
    chains = _CHAINS
    for c in constraints:
        depth: dict[int, int] = {}
        size: dict[int, int] = {}  # nodes written, a shared sub-formula at every use
        stack: list[tuple[Any, bool]] = [(c.body, False)]
        while stack:
            node, done = stack.pop()
            if not isinstance(node, tuple) or id(node) in depth:
                continue
            kids = _children(node)
            if not done:
                stack.append((node, True))
                stack.extend((k, False) for k in kids if id(k) not in depth)
                continue
            d = 0
            for k in kids:
                kd = depth.get(id(k), 0)
                d = max(d, kd if (node[0] in chains and k[0] == node[0]) else kd + 1)
            depth[id(node)] = d
            if d > MAX_FORMULA_DEPTH:
                raise _fail(c.where or where, c.line, f"formula nested deeper than "
                            f"{MAX_FORMULA_DEPTH} levels (MAX_FORMULA_DEPTH)")
            n = size[id(node)] = 1 + sum(size.get(id(k), 1) for k in kids)
            if n > MAX_FORMULA_NODES:
                raise _fail(c.where or where, c.line, f"formula of more than "
                            f"{MAX_FORMULA_NODES:,} operators once its shared parts (memory "
                            "buffers, defines, quantifiers) are written out "
                            "(MAX_FORMULA_NODES), refused before translating it")


def _children(node: Node) -> list[Node]:
    """The sub-formulas of a node: its tuple items, and the items of its argument tuples."""
    out: list[Node] = []
    for k in node[1:]:
        if isinstance(k, tuple) and k:
            if isinstance(k[0], str):
                out.append(k)
            else:
                out += [x for x in k if isinstance(x, tuple) and x and isinstance(x[0], str)]
    return out


def _import(text: str, *, fmt: str, where: str, default_name: str,
            semantics: str | None, base: Path | None) -> str:
    if fmt == "spectra":
        mod = _parse_spectra(text, where, default_name, base)
        spec = mod.spec
        _check_depth(mod.constraints, where)
        spec.constraints = _Expander(mod).run()
    elif fmt == "structuredslugs":
        spec = _parse_structuredslugs(text, where, default_name)
    elif fmt == "slugsin":
        spec = _parse_slugsin(text, where, default_name)
    else:
        raise SpecError(f"{where}: unknown format {fmt!r}")
    _check_depth(spec.constraints, where)
    _primed_justice(spec)
    if not spec.outputs():
        if fmt == "spectra" and not spec.variables and (mod.patterns or mod.predicates):
            raise SpecError(f"{where}: a library of patterns and predicates only (no "
                            "variables): import the specs that use it")
        raise SpecError(f"{where}: no system variable (our specs need at least one output)")
    tr = _Translator(spec, where)
    if fmt == "spectra":
        spec.constraints = _project_initial_assumptions(spec, tr)
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
    out = _toml(spec, sections, semantics)
    size = len(out.encode("utf-8"))
    if size > MAX_INPUT_BYTES:  # never write what no command can read back
        raise SpecError(f"{where}: the translation would be {size:,} bytes of TOML, more than "
                        f"any reader accepts ({MAX_INPUT_BYTES:,} bytes, MAX_INPUT_BYTES); "
                        "nothing written")
    return out


_PROJECTION_CUBES = 64
"""The most cubes a projected initial assumption is written with
(:func:`_project_initial_assumptions`)."""


def _project_initial_assumptions(spec: ImportedSpec, tr: _Translator) -> list[_Constraint]:
    """Spectra's reading of initial assumptions that mention system variables.

    Spectra checks the initial states as ``forall X, Y. theta_e(X, Y) -> exists Y'.
    theta_s(X, Y') & Win(X, Y')`` (spectra-synt ``GameSolver.sysWinAllInitial``: the system's
    variables are quantified only on the right), that is, ``theta_e`` -- the conjunction of
    every initial assumption -- acts through its projection ``exists Y. theta_e`` onto the
    environment's variables. A system variable's domain belongs to the system's initial
    condition there (``PlayerModule.addVar``), so ``Y`` ranges over every code of its bits.
    Our specs' initial assumptions range over inputs only, so the top-level conjuncts of the
    initial assumptions that mention system variables are projected *together* (``exists Y.
    phi_1 & phi_2`` is not ``(exists Y. phi_1) & (exists Y. phi_2)`` when they share a
    variable), with a BDD: nothing is assumed when the projection is ``true``; else it is one
    more initial assumption, ``false`` or a disjunction of disjoint cubes over the inputs'
    bits (:func:`~tli_verify.logic.gr1.disjoint_cubes`; refused by name and line beyond
    :data:`_PROJECTION_CUBES` cubes). Conjuncts over
    environment variables only are kept as they are.
    """
    from tli_verify.logic.gr1 import _to_bdd, disjoint_cubes, new_manager
    from tli_verify.logic.spot_import import spot

    sys_vars = {v.name for v in spec.variables if v.side == "sys"}
    sys_bits = {b for v in spec.variables if v.side == "sys" for b in v.bits()}
    out: list[_Constraint] = []
    mixed: list[tuple[_Constraint, Node]] = []
    for c in spec.constraints:
        if c.side != "assume" or c.slot != "init":
            out.append(c)
            continue
        kept: list[Node] = []
        for part in _flatten(c.body, "and"):
            if any(m[0] == "id" and m[1] in sys_vars for m in _nodes(part)):
                mixed.append((c, part))
            else:
                kept.append(part)
        if kept:
            body = kept[0]
            for part in kept[1:]:
                body = ("and", body, part)
            out.append(_Constraint(c.side, c.slot, body, c.line, c.where))
    if not mixed:
        return out
    texts = [tr.btext(part, primed=False, c=c, stack=()) for c, part in mixed]
    formulas = [spot.formula(t) for t in texts]
    aps = sorted({str(a) for f in formulas for a in spot.atomic_prop_collect(f)})
    bdd = new_manager()
    bdd.declare(*aps)
    u = bdd.true
    for f in formulas:
        u &= _to_bdd(f, bdd, primed=False)
    u = bdd.exist([a for a in aps if a in sys_bits], u)
    first = mixed[0][0]
    if u == bdd.true:
        return out
    cubes = disjoint_cubes(bdd, u, [a for a in aps if a not in sys_bits], _PROJECTION_CUBES)
    if cubes is None:
        raise tr.fail(first, "the initial assumptions over system variables project onto the "
                      f"environment's variables (Spectra's reading) with more than "
                      f"{_PROJECTION_CUBES} cubes")
    text = _or(["(" + " & ".join(a if v else f"!{a}" for a, v in sorted(cube.items())) + ")"
                for cube in cubes])
    out.append(_Constraint("assume", "init", ("raw", text), first.line, first.where))
    return out


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
