"""Expression trees (tuples) and the values an import builds: variables, constraints, the imported
spec.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tli_verify.errors import SpecError

__all__ = ["FORMATS", "ImportedSpec", "Node"]

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
