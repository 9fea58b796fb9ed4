"""LTL formulas: parsing with Spot and classification into the GR(1) slots.

A GR(1) specification (paper Sec. 4.2, eq. 3; Piterman, Pnueli and Sa'ar 2006) has three
slots on each side:

* ``init``: a propositional formula;
* ``safety``: ``G(phi)`` with ``phi`` propositional over the current state and ``X`` applied
  to propositional sub-formulas only (``X`` at depth <= 1);
* ``liveness``: ``GF(p)`` with ``p`` propositional.

Formulas use Spot's LTL syntax (``!``, ``&``, ``|``, ``->``, ``<->``, ``X``, ``G``, ``F``,
``U``, ``true``) and are parsed by Spot itself (Duret-Lutz et al., ATVA 2016), the library the
paper used. Anything outside its slot raises :class:`~tli_verify.errors.SpecError` naming the
offending sub-formula.
"""

from __future__ import annotations

import itertools
import operator
import re
from dataclasses import dataclass
from enum import Enum
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.limits import MAX_FORMULA_DEPTH, MAX_FORMULA_NODES

__all__ = [
    "AP_PATTERN",
    "MAX_FORMULA_DEPTH",
    "MAX_FORMULA_NODES",
    "RESERVED",
    "Slot",
    "atomic_propositions",
    "classify",
    "gr1_body",
    "parse_formula",
]

AP_PATTERN = re.compile(r"^[a-z_][a-z0-9_]*$")
"""Allowed names of atomic propositions: lower-case identifiers (Spot reads capitals as
operators: ``G``, ``F``, ``X``, ``U``, ``W``, ``R``, ``M``)."""

RESERVED = frozenset({"true", "false", "xor", "implies", "equiv"})


_FORMULA_CHARS = frozenset(
    "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_ \t\r\n!&|-<>=^~()/\\"
)
"""Characters a formula may use. Spot's PSL/SERE syntax (``[]``, ``{}``, ``;``, ``*``, ranges
``F[1:3]``, quoted names) is not GR(1), and on some malformed inputs (``[] [] X X []``) Spot's
parser needs seconds to recover: such text is refused before it reaches Spot."""
_NOT_FORMULA_CHAR = re.compile("[^" + re.escape("".join(sorted(_FORMULA_CHARS))) + "]")
"""A character outside :data:`_FORMULA_CHARS` (a regular expression: the scan of a long
formula's text runs in C)."""


class Slot(Enum):
    """The GR(1) slot a formula must fit."""

    INIT = "init"
    SAFETY = "safety"
    LIVENESS = "liveness"


def _spot() -> Any:
    from tli_verify.logic.spot_import import spot

    return spot


def parse_formula(text: str, *, where: str, max_nodes: int | None = MAX_FORMULA_NODES,
                  max_depth: int = MAX_FORMULA_DEPTH,
                  memo: dict[int, tuple[int, int, Any]] | None = None) -> Any:
    """Parse ``text`` with Spot.

    Parameters
    ----------
    text : str
        Formula in Spot's LTL syntax.
    where : str
        Location used in error messages (e.g. ``"specs/scoop.toml:23 guarantee.safety[0]"``).
    max_nodes : int or None
        Most operator nodes of the parsed formula (None: no limit, for formulas the tool
        builds from checked parts). The text's length is bounded only by the file's byte
        cap (:data:`tli_verify.limits.MAX_INPUT_BYTES`): what costs is the formula's size
        and depth, not its spelling.
    max_depth : int
        Deepest nesting accepted (parentheses in the text, runs of prefix operators before
        Spot parses it, operators in the parsed formula).
    memo : dict, optional
        Shared with :func:`formula_stats` over the formulas of one spec (Spot shares equal
        sub-formulas between formulas too), so that each distinct sub-formula is measured
        once per spec.

    Returns
    -------
    spot.formula
        The parsed formula.

    Raises
    ------
    SpecError
        On a syntax error, or on PSL/SERE syntax, which GR(1) does not use.
    """
    if not isinstance(text, str):
        raise SpecError(f"{where}: expected a formula string, got {type(text).__name__}")
    if not text.strip():
        raise SpecError(f"{where}: empty formula")
    if "\x00" in text:
        raise SpecError(f"{where}: formula contains a NUL character")
    found = _NOT_FORMULA_CHAR.search(text)
    if found is not None:
        bad = found.group()
        raise SpecError(f"{where}: character {bad!r} is not allowed in a formula (GR(1) "
                        "formulas use identifiers, true, false, ! & | -> <-> ^ X G F U W R M "
                        "and parentheses)")
    if _paren_depth(text) > max_depth:
        raise SpecError(f"{where}: formula nests parentheses deeper than the limit of "
                        f"{max_depth} levels")
    if _prefix_run(text) > max_depth:  # Spot's own recursion dies on ~10^5 nested X
        raise SpecError(f"{where}: formula nests operators deeper than the limit of "
                        f"{max_depth} levels")
    spot = _spot()
    try:
        f = spot.formula(text)
    except SyntaxError as exc:
        raise SpecError(f"{where}: cannot parse {text!r}: {_first_message(str(exc))}") from None
    except (RuntimeError, ValueError, TypeError) as exc:  # Spot's other parser failures
        raise SpecError(f"{where}: cannot parse {text!r}: {' '.join(str(exc).split())}"
                        ) from None
    if not f.is_ltl_formula():
        raise SpecError(f"{where}: {text!r} uses PSL/SERE operators; GR(1) specs use LTL only")
    if _node_bound(text) <= min(max_depth, max_nodes or max_depth):
        return f  # both limits hold: depth <= size <= _node_bound(text)
    depth, size = formula_stats(f, memo=memo)
    if depth > max_depth:
        raise SpecError(f"{where}: formula nests operators deeper than the limit of "
                        f"{max_depth} levels")
    if max_nodes is not None and size > max_nodes:
        raise SpecError(f"{where}: formula has {size} operator nodes (counting shared "
                        f"sub-formulas at each use), more than the limit of {max_nodes}")
    return f


def _node_bound(text: str) -> int:
    """An upper bound on the operator nodes of the formula Spot parses from ``text``: its
    characters other than blanks and parentheses. Every node of the parsed tree is written
    with at least one character of its own (an atom, a constant or an operator; ``GFa`` is
    three nodes in three characters), n-ary operators fold several written operators into
    one node, and Spot's trivial rewritings only shrink the tree. Without PSL/SERE syntax
    (:data:`_FORMULA_CHARS` refuses it) nothing expands, so the bound lets
    :func:`parse_formula` skip measuring short formulas, most of a spec's parse time."""
    return len(text) - sum(text.count(ch) for ch in " \t\r\n()")


def _paren_depth(text: str) -> int:
    """Deepest nesting of ``(`` in ``text`` (unbalanced text is Spot's to reject: a ``)``
    without its ``(`` counts from depth 0 again).

    The depth after each parenthesis is the walk ``S`` of +1 and -1 clamped at 0, i.e.
    ``S_i - min(0, min_{k <= i} S_k)``; computed with C-level iteration (``accumulate``,
    ``map``), which long imported formulas need."""
    parens = _NOT_PAREN.sub("", text)
    if "(" not in parens:
        return 0
    walk = list(itertools.accumulate(map(_PAREN_STEP.__getitem__, parens)))
    floor = itertools.accumulate(walk, min, initial=0)  # min(0, S_1, ..., S_i)
    next(floor)
    return max(map(operator.sub, walk, floor))


_NOT_PAREN = re.compile(r"[^()]+")
_PAREN_STEP = {"(": 1, ")": -1}


def _prefix_run(text: str) -> int:
    """Longest run of prefix operators (``! ~ X G F``) and ``(`` with nothing else between
    them: a lower bound on the parsed formula's depth, computed before Spot parses it.
    Atomic propositions are lower-case, so capitals are operators; blanks do not break a
    run (``text`` has only :data:`_FORMULA_CHARS`, whose blanks are ASCII)."""
    solid = text.translate(_DELETE_BLANKS)
    runs = _PREFIX_RUN.findall(solid)  # the runs of two or more, in C
    if runs:
        return max(map(len, runs))
    return 1 if _PREFIX_OPERATOR.search(solid) else 0


_DELETE_BLANKS = str.maketrans("", "", " \t\r\n")
_PREFIX_RUN = re.compile(r"[!~XGF(]{2,}")
_PREFIX_OPERATOR = re.compile(r"[!~XGF(]")


def formula_depth(f: Any, *, limit: int = MAX_FORMULA_DEPTH) -> int:
    """Operator nesting depth of a parsed formula (an atom has depth 1), without recursion.

    Spot shares equal sub-formulas (the formula is a DAG: ``F[1:3] F[1:3] ... a`` expands to
    a tree exponentially larger than its text), so depths are computed once per distinct
    sub-formula. ``limit`` is accepted for symmetry with the callers and not needed for speed.
    """
    del limit
    return formula_stats(f)[0]


def formula_stats(f: Any, *, memo: dict[int, tuple[int, int, Any]] | None = None
                  ) -> tuple[int, int]:
    """``(depth, size)`` of a parsed formula: nesting depth, and the number of operator
    nodes of its tree (sub-formulas counted at every occurrence), by dynamic programming over
    Spot's shared DAG (no recursion; linear in the number of distinct sub-formulas).

    ``memo`` (Spot's formula id -> depth, size and the formula, which it keeps alive so that
    the id stays its own) may be shared between calls."""
    memo = {} if memo is None else memo
    stack: list[tuple[Any, bool]] = [(f, False)]
    while stack:
        g, expanded = stack.pop()
        key = g.id()
        if key in memo:
            continue
        children = list(g)
        if expanded:
            stats = [memo[c.id()] for c in children]
            memo[key] = (1 + max((d for d, _, _ in stats), default=0),
                         1 + sum(n for _, n, _ in stats), g)
        else:
            stack.append((g, True))
            stack.extend((c, False) for c in children if c.id() not in memo)
    depth, size, _ = memo[f.id()]
    return depth, size


def atomic_propositions(f: Any) -> set[str]:
    """Names of the atomic propositions occurring in ``f``."""
    spot = _spot()
    return {str(ap.ap_name()) for ap in spot.atomic_prop_collect(f)}


def _first_message(diagnostic: str) -> str:
    """The first human message of Spot's multi-line parse diagnostic."""
    for line in diagnostic.splitlines():
        line = line.strip()
        if line and not line.startswith(">>>") and set(line) != {"^"}:
            return line
    return "syntax error"


@dataclass(frozen=True, slots=True)
class _Offence:
    sub: str
    reason: str


def _next_depth_offence(f: Any, *, under_x: bool) -> _Offence | None:
    """Check ``f`` is propositional with ``X`` applied to propositional sub-formulas only."""
    spot = _spot()
    kind = f.kind()
    if kind == spot.op_X:
        if under_x:
            return _Offence(str(f), "nested X (X at depth > 1)")
        return _next_depth_offence(f[0], under_x=True)
    if f.is_boolean():
        return None
    if kind in (spot.op_Not, spot.op_And, spot.op_Or, spot.op_Implies, spot.op_Equiv,
                spot.op_Xor):
        for child in f:
            off = _next_depth_offence(child, under_x=under_x)
            if off is not None:
                return off
        return None
    return _Offence(str(f), f"temporal operator {f.kindstr()} not allowed here")


def _safety_offence(f: Any) -> _Offence | None:
    spot = _spot()
    kind = f.kind()
    if kind in (spot.op_tt, spot.op_ff):  # Spot folds e.g. G(a | !a) to true
        return None
    if kind == spot.op_And:
        for child in f:
            off = _safety_offence(child)
            if off is not None:
                return off
        return None
    if kind != spot.op_G:
        return _Offence(str(f), "not G(p) with p propositional and X at depth <= 1")
    return _next_depth_offence(f[0], under_x=False)


def _liveness_offence(f: Any) -> _Offence | None:
    spot = _spot()
    if f.kind() in (spot.op_tt, spot.op_ff):  # Spot folds GF(true) to true
        return None
    if f.kind() == spot.op_And:
        for child in f:
            off = _liveness_offence(child)
            if off is not None:
                return off
        return None
    if f.kind() != spot.op_G or f[0].kind() != spot.op_F:
        return _Offence(str(f), "not GF(p)")
    inner = f[0][0]
    if not inner.is_boolean():
        return _Offence(str(inner), "not propositional inside GF(p)")
    return None


def classify(f: Any, slot: Slot, *, where: str) -> None:
    """Check that the parsed formula ``f`` fits its GR(1) ``slot``.

    Raises
    ------
    SpecError
        Naming ``where``, the offending sub-formula and why (e.g. ``F G a``: "not GF(p)").
    """
    if slot is Slot.INIT:
        off = None if f.is_boolean() else _Offence(str(f), "not propositional")
    elif slot is Slot.SAFETY:
        off = _safety_offence(f)
    else:
        off = _liveness_offence(f)
    if off is not None:
        sub = off.sub if len(off.sub) <= 200 else off.sub[:200] + "..."
        raise SpecError(f"{where}: {sub!r}: {off.reason}")


def is_ap_name(name: str) -> bool:
    """True if ``name`` is a valid atomic-proposition name."""
    return bool(AP_PATTERN.match(name)) and name not in RESERVED


def gr1_body(f: Any, slot: Slot) -> Any:
    """The propositional body of one conjunct of a classified formula.

    ``G(phi)`` gives ``phi``, ``GF(p)`` gives ``p``; a constant (Spot folds ``G(true)`` to
    ``true``) is its own body.
    """
    spot = _spot()
    if f.kind() in (spot.op_tt, spot.op_ff):
        return f
    if slot is Slot.SAFETY:
        return f[0]
    if slot is Slot.LIVENESS:
        return f[0][0]
    return f
