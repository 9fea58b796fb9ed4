"""An independent GR(1) solver for cross-checks: omega (Filippidis), not our fixpoint code.

The translation here is the textbook one, built with omega's own operators (not our code):
every safety formula ``G(phi)`` goes into the player's action as written (``X v`` -> ``v'``),
and, since ``G(phi)`` holds at every position the first included, its current-state
consequence (where the player's actions can continue forever: ``nu C. exists next. action &
C'``; for the assumptions with the outputs quantified as well) is added to the player's
initial condition and, primed, to its action. For an ``X``-free ``phi`` this is the textbook
``init & phi``, ``action & phi'``. The initial conditions given to omega are thus stated the
way our solver states them (docs/explanation/logic.md, "From spec to automaton").
Settings: ``plus_one=False, moore=False, qinit='\\A \\E'`` (Mealy, standard GR(1)).
"""

from __future__ import annotations

from typing import Any

from tli_verify.logic.spec import GR1Spec


def _expr(f: Any, primed: bool = False) -> str:
    import spot

    k = f.kind()
    if k == spot.op_tt:
        return "TRUE"
    if k == spot.op_ff:
        return "FALSE"
    if k == spot.op_ap:
        return str(f.ap_name()) + ("'" if primed else "")
    if k == spot.op_X:
        return _expr(f[0], True)
    args = [_expr(c, primed) for c in f]
    if k == spot.op_Not:
        return f"(~ {args[0]})"
    if k == spot.op_And:
        return "(" + r" /\ ".join(args) + ")"
    if k == spot.op_Or:
        return "(" + r" \/ ".join(args) + ")"
    if k == spot.op_Implies:
        return f"({args[0]} => {args[1]})"
    if k == spot.op_Equiv:
        return f"({args[0]} <=> {args[1]})"
    if k == spot.op_Xor:
        return f"(~ ({args[0]} <=> {args[1]}))"
    raise ValueError(str(f))


def _strip_g(f: Any) -> list[Any]:
    import spot

    if f.kind() == spot.op_And:
        out = []
        for c in f:
            out += _strip_g(c)
        return out
    if f.kind() in (spot.op_tt, spot.op_ff):
        return [f]
    return [f[0]]


def _unf(f: Any) -> Any:
    import spot

    return f if f.kind() in (spot.op_tt, spot.op_ff) else f[0]


def omega_automaton(spec: GR1Spec, *, semantics: str | None = None) -> Any:
    """The omega ``temporal.Automaton`` of ``spec`` (textbook translation).

    ``semantics`` (default: the spec's): ``"tli"`` adds each side's safety consequence at
    time 0 (:func:`_time_zero`); ``"textbook"`` (Spectra, slugs) gives omega the initial
    conditions and actions exactly as written."""
    from omega.symbolic import temporal as trl

    aut = trl.Automaton()
    aut.declare_variables(**{v: "bool" for v in spec.inputs + spec.outputs})
    aut.varlist["env"] = list(spec.inputs)
    aut.varlist["sys"] = list(spec.outputs)

    def conj(parts: list[str]) -> str:
        return r" /\ ".join(parts) if parts else "TRUE"

    aut.init["env"] = aut.add_expr(conj([_expr(f.ltl) for f in spec.assume.init]))
    aut.init["sys"] = aut.add_expr(conj([_expr(f.ltl) for f in spec.guarantee.init]))
    aut.action["env"] = aut.add_expr(
        conj([_expr(g) for f in spec.assume.safety for g in _strip_g(f.ltl)]))
    aut.action["sys"] = aut.add_expr(
        conj([_expr(g) for f in spec.guarantee.safety for g in _strip_g(f.ltl)]))
    if (spec.semantics if semantics is None else semantics) == "tli":
        _time_zero(aut, spec)
    env_live = [_expr(_unf(g)) for f in spec.assume.liveness for g in _strip_g(f.ltl)]
    sys_live = [_expr(_unf(g)) for f in spec.guarantee.liveness for g in _strip_g(f.ltl)]
    aut.win["<>[]"] = aut.bdds_from(*[f"~ ({p})" for p in env_live] or ["FALSE"])
    aut.win["[]<>"] = aut.bdds_from(*sys_live or ["TRUE"])
    aut.qinit = r"\A \E"
    aut.moore = False
    aut.plus_one = False
    return aut


def _closure(aut: Any, action: Any, current: list[str], quantified: list[str]) -> Any:
    """``nu C. exists quantified. action & C'`` with ``C`` over ``current`` (omega operators)."""
    c = aut.true
    while True:
        new = aut.exist(quantified, action & aut.replace_with_primed(current, c))
        if new == c:
            return c
        c = new


def _time_zero(aut: Any, spec: GR1Spec) -> None:
    """Add each side's safety consequence to its initial condition and (primed) action."""
    xs, ys = list(spec.inputs), list(spec.outputs)
    xp, yp = [v + "'" for v in xs], [v + "'" for v in ys]
    safe_e = _closure(aut, aut.action["env"], xs, ys + xp)
    safe_s = _closure(aut, aut.action["sys"], xs + ys, xp + yp)
    aut.init["env"] = aut.init["env"] & safe_e
    aut.init["sys"] = aut.init["sys"] & safe_s
    aut.action["env"] = aut.action["env"] & aut.replace_with_primed(xs, safe_e)
    aut.action["sys"] = aut.action["sys"] & aut.replace_with_primed(xs + ys, safe_s)


def omega_realizable(spec: GR1Spec, *, semantics: str | None = None) -> bool:
    """Realizability of ``spec`` decided by omega's GR(1) solver (in ``semantics``, default
    the spec's own)."""
    from omega.games import gr1

    aut = omega_automaton(spec, semantics=semantics)
    z, _, _ = gr1.solve_streett_game(aut)
    return bool(gr1.is_realizable(z, aut))
