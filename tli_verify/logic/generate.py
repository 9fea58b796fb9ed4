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
    env_state_safety : float
        Probability that an environment safety formula is ``X``-free, ``G(p)`` over the
        current inputs and outputs (these constrain the initial state too; 0 draws none and
        keeps the specs of earlier versions seed for seed).
    """

    n_inputs: int = 3
    n_outputs: int = 3
    n_env_safety: int = 2
    n_sys_safety: int = 3
    n_env_live: int = 1
    n_sys_live: int = 2
    depth: int = 2
    env_state_safety: float = 0.0


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
        if config.env_state_safety > 0 and rng.random() < config.env_state_safety:
            env_safety.append(f"G({_prop(rng, allv, config.depth)})")
            continue
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


def chain_spec_text(n_modes: int) -> str:
    """A scalable, realizable task spec: a chain of ``n_modes`` modes (like color tracing).

    Sensor ``ti`` says the robot is in region ``i`` (one-hot); mode ``mi`` runs there. The
    environment moves from region ``i`` to ``i+1`` (progress) or back to region 0 (a perturbation);
    the last region holds. ``p`` marks perturbations and the goal is ``GF(last | p)``.
    ``2 * n_modes + 1`` variables.
    """
    if n_modes < 2:
        raise ValueError("a chain needs at least 2 modes")
    ts = [f"t{i}" for i in range(n_modes)]
    ms = [f"m{i}" for i in range(n_modes)]

    def region(i: int) -> str:
        return " & ".join(t if k == i else f"!{t}" for k, t in enumerate(ts))

    env_safety = []
    for i in range(n_modes - 1):
        nxt = sorted({i, i + 1, 0})
        env_safety.append(f"G(({region(i)}) -> X(" + " | ".join(f"({region(k)})" for k in nxt)
                          + "))")
    env_safety.append(f"G(({region(n_modes - 1)}) -> X({region(n_modes - 1)}))")
    fairness = [f"GF(!{ms[i]} | !({region(i)}))" for i in range(n_modes - 1)]
    sys_safety = [f"G({ms[i]} -> X({ms[i]} | {ms[i + 1]} | {ms[0]}))"
                  for i in range(n_modes - 1)]
    sys_safety.append(f"G({ms[-1]} -> X {ms[-1]})")
    perturbed = " | ".join(f"({ms[i]} & X {ms[0]})" for i in range(1, n_modes - 1)) or "false"
    sys_safety.append(f"G(X p <-> ({perturbed}))")

    def quoted(items: list[str]) -> str:
        return "[" + ", ".join(f'"{s}"' for s in items) + "]"

    modes = "\n".join(f'{m} = "{region(i)}"' for i, m in enumerate(ms))
    return "\n".join([
        f'name = "chain-{n_modes}"',
        f"inputs = {quoted(ts)}",
        f"outputs = {quoted([*ms, 'p'])}",
        "[modes]",
        modes,
        "[assume]",
        f'init = "{region(0)}"',
        f"safety = {quoted(env_safety)}",
        f"liveness = {quoted(fairness)}",
        "[guarantee]",
        f'init = "{ms[0]} & !p"',
        f"safety = {quoted(sys_safety)}",
        f'liveness = ["GF({ms[-1]} | p)"]',
        "",
    ])
