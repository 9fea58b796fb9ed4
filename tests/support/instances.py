"""Shared problem instances of the tests and benchmarks (one copy, imported by both)."""

from __future__ import annotations

import numpy as np

CHAIN_SPEC = """
name = "chain"
inputs = ["u", "v"]
outputs = ["a", "b", "c", "p"]
[modes]
a = "!u & !v"
b = "u & !v"
c = "!u & v"
[assume]
init = "!u & !v"
safety = [
  "G((!u & !v) -> X((!u & !v) | (u & !v)))",
  "G((u & !v) -> X((!u & !v) | (u & !v) | (!u & v)))",
  "G((!u & v) -> X(!u & v))",
]
liveness = ["GF(!a | u)", "GF(!b | v)"]
[guarantee]
init = "a & !p"
safety = ["G(a -> X(a | b))", "G(b -> X(a | b | c))", "G(c -> X c)", "G(X p <-> (b & X a))"]
liveness = ["GF(c | p)"]
"""
"""The three-mode chain a -> b -> c of the executive's closed-loop tests and benchmark."""


def ball_instance(n: int, k: int, rng: np.random.Generator, *, shell: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """A cut problem in a mode region shaped like the unit ball: x* near the centre,
    x^{T_f-1} on the rim, the failure state just outside, x^0 and k more states inside (on a
    sphere of radius 0.97 with ``shell``, like earlier cut points on the boundary). A separating
    cut always exists. Returns ``(x_star, x0, x_last, x_fail, inner_points)``."""
    u = rng.standard_normal(n)
    u /= np.linalg.norm(u)
    x_star = rng.standard_normal(n)
    x_star *= 0.3 * rng.uniform() / np.linalg.norm(x_star)
    xl = 0.98 * u
    v = u + 0.5 * rng.standard_normal(n)
    xf = xl + 0.05 * (v / np.linalg.norm(v) if u @ v > 0 else u)
    Q = rng.standard_normal((k + 1, n))
    Q /= np.linalg.norm(Q, axis=1, keepdims=True)
    Q *= 0.97 if shell else 0.97 * rng.uniform(size=(k + 1, 1)) ** (1.0 / n)
    return x_star, Q[0], xl, xf, list(Q[1:])
