"""An explicit evaluator of GR(1) formulas on assignments, independent of our BDD code."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def holds(f: Any, cur: Mapping[str, bool], nxt: Mapping[str, bool] | None = None) -> bool:
    """Truth of a propositional formula with X at depth <= 1 on (current, next) assignments."""
    import spot

    k = f.kind()
    if k == spot.op_tt:
        return True
    if k == spot.op_ff:
        return False
    if k == spot.op_ap:
        return bool(cur[str(f.ap_name())])
    if k == spot.op_X:
        assert nxt is not None
        return holds(f[0], nxt, None)
    vals = [holds(c, cur, nxt) for c in f]
    if k == spot.op_Not:
        return not vals[0]
    if k == spot.op_And:
        return all(vals)
    if k == spot.op_Or:
        return any(vals)
    if k == spot.op_Implies:
        return (not vals[0]) or vals[1]
    if k == spot.op_Equiv:
        return vals[0] == vals[1]
    if k == spot.op_Xor:
        return vals[0] != vals[1]
    raise AssertionError(f"unexpected operator in {f}")


def conjuncts(f: Any) -> list[Any]:
    import spot

    if f.kind() == spot.op_And:
        return [g for c in f for g in conjuncts(c)]
    return [f]


def body(f: Any) -> Any:
    """G(phi) -> phi; GF(p) -> p; constants unchanged."""
    import spot

    if f.kind() in (spot.op_tt, spot.op_ff):
        return f
    if f.kind() == spot.op_G and f[0].kind() == spot.op_F:
        return f[0][0]
    return f[0]
