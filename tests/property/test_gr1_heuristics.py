"""Theorem checked: the performance heuristics of Firman, Maoz and Ringert (2020) that
:class:`~tli_verify.logic.gr1.Heuristics` switches (partitioned transition relations with
early quantification, early fixed-point detection, fixed-point recycling, early
unrealizability detection, variable order and grouping, dynamic reordering) change neither
the verdict nor the winning set nor the iterates the strategy is built from, in either
reading of safety; and the verdict equals omega's on the same spec."""

from __future__ import annotations

import contextlib
import io
import itertools
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.omega_oracle import omega_realizable
from tli_verify.logic.generate import RandomSpecConfig, random_spec
from tli_verify.logic.gr1 import HEURISTIC_SWITCHES, Heuristics, build_game, solve

CONFIG = RandomSpecConfig(n_inputs=2, n_outputs=3, n_env_safety=2, n_sys_safety=3,
                          n_env_live=2, n_sys_live=2, env_state_safety=0.3)

# Every combination of the switches that act in the solver, and the build-time ones varied
# one at a time (the order switches only move nodes around).
SOLVER = ("partition", "early_fixpoint", "recycle", "early_unrealizable")
COMBOS = [
    Heuristics(**dict(zip(SOLVER, bits, strict=True)))
    for bits in itertools.product((False, True), repeat=len(SOLVER))
] + [Heuristics(interleave=False, group_pairs=False), Heuristics(group_pairs=True),
     Heuristics(reorder=False), Heuristics(max_growth=1.2), Heuristics(cluster_nodes=1)]


def _in(target: Any, u: Any) -> Any:
    """``u`` copied into the manager ``target`` (managers differ in variable order)."""
    import dd.cudd

    return dd.cudd.copy_bdd(u, target)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), semantics=st.sampled_from(["tli", "textbook"]))
def test_heuristics_change_no_answer(seed: int, semantics: str) -> None:
    spec = random_spec(CONFIG, seed)
    ref_game = build_game(spec, semantics=semantics, heuristics=Heuristics.none())
    ref = solve(ref_game)
    bdd = ref_game.manager
    with contextlib.redirect_stdout(io.StringIO()):
        assert omega_realizable(spec, semantics=semantics) == ref.realizable
    for h in COMBOS:
        game = build_game(spec, semantics=semantics, heuristics=h)
        sol = solve(game)
        assert sol.exact
        assert sol.realizable == ref.realizable
        assert _in(bdd, sol.winning) == ref.winning
        assert [[_in(bdd, y) for y in ring] for ring in sol.rings] == \
            [list(ring) for ring in ref.rings]
        assert [[[_in(bdd, x) for x in layer] for layer in ring] for ring in sol.traps] == \
            [[list(layer) for layer in ring] for ring in ref.traps]
        quick = solve(game, keep_iterates=False, exact=False)
        assert quick.realizable == ref.realizable
        # Stopped early only on an unrealizable spec, with a superset of the winning set.
        assert quick.exact or not quick.realizable
        assert (ref.winning & ~_in(bdd, quick.winning)) == bdd.false


def test_switches_are_named() -> None:
    """Every Boolean switch is listed in HEURISTIC_SWITCHES (benchmarks iterate over it)."""
    fields = {f for f in Heuristics.__dataclass_fields__
              if isinstance(getattr(Heuristics(), f), bool)}
    assert fields == set(HEURISTIC_SWITCHES)


def test_early_unrealizable_stops_before_the_fixpoint() -> None:
    """Not vacuous: on some unrealizable random specs the early check answers with a proper
    superset of the winning set."""
    stopped = 0
    for seed in range(40):
        game = build_game(random_spec(CONFIG, 90_000 + seed))
        quick = solve(game, keep_iterates=False, exact=False)
        if not quick.exact:
            stopped += 1
            assert not quick.realizable
            assert (solve(game).winning & ~quick.winning) == game.false
    assert stopped > 0
