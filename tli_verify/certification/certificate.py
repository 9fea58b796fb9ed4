"""Lyapunov certificates of model files: issue (``tli certify``) and re-check (``tli check-cert``).

A certificate (schema ``tli_verify/schemas/certificate.schema.json``) states, for every DS of a
model, that ``V(x) = (x - x*)^T P (x - x*)`` with **the model's own P** -- the P the runtime's
modulation and corner guard use (paper Thm. 1 needs one P for both) -- proves

* ``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for every component k (paper eq. 5);
* at the declared control period ``dt``: ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` for every k,
  so each explicit Euler step of the nominal DS decreases ``V`` (and at every shorter period);
* well-posedness: every number of the model lies in the declared ranges
  (:func:`tli_verify.model.types.numeric_limits`) and every covariance is safely invertible, so the
  velocity is finite and well defined everywhere the certificate claims stability;
* a decay rate ``lambda > 0``: ``A_k^T P + P A_k + lambda P < 0`` for every k, so
  ``V(x(t)) <= V(x(0)) exp(-lambda t)`` (the reachability deadline of
  :mod:`tli_verify.certification.reach`).

It records the schema version, the model file (path relative to the certificate, SHA-256) and
the spec the model names, and per DS: ``P``, the smallest eigenvalue of ``P``, the largest
eigenvalue of each ``A_k^T P + P A_k``, the rate, the learning solver's status, the cuts, and the
exact verdicts. ``digest`` is the SHA-256 of the canonical JSON of everything else.

Nothing in it is trusted. :func:`check_certificate` recomputes the hashes, requires the spec the
certificate names to be the file the model names, requires ``P`` to be the model's bit for bit,
recomputes the eigenvalues and re-runs every exact check (:mod:`tli_verify.certification.exact`).
A model whose own ``P`` does not certify is refused (exit 1); ``tli certify --repair``
(:mod:`tli_verify.certification.repair`) writes a new model with a certifying ``P``.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify._version import __version__
from tli_verify.certification.exact import (
    LyapunovCheck,
    certified_decay_rate,
    check_lyapunov,
    parse_rational,
)
from tli_verify.defaults import DEFAULT_DT
from tli_verify.errors import CertificateError, ModelError, bad_input, missing
from tli_verify.io import (
    atomic_write_text,
    canonical_json,
    read_json,
    same_file,
    sha256_file,
    validate_schema,
)
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model
from tli_verify.model.types import numeric_limits

__all__ = [
    "CERT_KIND",
    "CERT_SCHEMA_VERSION",
    "EXACT_METHOD",
    "CertCheck",
    "certificate_digest",
    "check_certificate",
    "issue_certificate",
    "write_certificate",
]

FloatArray = npt.NDArray[np.float64]

CERT_SCHEMA_VERSION = 2
CERT_KIND = "tli-verify/lyapunov-certificate"
EXACT_METHOD = ("floats converted to exact dyadic rationals (integers times a power of two); "
                "P > 0, -(A_k^T P + P A_k) > 0, P - (I + dt A_k)^T P (I + dt A_k) > 0 and "
                "-(A_k^T P + P A_k) - lambda P > 0 decided on integers: an exact congruence to a "
                "diagonally dominant matrix (Sylvester's law of inertia + Gershgorin), else "
                "fraction-free elimination (Sylvester's criterion)")
_REL_TOL = 1e-9


def certificate_digest(doc: Mapping[str, Any]) -> str:
    """SHA-256 of the canonical JSON of a certificate without its ``digest`` field."""
    body = {k: v for k, v in doc.items() if k != "digest"}
    return hashlib.sha256(canonical_json(body).encode("utf-8")).hexdigest()


def _relpath(target: Path, base_dir: Path) -> str:
    return Path(os.path.relpath(target.resolve(), base_dir.resolve())).as_posix()


def _eigs(P: FloatArray, A: FloatArray) -> tuple[float, list[float]]:
    lam_p = float(np.linalg.eigvalsh(P).min())
    lam = [float(np.linalg.eigvalsh(a.T @ P + P @ a).max()) for a in A]
    return lam_p, lam


def _solver_of_fit(fit: Mapping[str, Any] | None) -> dict[str, Any]:
    """The learning solver's record (informational; the exact check is the proof)."""
    if fit is None:
        return {"name": None, "status": "not recorded in the model file", "eps": None}
    return {"name": fit.get("solver"), "status": str(fit.get("status") or "unknown"),
            "eps": fit.get("eps")}


def rational_text(q: Fraction) -> str:
    """``"p"`` or ``"p/q"``: the exact text of a rational in a certificate."""
    return str(q.numerator) if q.denominator == 1 else f"{q.numerator}/{q.denominator}"


def _repair_hint(mpath: Path) -> str:
    stem = mpath.name.removesuffix(".json").removesuffix(".model")
    return (f"run 'tli certify {mpath} --repair {mpath.parent / (stem + '.repaired.model.json')}' "
            "to search a certifying P and write it into a new model (the runtime must use the "
            "certified P)")


def certify_mode(key: str, mm: Any, *, dt: Fraction, where: str) -> dict[str, Any]:
    """Certify one DS with its own P, or raise naming the mode and what fails.

    Parameters
    ----------
    key : str
        Model key of the DS.
    mm : ModeModel
    dt : Fraction
        Control period of the sampled-data conditions.
    where : str
        The model file, for messages.

    Returns
    -------
    dict
        The certificate's entry for the DS.

    Raises
    ------
    CertificateError
        The model's P fails an exact condition (exit 1).
    """
    A, P = mm.ds.A, mm.ds.P
    verdict = check_lyapunov(P, A, dt=dt)
    if not verdict.ok:
        raise CertificateError(
            f"{where}: mode {key!r}: the model's P does not certify: {verdict.failures()[0]}; "
            f"{_repair_hint(Path(where))}")
    rate = certified_decay_rate(P, A)
    if rate <= 0:  # cannot happen when the continuous conditions hold; never certify 0
        raise CertificateError(f"{where}: mode {key!r}: no positive decay rate verifies "
                               "exactly")
    lam_p, lam = _eigs(P, A)
    return {
        "P": P.tolist(),
        "lambda_min_P": lam_p,
        "lambda_max": lam,
        "decay_rate": rational_text(rate),
        "decay_rate_float": float(rate),
        "solver": _solver_of_fit(mm.fit),
        "cuts": [c.to_dict() for c in mm.cuts],
        "exact": {"P_positive_definite": True,
                  "components_negative_definite": [True] * len(lam),
                  "sampled_decrease": [True] * len(lam),
                  "decay_rate": True},
    }


def issue_certificate(model_path: str | os.PathLike[str], *,
                      cert_path: str | os.PathLike[str],
                      dt: Fraction | str = DEFAULT_DT) -> dict[str, Any]:
    """Verify every DS of a model exactly, with the model's own P, and build its certificate.

    Parameters
    ----------
    model_path : path-like
        The model file.
    cert_path : path-like
        Where the certificate will be written (paths inside are relative to its directory).
    dt : Fraction or str, optional
        Control period of the sampled-data conditions (default
        :data:`~tli_verify.defaults.DEFAULT_DT`).

    Returns
    -------
    dict
        The certificate document (with its digest).

    Raises
    ------
    ModelError
        The model file does not load, or its spec is missing or does not load (exit 2).
    CertificateError
        A DS is not certifiable with the model's P, naming the mode and the condition (exit 1).
    """
    try:
        dt_q = parse_rational(dt, what="dt")
    except ValueError as exc:
        raise bad_input(CertificateError, str(exc)) from None
    if dt_q <= 0:
        raise bad_input(CertificateError, f"dt: control period {dt} must be positive")
    mpath = Path(model_path)
    model = load_model(mpath)
    base = Path(cert_path).parent
    spec = None
    if model.spec_path is not None:
        if not model.spec_path.is_file():
            raise ModelError(f"{mpath}: spec: file {model.spec_path} not found")

        load_spec(model.spec_path)  # a certificate never binds a spec that does not load
        spec = {"path": _relpath(model.spec_path, base), "sha256": sha256_file(model.spec_path)}
    modes = {key: certify_mode(key, mm, dt=dt_q, where=str(mpath))
             for key, mm in model.modes.items()}
    doc: dict[str, Any] = {
        "schema_version": CERT_SCHEMA_VERSION,
        "kind": CERT_KIND,
        "tool": {"name": "tli-verify", "version": __version__},
        "model": {"path": _relpath(mpath, base), "sha256": sha256_file(mpath)},
        "spec": spec,
        "control_period": {"dt": rational_text(dt_q), "dt_float": float(dt_q)},
        "well_posed": {"limits": numeric_limits(), "velocity_finite": True},
        "modes": modes,
        "exact_check": {"passed": True, "method": EXACT_METHOD},
    }
    doc["digest"] = certificate_digest(doc)
    return doc


def write_certificate(doc: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Write a certificate document atomically (canonical JSON)."""
    atomic_write_text(path, canonical_json(dict(doc)))


@dataclass(frozen=True, slots=True)
class CertCheck:
    """Result of re-checking a certificate from scratch.

    Attributes
    ----------
    path : str
        The certificate file.
    model_path : str or None
        The model file it was checked against (resolved).
    problems : tuple of str
        Everything that differs or fails; empty iff the certificate is valid.
    passed : tuple of str
        What was verified.
    dt : str or None
        The control period the certificate states (exact text), when it could be read.
    """

    path: str
    model_path: str | None
    problems: tuple[str, ...] = ()
    passed: tuple[str, ...] = field(default=())
    dt: str | None = None

    @property
    def ok(self) -> bool:
        """True iff nothing failed."""
        return not self.problems


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= _REL_TOL * max(1.0, abs(a), abs(b))


def check_certificate(cert_path: str | os.PathLike[str], *,
                      model_path: str | os.PathLike[str] | None = None) -> CertCheck:
    """Re-check a certificate exactly, from its numbers and the files' hashes.

    Parameters
    ----------
    cert_path : path-like
        The certificate.
    model_path : path-like, optional
        Model file to check against (default: the one the certificate names, relative to it).

    Returns
    -------
    CertCheck
        With every problem found (not just the first).

    Raises
    ------
    CertificateError
        Only when the certificate file cannot be read at all (exit 2).
    """
    cpath = Path(cert_path)
    if cpath.is_dir():
        raise bad_input(CertificateError,
                        f"{cpath}: is a directory, expected a certificate file")
    if cpath.exists() and not cpath.is_file():
        raise bad_input(CertificateError, f"{cpath}: not a regular file (a device, FIFO or "
                        "socket); refused, never read")
    if not cpath.is_file():
        raise missing(CertificateError, f"{cpath}: no such certificate file", cpath)
    problems: list[str] = []
    passed: list[str] = []
    try:
        doc = read_json(cpath, what="certificate", error=CertificateError)
        validate_schema(doc, "certificate.schema.json", where=str(cpath),
                        error=CertificateError)
    except CertificateError as exc:
        return CertCheck(str(cpath), None, (f"malformed certificate: {exc}",))
    if certificate_digest(doc) != doc["digest"]:
        problems.append(f"{cpath}: digest does not match the content: the certificate was "
                        "edited after it was issued")
    else:
        passed.append("digest matches the content")
    mpath = Path(model_path) if model_path is not None else \
        Path(os.path.realpath(cpath.parent / doc["model"]["path"]))
    if not mpath.is_file():
        problems.append(f"{cpath}: model file {mpath} not found")
        return CertCheck(str(cpath), str(mpath), tuple(problems), tuple(passed))
    digest = sha256_file(mpath)
    if digest != doc["model"]["sha256"]:
        problems.append(f"{mpath}: SHA-256 {digest[:12]}... differs from the certificate's "
                        f"{doc['model']['sha256'][:12]}...: the model changed after certification")
    else:
        passed.append(f"model {mpath} matches its SHA-256")
    try:
        model = load_model(mpath)
    except ModelError as exc:
        problems.append(f"model does not load: {exc}")
        return CertCheck(str(cpath), str(mpath), tuple(problems), tuple(passed))

    if doc["well_posed"]["limits"] != numeric_limits():
        problems.append(f"{cpath}: well_posed.limits differ from this tool's declared ranges "
                        f"{numeric_limits()}: re-certify with this version")
    else:
        passed.append("the model's numbers lie within the declared ranges (velocity finite "
                      "and well defined)")
    problems += _check_spec_binding(doc["spec"], cpath, model, mpath, passed)
    dt_text = doc["control_period"]["dt"]
    dt = Fraction(dt_text)
    if dt <= 0:
        problems.append(f"{cpath}: control_period.dt {dt_text!r} is not positive")
    cert_modes: Mapping[str, Any] = doc["modes"]
    for key in sorted(set(model.modes) - set(cert_modes)):
        problems.append(f"mode {key!r} of the model is not covered by the certificate")
    for key in sorted(set(cert_modes) - set(model.modes)):
        problems.append(f"mode {key!r} of the certificate does not exist in the model")
    for key in sorted(set(cert_modes) & set(model.modes)):
        entry = cert_modes[key]
        found = _check_mode(key, entry, model.modes[key], dt)
        problems += found
        if not found:
            passed.append(f"mode {key!r}: the model's P > 0; A_k^T P + P A_k < 0, "
                          f"(I + dt A_k)^T P (I + dt A_k) < P at dt = {dt_text} and decay rate "
                          f"{entry['decay_rate']} for all {model.modes[key].ds.n_components} "
                          "components (exact)")
    return CertCheck(str(cpath), str(mpath), tuple(problems), tuple(passed), dt_text)


def _check_spec_binding(spec: Mapping[str, Any] | None, cpath: Path, model: Any, mpath: Path,
                        passed: list[str]) -> list[str]:
    """The certificate's spec must be the very file the model names, unchanged."""
    spec_path = model.spec_path  # resolved as the OS opens it
    if spec_path is None:
        return ([f"the certificate covers spec {spec['path']} but {mpath} names none"]
                if spec is not None else [])
    if spec is None:
        return [f"{mpath} names spec {model.spec} but the certificate covers no spec"]
    named = Path(os.path.realpath(cpath.parent / spec["path"]))
    if not spec_path.is_file():
        return [f"spec file {spec_path} not found"]
    if not same_file(named, spec_path):
        return [f"{cpath}: spec.path {spec['path']!r} ({named}) is not the spec the model "
                f"names ({spec_path}): the certificate binds another spec"]
    if sha256_file(spec_path) != spec["sha256"]:
        return [f"{spec_path}: SHA-256 differs from the certificate's: the spec changed after "
                "certification"]
    passed.append(f"spec {spec_path} is the model's and matches its SHA-256")
    return []


def _check_mode(key: str, entry: Mapping[str, Any], mm: Any, dt: Fraction) -> list[str]:
    """Every discrepancy between one certified DS and the model, and the exact verdicts."""
    out: list[str] = []
    tag = f"mode {key!r}"
    A = mm.ds.A
    n = A.shape[1]
    try:
        P = np.array(entry["P"], dtype=np.float64)
    except ValueError:
        return [f"{tag}: P is not a rectangular matrix"]
    if P.shape != (n, n):
        return [f"{tag}: P has shape {P.shape}, the model's DS has dimension {n}"]
    diff = np.argwhere(P != mm.ds.P)
    if diff.size:
        i, j = (int(v) for v in diff[0])
        out.append(f"{tag}: P[{i}][{j}] = {float(P[i, j])!r} differs from the model's "
                   f"P[{i}][{j}] = {float(mm.ds.P[i, j])!r}: the certificate must prove the P "
                   "the runtime uses")
    lam = entry["lambda_max"]
    if len(lam) != A.shape[0]:
        out.append(f"{tag}: certificate lists {len(lam)} components, the model has "
                   f"{A.shape[0]}")
    cuts = [c.to_dict() for c in mm.cuts]
    if entry["cuts"] != cuts:
        out.append(f"{tag}: the certificate was issued for {len(entry['cuts'])} cut(s) that "
                   f"differ from the model's {len(cuts)}")
    rate = Fraction(entry["decay_rate"])
    if rate <= 0:
        out.append(f"{tag}: decay_rate {entry['decay_rate']!r} is not positive")
    verdict: LyapunovCheck = check_lyapunov(P, A, dt=dt if dt > 0 else None,
                                            rate=rate if rate > 0 else None)
    out += [f"{tag}: {f} (exact re-check)" for f in verdict.failures()]
    if verdict.p.positive:
        lam_p, lam_now = _eigs(P, A)
        if not _close(lam_p, float(entry["lambda_min_P"])):
            out.append(f"{tag}: recorded smallest eigenvalue of P {entry['lambda_min_P']!r} "
                       f"differs from the recomputed {lam_p!r}")
        for k, (rec, now) in enumerate(zip(lam, lam_now, strict=False)):
            if not _close(float(rec), now):
                out.append(f"{tag}: component {k}: recorded largest eigenvalue of "
                           f"A_k^T P + P A_k {rec!r} differs from the recomputed {now!r}")
    return out
