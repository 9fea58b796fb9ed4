"""Spectra's derived constructs, expanded into plain GR(1) over fresh auxiliary variables (as
spectra-synt's translators expand them).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.limits import (
    MAX_FORMULA_DEPTH,
    MAX_IMPORT_CELLS,
)
from tli_verify.logic.foreign.naming import (
    _ap_name,
)
from tli_verify.logic.foreign.spectra import (
    _ARRAY_FUNCS,
    _const,
    _declare_typed,
    _spectra_type,
    _SpectraModule,
)
from tli_verify.logic.foreign.tree import (
    _CHAINS,
    Node,
    _Constraint,
    _fail,
)

__all__: list[str] = []

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
