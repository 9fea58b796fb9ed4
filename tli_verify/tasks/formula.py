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
    fn = parser.expr(0)
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
        return TaskError(f"{self.where}: {self.text!r}: {what}")

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

    def expr(self, min_prec: int) -> Node:
        self.depth += 1
        if self.depth > 200:
            raise self.fail("nested deeper than 200 levels")
        left = self.unary()
        while True:
            op = self.peek()
            prec = _PREC.get(op or "")
            if op is None or prec is None or prec < min_prec:
                break
            self.i += 1
            # '->' is right-associative, the others left-associative
            right = self.expr(prec if op == "->" else prec + 1)
            left = _combine(op, left, right)
        self.depth -= 1
        return left

    def unary(self) -> Node:
        tok = self.take()
        if tok == "!":
            inner = self.unary()
            return lambda now, prev, n: ~inner(now, prev, n)
        if tok == "(":
            inner = self.expr(0)
            self.take(")")
            return inner
        if tok == "true":
            return lambda now, prev, n: np.ones(n, dtype=bool)
        if tok == "false":
            return lambda now, prev, n: np.zeros(n, dtype=bool)
        if tok == "prev":
            self.take("(")
            name = self.take()
            if name not in self.prev_names:
                raise self.fail(f"prev({name}): unknown name {name!r}"
                                + _known(self.prev_names))
            self.take(")")
            self.prev.add(name)
            return lambda now, prev, n: prev[name]
        if not is_name(tok):
            raise self.fail(f"unexpected {tok!r}")
        if tok not in self.names:
            raise self.fail(f"unknown name {tok!r}" + _known(self.names))
        self.now.add(tok)
        return lambda now, prev, n: now[tok]


def _known(names: frozenset[str]) -> str:
    shown = sorted(names)
    if not shown:
        return ""
    return f" (known: {', '.join(shown[:12])}{', ...' if len(shown) > 12 else ''})"


def _combine(op: str, a: Node, b: Node) -> Node:
    if op == "&":
        return lambda now, prev, n: a(now, prev, n) & b(now, prev, n)
    if op == "|":
        return lambda now, prev, n: a(now, prev, n) | b(now, prev, n)
    if op == "^":
        return lambda now, prev, n: a(now, prev, n) ^ b(now, prev, n)
    if op == "->":
        return lambda now, prev, n: ~a(now, prev, n) | b(now, prev, n)
    return lambda now, prev, n: a(now, prev, n) == b(now, prev, n)
