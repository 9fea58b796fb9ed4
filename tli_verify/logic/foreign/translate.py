"""From expression trees to Spot formulas, with integers and enumerations bit-blasted.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence

from tli_verify.errors import SpecError
from tli_verify.limits import (
    MAX_INPUT_BYTES,
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
