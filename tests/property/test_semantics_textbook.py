"""Theorem checked: in the textbook reading (``semantics = "textbook"``: initial conditions and
transition relations exactly as written, Spectra's and slugs' reading), our realizability
verdict equals omega's GR(1) solver given the same initial conditions and actions, on random
small specs whose safety formulas include X-free ``G(p)`` over inputs and outputs (where the
two readings differ)."""

from __future__ import annotations

import contextlib
import io

from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.omega_oracle import omega_realizable
from tli_verify.logic.generate import RandomSpecConfig, random_spec
from tli_verify.logic.gr1 import build_game, solve

CONFIG = RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_safety=3, n_sys_safety=3,
                          n_env_live=1, n_sys_live=1, env_state_safety=0.5)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), semantics=st.sampled_from(["tli", "textbook"]))
def test_verdict_equals_omega_in_the_same_reading(seed: int, semantics: str) -> None:
    spec = random_spec(CONFIG, seed)
    ours = solve(build_game(spec, semantics=semantics), keep_iterates=False).realizable
    with contextlib.redirect_stdout(io.StringIO()):
        theirs = omega_realizable(spec, semantics=semantics)
    assert ours == theirs


def test_the_readings_differ_on_some_random_specs() -> None:
    """The property above is not vacuous: the two readings give different verdicts on a
    fraction of these specs."""
    differ = 0
    for seed in range(60):
        spec = random_spec(CONFIG, 40_000 + seed)
        verdicts = {s: solve(build_game(spec, semantics=s), keep_iterates=False).realizable
                    for s in ("tli", "textbook")}
        differ += verdicts["tli"] != verdicts["textbook"]
    assert differ > 0
