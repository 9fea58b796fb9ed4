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

The package, one job per module: :mod:`~tli_verify.logic.foreign.tree` (expression trees, the
imported spec), :mod:`~tli_verify.logic.foreign.parse` (tokenizer and Pratt parser),
:mod:`~tli_verify.logic.foreign.translate` (to Spot formulas, bit-blasting),
:mod:`~tli_verify.logic.foreign.naming`, :mod:`~tli_verify.logic.foreign.spectra` (the Spectra
reader), :mod:`~tli_verify.logic.foreign.expand` (Spectra's derived constructs),
:mod:`~tli_verify.logic.foreign.slugs` (the slugs readers),
:mod:`~tli_verify.logic.foreign.projection` (initial assumptions onto the inputs) and
:mod:`~tli_verify.logic.foreign.emit` (our TOML); this module is the import driver.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tli_verify.errors import SpecError
from tli_verify.io import read_text
from tli_verify.limits import (
    MAX_FORMULA_DEPTH,
    MAX_FORMULA_NODES,
    MAX_INPUT_BYTES,
)
from tli_verify.logic.foreign.emit import (
    _primed_justice,
    _toml,
)
from tli_verify.logic.foreign.expand import (
    _Expander,
)
from tli_verify.logic.foreign.projection import (
    _project_initial_assumptions,
)
from tli_verify.logic.foreign.slugs import (
    _parse_slugsin,
    _parse_structuredslugs,
)
from tli_verify.logic.foreign.spectra import (
    _parse_spectra,
)
from tli_verify.logic.foreign.translate import (
    _Translator,
)
from tli_verify.logic.foreign.tree import (
    _CHAINS,
    FORMATS,
    ImportedSpec,
    Node,
    _Constraint,
    _fail,
)

__all__ = ["FORMATS", "ImportedSpec", "import_spec_file", "import_spec_text"]


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


