"""One P from certificate to runtime (paper Thm. 1 (b)), through the files a user deploys.

For random models, cut sets and states: the model goes through ``certify`` (and ``--repair``
when its own P does not certify), the certificate is written and re-read, and the P *read from
the certificate file* is the Lyapunov function the runtime's ``Model.velocity`` decreases:
``grad V . M(x) f(x) <= 0`` everywhere, with and without a control period.

Before the one-P rule, certify could prove a different P than the one the guard uses, and this
property failed (the issue's A = [[-1, 8], [0, -1]], P = I example is an explicit case).
"""

from __future__ import annotations

import json
import tempfile
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tli_verify.certification.certificate import (
    check_certificate,
    issue_certificate,
    write_certificate,
)
from tli_verify.certification.repair import repair_model
from tli_verify.errors import CertificateError
from tli_verify.model.serialize import load_model, save_model


def _spd(rng: np.random.Generator, n: int, lo: float) -> np.ndarray:
    X = rng.normal(size=(n, n))
    return X @ X.T + lo * np.eye(n)


def _model_doc(seed: int, n: int, K: int, n_cuts: int, identity_p: bool) -> dict[str, Any]:
    """A stable LPV-DS (a common Lyapunov matrix P0 exists by construction) storing another P."""
    rng = np.random.default_rng(seed)
    x_star = rng.uniform(-1, 1, size=n)
    P0 = _spd(rng, n, 0.5)
    As = []
    for _ in range(K):
        W = rng.normal(size=(n, n)) * 3.0
        As.append(np.linalg.solve(P0, -_spd(rng, n, 0.2) + (W - W.T)))
    P = np.eye(n) if identity_p else _spd(rng, n, 0.1)
    cuts = []
    for _ in range(n_cuts):
        w = rng.normal(size=n)
        w /= np.linalg.norm(w)
        h = float(rng.choice([0.0, rng.uniform(0.2, 2.0)]))  # some cuts through x*
        cuts.append({"normal": w.tolist(), "point": (x_star + h * w).tolist()})
    comps = [{"prior": 1.0 / K, "mean": (x_star + rng.normal(size=n)).tolist(),
              "cov": (_spd(rng, n, 0.3)).tolist(), "A": a.tolist()} for a in As]
    for c in comps:  # exact symmetry of the stored covariance
        C = np.array(c["cov"])
        c["cov"] = (0.5 * (C + C.T)).tolist()
    Ps = 0.5 * (P + P.T)
    return {"schema_version": 1, "state_names": [f"x{i}" for i in range(n)], "spec": None,
            "modes": {"m": {"attractor": x_star.tolist(), "P": Ps.tolist(),
                            "components": comps, "cuts": cuts}}}


DT = Fraction(1, 1000)
"""The period certify and repair both prove (these random systems are fast: some have no
common P at the slower default)."""


def _deploy(doc: dict[str, Any], root: Path) -> tuple[np.ndarray, Path]:
    """certify (repairing when needed) -> the P read back from the certificate, the model."""
    model = root / "m.model.json"
    model.write_text(json.dumps(doc), encoding="utf-8")
    cert = root / "m.cert.json"
    try:
        cdoc = issue_certificate(model, cert_path=cert, dt=DT)
    except CertificateError:
        repaired = root / "m.repaired.model.json"
        save_model(repair_model(model, repaired, dt=DT).model, repaired)
        model = repaired
        cdoc = issue_certificate(model, cert_path=cert, dt=DT)
    write_certificate(cdoc, cert)
    assert check_certificate(cert).ok
    P = np.array(json.loads(cert.read_text(encoding="utf-8"))["modes"]["m"]["P"])
    return P, model


@settings(max_examples=30)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 3), K=st.integers(1, 3),
       n_cuts=st.integers(0, 3), identity_p=st.booleans())
@example(seed=0, n=2, K=1, n_cuts=2, identity_p=True)
def test_certified_v_never_increases_along_model_velocity(seed: int, n: int, K: int,
                                                          n_cuts: int,
                                                          identity_p: bool) -> None:
    doc = _model_doc(seed, n, K, n_cuts, identity_p)
    if seed == 0 and n == 2 and K == 1:  # the issue's reproduction
        doc["modes"]["m"]["components"][0]["A"] = [[-1.0, 8.0], [0.0, -1.0]]
    with tempfile.TemporaryDirectory() as tmp:
        P, path = _deploy(doc, Path(tmp))
        model = load_model(path)
    mm = model.modes["m"]
    assert np.array_equal(P, mm.ds.P)
    rng = np.random.default_rng(seed + 1)
    x_star = mm.ds.attractor
    X = x_star + rng.uniform(-3, 3, size=(3000, n))
    for c in mm.cuts:  # states on the cut planes too, where eq. 7 acts hardest
        Y = X[:200] - np.outer((X[:200] - c.point) @ c.normal, c.normal)
        X = np.vstack([X, Y])
    d = X - x_star
    for dt in (None, 1e-3):
        v = model.velocity(X, "m", dt=dt)
        dV = 2.0 * np.einsum("ni,ij,nj->n", d, P, v)
        scale = np.einsum("ni,ij,nj->n", d, P, d) * (1.0 + np.abs(v).max())
        assert np.all(dV <= 1e-9 * scale), float((dV / np.maximum(scale, 1e-300)).max())
