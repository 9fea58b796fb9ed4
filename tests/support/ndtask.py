"""A task the tests write, in any dimension ``n >= 2``: the scoop-shaped spec (modes a -> b -> c
-> d, knock-backs allowed) over bands of ``x0`` inside a tube ``max |x_i| <= R`` (i >= 1), with
a certified random LPV-DS per mode (K components, a random SPD ``P``; ``A_k = P^-1 (-c I +
S_k)`` with ``S_k`` skew, so ``A_k^T P + P A_k = -2c I``). The skew parts spin the flow out of
the tube, so episodes leave modes (invariance failures) and learn cuts.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

SPEC = '''
name = "nd-chain"
inputs  = ["r", "s", "t"]
outputs = ["a", "b", "c", "d", "p"]

[modes]
a = "!r & !s & !t"
b = "r & !s & !t"
c = "!r & s & !t"
d = "!r & !s & t"

[assume]
init = "!r & !s & !t"
safety = [
  "G((!r & !s & !t) -> X((!r & !s & !t) | (r & !s & !t)))",
  "G((r & !s & !t) -> X((r & !s & !t) | (!r & s & !t) | (!r & !s & !t)))",
  "G((!r & s & !t) -> X((!r & s & !t) | (!r & !s & t) | (!r & !s & !t) | (r & !s & !t)))",
  "G((!r & !s & t) -> X(!r & !s & t))",
]
liveness = ["GF(!a | r)", "GF(!b | s)", "GF(!c | t)"]

[guarantee]
init = "a & !p"
safety = [
  "G(a -> X(a | b))",
  "G(b -> X(a | b | c))",
  "G(c -> X(a | b | c | d))",
  "G(d -> X d)",
  "G(X p <-> ((b & X a) | (c & X a) | (c & X b)))",
]
liveness = ["GF(d | p)"]
'''

RADIUS = 0.6
"""Half-width of the tube around the x0 axis; outside it the reading is mode a's."""

DT = 0.01


class NDSensors:
    """Readings of the written task (``reset``/``read``, the runtime's sensor protocol)."""

    def __init__(self, n: int, radius: float = RADIUS) -> None:
        self.n = n
        self.radius = radius

    def reset(self, x: Any) -> None:
        """No memory."""

    def read(self, x: Any) -> dict[str, bool]:
        x = np.asarray(x, dtype=np.float64)
        inside = bool(np.max(np.abs(x[1:])) <= self.radius)
        band = x[0]
        return {"r": inside and 1.0 <= band < 2.0, "s": inside and 2.0 <= band < 3.0,
                "t": inside and band >= 3.0}


def _ds(rng: np.random.Generator, mode: str, nxt: str | None, att: np.ndarray, K: int,
        spin: float, cuts: int = 0) -> dict[str, Any]:
    n = att.size
    M = rng.normal(size=(n, n))
    P = M @ M.T / n + np.eye(n)
    P = np.round(0.5 * (P + P.T), 6)
    Pinv = np.linalg.inv(P)
    comps = []
    for _ in range(K):
        S = rng.normal(scale=spin, size=(n, n))
        S = S - S.T
        A = Pinv @ (-np.eye(n) + S)
        B = rng.normal(size=(n, n))
        cov = B @ B.T / n * 0.2 + 0.05 * np.eye(n)
        cov = 0.5 * (cov + cov.T)
        mean = att + rng.normal(scale=0.5, size=n) - np.r_[0.8, np.zeros(n - 1)]
        comps.append({"prior": 1.0 / K, "mean": mean.tolist(), "cov": cov.tolist(),
                      "A": A.tolist()})
    planes = []
    for _ in range(cuts):  # offline cuts keeping x* inside (h in [0.3, 0.6])
        w = rng.normal(size=n)
        w /= np.linalg.norm(w)
        planes.append({"normal": w.tolist(), "point": (att + rng.uniform(0.3, 0.6) * w).tolist()})
    return {"mode": mode, "next_mode": nxt, "attractor": att.tolist(), "P": P.tolist(),
            "components": comps, "cuts": planes}


def write_nd(root: Path, n: int, *, K: int = 3, seed: int = 0, spin: float = 2.0,
             cuts: int = 0, spec_text: str = SPEC) -> SimpleNamespace:
    """Write spec, model and certificate of the n-D task under ``root``; return the policy's
    pieces (``automaton``, ``model``, ``certificate``, ``spec``, ``setup`` for
    :func:`tli_verify.deploy.export.build_artifact`); ``cuts`` offline cuts per DS;
    ``spec_text`` another spec over the same modes (e.g. with an input the strategy never
    reads)."""
    from tli_verify.certification.certificate import issue_certificate, write_certificate
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import parse_spec
    from tli_verify.model.serialize import load_model, model_from_dict, save_model

    rng = np.random.default_rng(seed)
    for d in ("specs", "models", "certificates"):
        (root / d).mkdir(parents=True, exist_ok=True)
    (root / "specs" / "nd.toml").write_text(spec_text)
    e0 = np.r_[1.0, np.zeros(n - 1)]
    modes = {m: _ds(rng, m, nxt, x0 * e0, K, spin, cuts)
             for m, nxt, x0 in (("a", "b", 1.5), ("b", "c", 2.5), ("c", "d", 3.5),
                                ("d", None, 4.0))}
    doc = {"schema_version": 1, "state_names": [f"x{i}" for i in range(n)],
           "spec": "../specs/nd.toml", "modes": modes}
    mpath = root / "models" / "nd.model.json"
    save_model(model_from_dict(doc, path=str(mpath)), mpath)
    cpath = root / "certificates" / "nd.cert.json"
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt="1/100"), cpath)
    spec = parse_spec(spec_text)
    automaton = synthesize(spec)
    model = load_model(mpath)
    setup = SimpleNamespace(automaton=automaton, model=model, task=SimpleNamespace(dt=DT))
    return SimpleNamespace(automaton=automaton, model=model, certificate=cpath, spec=spec,
                           setup=setup, model_path=mpath)
