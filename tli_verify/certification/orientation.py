"""Exact certificates of orientation DSs (issue 35): issue and re-check.

The orientation DS (:mod:`tli_verify.ds.quaternion`) is an LPV-DS in the tangent coordinates
``xi = log_{q*}(q)`` (the rotation vector of ``q*^{-1} q``, ``q`` taken in the hemisphere of
``q*``); the orientation is *defined* by ``xi`` and recovered as ``q = exp_{q*}(xi)``, so no
approximation of the quaternion <-> tangent map enters the argument. A certificate states, with
``V(xi) = xi^T P xi`` and every condition decided in exact rational arithmetic
(:func:`tli_verify.certification.exact.check_lyapunov`, :func:`~tli_verify.certification.exact.
positive_definite`):

* ``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for every k (continuous time);
* at the control period ``dt``: ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` for every k, so each
  controller step ``xi+ = xi + dt f(xi)`` decreases ``V`` (the weights ``gamma_k`` are convex);
* a decay rate ``lambda``: ``A_k^T P + P A_k + lambda P < 0`` for every k;
* the chart: rationals ``m`` and ``M`` with ``P - m I > 0`` and ``M I - P > 0``; with
  ``pi_low = 314159265/100000000 < pi``, the sub-level set ``{V < c}``, ``c = m pi_low^2``, lies
  in the ball ``|xi| < pi`` where ``log_{q*}`` / ``exp_{q*}`` are inverse bijections, so every
  run that starts with ``V < c`` stays in the chart and converges to ``q*``; every start at
  rotation angle ``theta_0`` with ``theta_0^2 < c / M`` has ``V < c`` (both bounds recorded).

The certificate binds the orientation model file (path relative to the certificate, SHA-256),
records ``q*``, ``P`` and every ``A_k``, and a ``digest`` (SHA-256 of the canonical JSON of
everything else). :func:`check_orientation_certificate` trusts none of it: it recomputes the
digest and the model's hash, requires the certificate's ``q*``, ``P`` and ``A_k`` to be the
model's bit for bit, and re-runs every exact check; a forged orientation matrix is refused by
whichever of these it breaks.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.certification.exact import (
    certified_decay_rate,
    check_lyapunov,
    parse_rational,
    positive_definite,
)
from tli_verify.defaults import DEFAULT_DT
from tli_verify.ds.quaternion import QuaternionDS, load_orientation_model
from tli_verify.errors import CertificateError, ModelError
from tli_verify.io import atomic_write_text, canonical_json, read_json, sha256_file

__all__ = [
    "ORIENTATION_CERT_KIND",
    "PI_LOWER",
    "OrientationCheck",
    "check_orientation_certificate",
    "issue_orientation_certificate",
    "write_orientation_certificate",
]

FloatArray = npt.NDArray[np.float64]

ORIENTATION_CERT_KIND = "tli-verify/orientation-certificate"
ORIENTATION_CERT_VERSION = 1
PI_LOWER = Fraction(314159265, 100000000)
"""A rational below pi (pi = 3.14159265358...): the chart radius the certificate uses."""
TANGENT_MAP = (
    "quaternions scalar-first (w, x, y, z); xi = log_{q*}(q) = theta u, the rotation vector of "
    "q*^{-1} q with q taken in the hemisphere of q* (<q, q*> >= 0, so q and -q give the same "
    "xi: the double cover is quotiented out); the DS xi_dot = sum_k gamma_k(xi) A_k xi is "
    "defined in these coordinates and the orientation is recovered exactly as "
    "q = q* (x) (cos(|xi|/2), sin(|xi|/2) xi/|xi|); log_{q*} and exp_{q*} are inverse "
    "bijections between the rotations at angle < pi from q* and the ball |xi| < pi, so the "
    "argument holds for runs that stay at rotation angle < pi, which every start with "
    "V < region_V_below does")


def _rational_text(q: Fraction) -> str:
    return str(q.numerator) if q.denominator == 1 else f"{q.numerator}/{q.denominator}"


def _digest(doc: Mapping[str, Any]) -> str:
    body = {k: v for k, v in doc.items() if k != "digest"}
    return hashlib.sha256(canonical_json(body).encode("utf-8")).hexdigest()


def _fractions(M: FloatArray) -> list[list[Fraction]]:
    return [[Fraction(float(v)) for v in row] for row in M]


def _short_below(x: float, digits: int = 4) -> Fraction:
    """A short decimal rational ``<= x`` (``x > 0``)."""
    import math

    exp10 = math.floor(math.log10(x)) - digits + 1
    unit = Fraction(10) ** exp10
    return Fraction(math.floor(Fraction(x) / unit)) * unit


def _short_above(x: float, digits: int = 4) -> Fraction:
    """A short decimal rational ``>= x`` (``x > 0``)."""
    import math

    exp10 = math.floor(math.log10(x)) - digits + 1
    unit = Fraction(10) ** exp10
    return Fraction(math.ceil(Fraction(x) / unit)) * unit


def _shifted(P: FloatArray, shift: Fraction, sign: int) -> list[list[Fraction]]:
    """Exact ``sign (P - shift I)``."""
    F = _fractions(P)
    n = len(F)
    return [[sign * (F[i][j] - (shift if i == j else 0)) for j in range(n)] for i in range(n)]


def _eigen_bounds(P: FloatArray) -> tuple[Fraction, Fraction]:
    """Rationals ``0 < m <= lambda_min(P)`` and ``M >= lambda_max(P)``, each verified exactly
    (``P - m I > 0``, ``M I - P > 0``); ``m = 0`` when no positive bound verifies."""
    eig = np.linalg.eigvalsh(0.5 * (P + P.T))
    lo = float(eig[0]) * (1.0 - 1e-6)
    m = Fraction(0)
    for _ in range(40):
        if lo <= 0.0:
            break
        cand = _short_below(lo)
        if positive_definite(_shifted(P, cand, 1)).positive:
            m = cand
            break
        lo /= 2.0
    hi = float(eig[-1]) * (1.0 + 1e-6)
    M = _short_above(hi)
    for _ in range(40):
        if positive_definite(_shifted(P, M, -1)).positive:
            break
        M *= 2
    return m, M


def issue_orientation_certificate(model_path: str | os.PathLike[str],
                                  cert_path: str | os.PathLike[str], *,
                                  dt: Fraction | str = DEFAULT_DT) -> dict[str, Any]:
    """Decide every condition of the orientation DS exactly and build its certificate.

    Parameters
    ----------
    model_path : path-like
        Orientation model file (:func:`tli_verify.ds.quaternion.write_orientation_model`).
    cert_path : path-like
        Where the certificate will be written (the model path is recorded relative to it).
    dt : Fraction or str, optional
        Control period of the sampled-data conditions (default 1 ms).

    Returns
    -------
    dict
        The certificate (JSON-ready, with ``digest``).

    Raises
    ------
    ModelError
        The model file is unreadable or malformed.
    CertificateError
        A condition fails exactly: no certificate for this DS (the message names it).
    """
    mpath = Path(model_path)
    ds = load_orientation_model(mpath)
    dt_q = parse_rational(dt, what="dt")
    P, A = ds.P, ds.A
    verdict = check_lyapunov(P, A, dt=dt_q)
    if not verdict.ok:
        raise CertificateError(f"{mpath}: orientation DS does not certify: "
                               f"{'; '.join(verdict.failures())}")
    rate = certified_decay_rate(P, A)
    m, M = _eigen_bounds(P)
    if m <= 0:
        raise CertificateError(f"{mpath}: no positive lower bound of lambda_min(P) verifies")
    c = m * PI_LOWER * PI_LOWER
    rel = os.path.relpath(mpath.resolve(), Path(cert_path).resolve().parent)
    doc: dict[str, Any] = {
        "kind": ORIENTATION_CERT_KIND,
        "schema_version": ORIENTATION_CERT_VERSION,
        "model": {"path": Path(rel).as_posix(), "sha256": sha256_file(mpath)},
        "tangent_map": TANGENT_MAP,
        "attractor": ds.attractor.tolist(),
        "P": P.tolist(),
        "A": A.tolist(),
        "dt": _rational_text(dt_q),
        "exact": {
            "P_positive": verdict.p.positive,
            "continuous": [r.positive for r in verdict.components],
            "sampled": [r.positive for r in verdict.sampled],
            "decay_rate": _rational_text(rate),
            "lambda_min_P_lower": _rational_text(m),
            "lambda_max_P_upper": _rational_text(M),
            "pi_lower": _rational_text(PI_LOWER),
            "region_V_below": _rational_text(c),
            "region_angle_squared_below": _rational_text(c / M),
        },
    }
    doc["digest"] = _digest(doc)
    return doc


def write_orientation_certificate(doc: Mapping[str, Any],
                                  path: str | os.PathLike[str]) -> None:
    """Write a certificate as canonical JSON, atomically."""
    atomic_write_text(path, canonical_json(dict(doc)))


@dataclass(frozen=True, slots=True)
class OrientationCheck:
    """Result of :func:`check_orientation_certificate`.

    Attributes
    ----------
    failures : tuple of str
        One line per failed check (empty: the certificate re-checks).
    """

    failures: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """True iff every check passed."""
        return not self.failures


def _same_floats(a: Any, b: FloatArray) -> bool:
    try:
        arr = np.asarray(a, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return arr.shape == b.shape and bool(np.array_equal(arr, b))


def check_orientation_certificate(cert_path: str | os.PathLike[str]) -> OrientationCheck:
    """Re-check an orientation certificate from scratch (module docstring).

    Parameters
    ----------
    cert_path : path-like

    Returns
    -------
    OrientationCheck
        Failures: digest mismatch (the file was edited), model hash mismatch, ``q*`` / ``P`` /
        ``A_k`` not the model's, or any exact condition failing.

    Raises
    ------
    CertificateError
        The certificate is unreadable, not JSON, or not an orientation certificate.
    """
    cpath = Path(cert_path)
    doc = read_json(cpath, what="orientation certificate", error=CertificateError)
    if not isinstance(doc, dict) or doc.get("kind") != ORIENTATION_CERT_KIND:
        raise CertificateError(f"{cpath}: not an orientation certificate (kind must be "
                               f"{ORIENTATION_CERT_KIND!r})")
    failures: list[str] = []
    if doc.get("digest") != _digest(doc):
        failures.append(f"{cpath}: digest does not match the content: the file was edited")
    try:
        model = doc["model"]
        mpath = cpath.parent / str(model["path"])
        exact = doc["exact"]
        dt_q = parse_rational(doc["dt"], what="dt")
        P = np.asarray(doc["P"], dtype=np.float64)
        A = np.asarray(doc["A"], dtype=np.float64)
        m = parse_rational(exact["lambda_min_P_lower"], what="lambda_min_P_lower")
        M = parse_rational(exact["lambda_max_P_upper"], what="lambda_max_P_upper")
        c = parse_rational(exact["region_V_below"], what="region_V_below")
        c_angle = parse_rational(exact["region_angle_squared_below"],
                                 what="region_angle_squared_below")
        pi_low = parse_rational(exact["pi_lower"], what="pi_lower")
        rate = parse_rational(exact["decay_rate"], what="decay_rate")
    except (KeyError, TypeError, ValueError) as exc:
        raise CertificateError(f"{cpath}: malformed orientation certificate: {exc}") from None
    if P.ndim != 2 or P.shape != (3, 3) or A.ndim != 3 or A.shape[1:] != (3, 3):
        raise CertificateError(f"{cpath}: P must be 3x3 and A K x 3 x 3, got {P.shape}, "
                               f"{A.shape}")
    ds: QuaternionDS | None = None
    if not mpath.is_file():
        failures.append(f"{cpath}: model file {model['path']!r} not found")
    else:
        if sha256_file(mpath) != model.get("sha256"):
            failures.append(f"{cpath}: model {model['path']!r} changed since certification "
                            "(sha256 differs)")
        try:
            ds = load_orientation_model(mpath)
        except ModelError as exc:
            failures.append(str(exc))
    if ds is not None:
        for name, mine in (("attractor", ds.attractor), ("P", ds.P), ("A", ds.A)):
            if not _same_floats(doc.get(name), mine):
                failures.append(f"{cpath}: {name} is not the model's (bit for bit): a forged "
                                "or stale orientation certificate")
    verdict = check_lyapunov(P, A, dt=dt_q, rate=rate)
    failures += [f"{cpath}: {f}" for f in verdict.failures()]
    if not 0 < pi_low <= PI_LOWER:
        failures.append(f"{cpath}: pi_lower {pi_low} is not a rational below pi")
    if not (m > 0 and positive_definite(_shifted(P, m, 1)).positive):
        failures.append(f"{cpath}: P - lambda_min_P_lower I is not positive definite")
    if not positive_definite(_shifted(P, M, -1)).positive:
        failures.append(f"{cpath}: lambda_max_P_upper I - P is not positive definite")
    if c != m * pi_low * pi_low or c_angle != c / M:
        failures.append(f"{cpath}: region bounds are not lambda_min_P_lower pi_lower^2 and "
                        "region_V_below / lambda_max_P_upper")
    return OrientationCheck(tuple(failures))
