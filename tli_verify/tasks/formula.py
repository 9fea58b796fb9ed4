"""Boolean formulas of a task's sensors: region membership now and one step before, and latches.

A task's sensors (the spec's inputs, paper Sec. 3: the robot perceives a sensor reading, never
the state's mode) are boolean formulas over

* ``NAME`` -- the current state lies in region ``NAME`` (a cell of the task's partition, or a
  layer), or the current value of latch ``NAME``;
* ``prev(NAME)`` -- the same one step before (at the first step: the current state's region;
  a latch's initial value);
* ``true``, ``false``, ``!``, ``&``, ``|``, ``->``, ``<->``, ``^`` (exclusive or) and
  parentheses, with the usual precedence (``!`` > ``&`` > ``^`` > ``|`` > ``->`` > ``<->``;
  ``->`` associates to the right).

:func:`parse` checks a formula against the names it may use and returns a :class:`Formula`
whose :meth:`~Formula.evaluate` is vectorised over a batch of states (numpy bool arrays).
No text is ever passed to ``eval``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TaskError
from tli_verify.limits import MAX_FORMULA_DEPTH

__all__ = ["MAX_FORMULA_CHARS", "NAME_PATTERN", "Formula", "is_name", "parse"]

BoolArray = npt.NDArray[np.bool_]
Env = Mapping[str, BoolArray]

NAME_PATTERN = r"[A-Za-z_][A-Za-z0-9_]*"
"""Region, latch and sensor names: identifiers (``-`` would read as part of ``->``)."""
_KEYWORDS = frozenset({"true", "false", "prev"})
MAX_FORMULA_CHARS = 10_000
"""Longest sensor, latch or goal formula accepted (characters)."""
MAX_FORMULA_NODES = 5_000
"""Most operators and names in one formula."""

_TOKEN = re.compile(rf"\s*(?:(<->|->|[!&|^()])|({NAME_PATTERN}))")


def is_name(text: str) -> bool:
    """Whether ``text`` is a valid region, latch or sensor name (not a keyword)."""
    return bool(re.fullmatch(NAME_PATTERN, text)) and text not in _KEYWORDS


@dataclass(frozen=True, slots=True, eq=False)
class Formula:
    """A parsed formula.

    Attributes
    ----------
    text : str
        As written.
    now : frozenset of str
        Names read at the current step.
    prev : frozenset of str
        Names read one step before (``prev(NAME)``).
    """

    text: str
    now: frozenset[str]
    prev: frozenset[str]
    _fn: Callable[[Env, Env, int], BoolArray]

    def evaluate(self, now: Env, prev: Env, batch: int) -> BoolArray:
        """The formula's value for a batch, shape (batch,).

        Parameters
        ----------
        now, prev : mapping of str to ndarray of bool, shape (batch,)
            Every name in :attr:`now` / :attr:`prev`.
        batch : int
        """
        return self._fn(now, prev, batch)


def parse(text: str, *, names: Collection[str], where: str,
          prev_names: Collection[str] | None = None) -> Formula:
    """Parse a sensor, latch or goal formula.

    Parameters
    ----------
    text : str
    names : collection of str
        The names the formula may read now.
    where : str
        ``file: sensors.r`` for messages.
    prev_names : collection of str, optional
        The names ``prev(...)`` may read (default: ``names``).

    Raises
    ------
    TaskError
        (exit 2) A syntax error, an unknown name, a formula over the length or size limits.
    """
    if not isinstance(text, str) or not text.strip():
        raise TaskError(f"{where}: expected a non-empty formula string")
    if len(text) > MAX_FORMULA_CHARS:
        raise TaskError(f"{where}: formula longer than {MAX_FORMULA_CHARS} characters")
    tokens: list[str] = []
    pos = 0
    stripped = text.rstrip()
    while pos < len(stripped):
        m = _TOKEN.match(stripped, pos)
        if m is None:
            raise TaskError(f"{where}: {text!r}: unexpected character "
                            f"{stripped[pos:].lstrip()[:1]!r} at column {pos + 1}")
        tokens.append(m.group(1) or m.group(2))
        pos = m.end()
    if len(tokens) > MAX_FORMULA_NODES:
        raise TaskError(f"{where}: more than {MAX_FORMULA_NODES} operators and names")
    parser = _Parser(tokens, text, where, frozenset(names),
                     frozenset(names if prev_names is None else prev_names))
    fn, _ = parser.expr(0)
    if parser.i != len(tokens):
        raise TaskError(f"{where}: {text!r}: unexpected {tokens[parser.i]!r}")
    return Formula(text=text, now=frozenset(parser.now), prev=frozenset(parser.prev), _fn=fn)


Node = Callable[[Env, Env, int], BoolArray]
_BINARY = (("<->", 1), ("->", 2), ("|", 3), ("^", 4), ("&", 5))
_PREC = dict(_BINARY)


class _Parser:
    """Precedence climbing over the token list; builds closures (no eval)."""

    def __init__(self, tokens: list[str], text: str, where: str, names: frozenset[str],
                 prev_names: frozenset[str]) -> None:
        self.t = tokens
        self.i = 0
        self.text = text
        self.where = where
        self.names = names
        self.prev_names = prev_names
        self.now: set[str] = set()
        self.prev: set[str] = set()
        self.depth = 0

    def fail(self, what: str) -> TaskError:
        shown = self.text if len(self.text) <= 80 else self.text[:77] + "..."
        return TaskError(f"{self.where}: {shown!r}: {what}")

    def peek(self) -> str | None:
        return self.t[self.i] if self.i < len(self.t) else None

    def take(self, want: str | None = None) -> str:
        tok = self.peek()
        if tok is None:
            raise self.fail("unexpected end of formula"
                            + (f" (expected {want!r})" if want else ""))
        if want is not None and tok != want:
            raise self.fail(f"expected {want!r}, got {tok!r}")
        self.i += 1
        return tok

    def enter(self) -> None:
        self.depth += 1
        if self.depth > MAX_FORMULA_DEPTH:
            raise self.fail(f"nested deeper than {MAX_FORMULA_DEPTH} levels "
                            "(MAX_FORMULA_DEPTH)")

    def expr(self, min_prec: int) -> tuple[Node, int]:
        """The expression from here, and the depth of the closures it builds (a chain of one
        associative operator, ``a & b & c``, is one level: it is evaluated in a loop)."""
        self.enter()
        left, depth = self.unary()
        while True:
            op = self.peek()
            prec = _PREC.get(op or "")
            if op is None or prec is None or prec < min_prec:
                break
            self.i += 1
            if op == "->":  # right-associative
                right, rd = self.expr(prec)
                left, depth = _chain(op, [left, right]), max(depth, rd) + 1
            else:  # left-associative: the whole chain of this operator, one node
                parts, deepest = [left], depth
                while True:
                    right, rd = self.expr(prec + 1)
                    parts.append(right)
                    deepest = max(deepest, rd)
                    if self.peek() != op:
                        break
                    self.i += 1
                left, depth = _chain(op, parts), deepest + 1
            if depth > MAX_FORMULA_DEPTH:
                raise self.fail(f"operators nested deeper than {MAX_FORMULA_DEPTH} levels "
                                "(MAX_FORMULA_DEPTH)")
        self.depth -= 1
        return left, depth

    def unary(self) -> tuple[Node, int]:
        tok = self.take()
        if tok == "!":
            self.enter()
            inner, depth = self.unary()
            self.depth -= 1
            return (lambda now, prev, n: ~inner(now, prev, n)), depth + 1
        if tok == "(":
            node = self.expr(0)
            self.take(")")
            return node
        if tok == "true":
            return (lambda now, prev, n: np.ones(n, dtype=bool)), 0
        if tok == "false":
            return (lambda now, prev, n: np.zeros(n, dtype=bool)), 0
        if tok == "prev":
            self.take("(")
            name = self.take()
            if name not in self.prev_names:
                raise self.fail(f"prev({name}): unknown name {name!r}"
                                + _known(self.prev_names))
            self.take(")")
            self.prev.add(name)
            return (lambda now, prev, n: prev[name]), 0
        if not is_name(tok):
            raise self.fail(f"unexpected {tok!r}")
        if tok not in self.names:
            raise self.fail(f"unknown name {tok!r}" + _known(self.names))
        self.now.add(tok)
        return (lambda now, prev, n: now[tok]), 0


def _known(names: frozenset[str]) -> str:
    shown = sorted(names)
    if not shown:
        return ""
    return f" (known: {', '.join(shown[:12])}{', ...' if len(shown) > 12 else ''})"


def _chain(op: str, parts: list[Node]) -> Node:
    """``parts[0] op parts[1] op ...`` (left to right; ``->`` takes exactly two), evaluated
    in a loop, so a long chain never recurses."""
    if op == "->":
        a, b = parts
        return lambda now, prev, n: ~a(now, prev, n) | b(now, prev, n)
    step: Callable[[BoolArray, BoolArray], BoolArray] = {
        "&": np.logical_and, "|": np.logical_or, "^": np.logical_xor,
        "<->": np.equal}[op]
    first, rest = parts[0], tuple(parts[1:])

    def chained(now: Env, prev: Env, n: int) -> BoolArray:
        out = first(now, prev, n)
        for p in rest:
            out = step(out, p(now, prev, n))
        return out

    return chained
