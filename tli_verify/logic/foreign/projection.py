"""The projection of initial assumptions onto the inputs (a BDD existential projection through
:mod:`tli_verify.logic.gr1`).
"""

from __future__ import annotations

from tli_verify.logic.foreign.expand import (
    _nodes,
)
from tli_verify.logic.foreign.translate import (
    _flatten,
    _or,
    _Translator,
)
from tli_verify.logic.foreign.tree import (
    ImportedSpec,
    Node,
    _Constraint,
)
from tli_verify.logic.gr1 import disjoint_cubes, formula_bdd, new_manager

__all__: list[str] = []

_PROJECTION_CUBES = 64
"""The most cubes a projected initial assumption is written with
(:func:`_project_initial_assumptions`)."""


def _project_initial_assumptions(spec: ImportedSpec, tr: _Translator) -> list[_Constraint]:
    """Spectra's reading of initial assumptions that mention system variables.

    Spectra checks the initial states as ``forall X, Y. theta_e(X, Y) -> exists Y'.
    theta_s(X, Y') & Win(X, Y')`` (spectra-synt ``GameSolver.sysWinAllInitial``: the system's
    variables are quantified only on the right), that is, ``theta_e`` -- the conjunction of
    every initial assumption -- acts through its projection ``exists Y. theta_e`` onto the
    environment's variables. A system variable's domain belongs to the system's initial
    condition there (``PlayerModule.addVar``), so ``Y`` ranges over every code of its bits.
    Our specs' initial assumptions range over inputs only, so the top-level conjuncts of the
    initial assumptions that mention system variables are projected *together* (``exists Y.
    phi_1 & phi_2`` is not ``(exists Y. phi_1) & (exists Y. phi_2)`` when they share a
    variable), with a BDD: nothing is assumed when the projection is ``true``; else it is one
    more initial assumption, ``false`` or a disjunction of disjoint cubes over the inputs'
    bits (:func:`~tli_verify.logic.gr1.disjoint_cubes`; refused by name and line beyond
    :data:`_PROJECTION_CUBES` cubes). Conjuncts over
    environment variables only are kept as they are.
    """
    from tli_verify.logic.spot_import import spot

    sys_vars = {v.name for v in spec.variables if v.side == "sys"}
    sys_bits = {b for v in spec.variables if v.side == "sys" for b in v.bits()}
    out: list[_Constraint] = []
    mixed: list[tuple[_Constraint, Node]] = []
    for c in spec.constraints:
        if c.side != "assume" or c.slot != "init":
            out.append(c)
            continue
        kept: list[Node] = []
        for part in _flatten(c.body, "and"):
            if any(m[0] == "id" and m[1] in sys_vars for m in _nodes(part)):
                mixed.append((c, part))
            else:
                kept.append(part)
        if kept:
            body = kept[0]
            for part in kept[1:]:
                body = ("and", body, part)
            out.append(_Constraint(c.side, c.slot, body, c.line, c.where))
    if not mixed:
        return out
    texts = [tr.btext(part, primed=False, c=c, stack=()) for c, part in mixed]
    formulas = [spot.formula(t) for t in texts]
    aps = sorted({str(a) for f in formulas for a in spot.atomic_prop_collect(f)})
    bdd = new_manager()
    bdd.declare(*aps)
    u = bdd.true
    for f in formulas:
        u &= formula_bdd(f, bdd, primed=False)
    u = bdd.exist([a for a in aps if a in sys_bits], u)
    first = mixed[0][0]
    if u == bdd.true:
        return out
    cubes = disjoint_cubes(bdd, u, [a for a in aps if a not in sys_bits], _PROJECTION_CUBES)
    if cubes is None:
        raise tr.fail(first, "the initial assumptions over system variables project onto the "
                      f"environment's variables (Spectra's reading) with more than "
                      f"{_PROJECTION_CUBES} cubes")
    text = _or(["(" + " & ".join(a if v else f"!{a}" for a, v in sorted(cube.items())) + ")"
                for cube in cubes])
    out.append(_Constraint("assume", "init", ("raw", text), first.line, first.where))
    return out

