"""The tokenizer and the Pratt parser shared by Spectra and structured slugs.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from tli_verify.errors import SpecError
from tli_verify.limits import (
    MAX_FORMULA_DEPTH,
)
from tli_verify.logic.foreign.tree import (
    _CHAINS,
    Node,
    _fail,
)

__all__: list[str] = []

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
