"""Our names for imported variables: lower-case AP names, clashes refused.
"""

from __future__ import annotations

import re

from tli_verify.logic.foreign.tree import (
    ImportedSpec,
    _fail,
    _Var,
)

__all__: list[str] = []

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
