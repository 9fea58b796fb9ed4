"""Seeded random GR(1) specs, for cross-checks against independent solvers and benchmarks.

Formulas are random propositional trees over the declared APs. Safety formulas have the shape
``G(p -> X q)`` or ``G(p)``, liveness ``GF(p)``; the mix yields both realizable and
unrealizable specs. Same seed, same spec.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tli_verify.logic.spec import GR1Spec, parse_spec

__all__ = ["RandomSpecConfig", "random_spec", "random_spec_text"]


@dataclass(frozen=True, slots=True)
class RandomSpecConfig:
    """Shape of a random spec.

    Attributes
    ----------
    n_inputs, n_outputs : int
        Numbers of environment and system APs.
    n_env_safety, n_sys_safety, n_env_live, n_sys_live : int
        Numbers of formulas per slot.
    depth : int
        Depth of the random propositional trees.
    """

    n_inputs: int = 3
    n_outputs: int = 3
    n_env_safety: int = 2
    n_sys_safety: int = 3
    n_env_live: int = 1
    n_sys_live: int = 2
    depth: int = 2


def _prop(rng: np.random.Generator, names: list[str], depth: int) -> str:
    if depth <= 0 or rng.random() < 0.3:
        name = names[int(rng.integers(len(names)))]
        return name if rng.random() < 0.6 else f"!{name}"
    op = ("&", "|", "->")[int(rng.integers(3))]
    left = _prop(rng, names, depth - 1)
    right = _prop(rng, names, depth - 1)
    return f"({left} {op} {right})"


def random_spec_text(config: RandomSpecConfig, seed: int) -> str:
    """TOML text of a random GR(1) spec."""
    rng = np.random.default_rng(seed)
    xs = [f"x{i}" for i in range(config.n_inputs)]
    ys = [f"y{i}" for i in range(config.n_outputs)]
    allv = xs + ys

    def quoted(items: list[str]) -> str:
        return "[" + ", ".join(f'"{s}"' for s in items) + "]"

    env_safety = []
    for _ in range(config.n_env_safety):
        pre = _prop(rng, allv, config.depth)
        post = _prop(rng, xs, config.depth)
        env_safety.append(f"G({pre} -> X{post})")
    sys_safety = []
    for _ in range(config.n_sys_safety):
        if rng.random() < 0.25:
            sys_safety.append(f"G({_prop(rng, allv, config.depth)})")
        else:
            pre = _prop(rng, allv, config.depth)
            post = _prop(rng, allv, config.depth)
            sys_safety.append(f"G({pre} -> X{post})")
    env_live = [f"GF({_prop(rng, allv, config.depth)})" for _ in range(config.n_env_live)]
    sys_live = [f"GF({_prop(rng, allv, config.depth)})" for _ in range(config.n_sys_live)]
    env_init = _prop(rng, xs, 1)
    sys_init = _prop(rng, allv, 1)
    return "\n".join([
        f'name = "random-{seed}"',
        f"inputs = {quoted(xs)}",
        f"outputs = {quoted(ys)}",
        "[assume]",
        f'init = "{env_init}"',
        f"safety = {quoted(env_safety)}",
        f"liveness = {quoted(env_live)}",
        "[guarantee]",
        f'init = "{sys_init}"',
        f"safety = {quoted(sys_safety)}",
        f"liveness = {quoted(sys_live)}",
        "",
    ])


def random_spec(config: RandomSpecConfig, seed: int) -> GR1Spec:
    """A random GR(1) spec (see :func:`random_spec_text`)."""
    return parse_spec(random_spec_text(config, seed), path=f"<random-{seed}>")
