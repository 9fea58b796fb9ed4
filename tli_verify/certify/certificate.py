"""Lyapunov certificates of model files: issue (``tli certify``) and re-check (``tli check-cert``).

A certificate (schema ``tli_verify/schemas/certificate.schema.json``) states, for every DS of a
model, that ``V(x) = (x - x*)^T P (x - x*)`` proves global asymptotic stability (paper eq. 5):
``P = P^T > 0`` and ``A_k^T P + P A_k < 0`` for every component k. It records

* ``schema_version``, ``kind`` and the tool version;
* the model file (path relative to the certificate, SHA-256) and its spec file if it names one;
* per DS: ``P``, where it came from (the model's own ``P``, or an SDP solved by ``certify``),
  the smallest eigenvalue of ``P``, the largest eigenvalue of each ``A_k^T P + P A_k``, the
  solver and status, the cuts the certificate was issued for, and the exact verdicts;
* ``digest``: SHA-256 of the canonical JSON of everything else, so any edit of the certificate
  shows even when the edited numbers would still certify.

Nothing in it is trusted. :func:`check_certificate` recomputes the model hash, reloads the
model, requires the certificate's ``P`` to be the model's when it claims so, recomputes the
eigenvalues, and re-runs the exact rational check (:mod:`tli_verify.certify.exact`) on the
numbers themselves.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.certify.exact import check_lyapunov
from tli_verify.errors import CertificateError, ModelError, SolverError
from tli_verify.io import atomic_write_text, canonical_json, sha256_file

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

CERT_SCHEMA_VERSION = 1
CERT_KIND = "tli-verify/lyapunov-certificate"
EXACT_METHOD = ("floats converted to exact rationals (fractions.Fraction); P > 0 and "
                "-(A_k^T P + P A_k) > 0 decided by LDL^T pivots (Sylvester's criterion)")
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


def _solver_of_fit(fit: Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The solver record of the model's learning SDP, if its P may be used."""
    if fit is None:
        return {"name": None, "status": "not solved here: P taken from the model file",
                "eps": None}
    status = fit.get("status")
    if status is not None and status != "optimal":
        return None  # e.g. optimal_inaccurate: never a certificate from that P
    return {"name": fit.get("solver"), "status": str(status or "unknown"),
            "eps": fit.get("eps")}


def issue_certificate(model_path: str | os.PathLike[str], *,
                      cert_path: str | os.PathLike[str]) -> dict[str, Any]:
    """Verify every DS of a model exactly and build its certificate document.

    For each DS the model's own ``P`` is tried first. If it does not certify exactly (or the
    model records a non-optimal learning status), a common Lyapunov matrix is searched for the
    fixed ``A_k`` with an SDP (:func:`tli_verify.ds.lyapunov.find_p`) and checked exactly.

    Parameters
    ----------
    model_path : path-like
        The model file.
    cert_path : path-like
        Where the certificate will be written (paths inside are relative to its directory).

    Returns
    -------
    dict
        The certificate document (with its digest).

    Raises
    ------
    ModelError
        The model file does not load (exit 2).
    CertificateError
        A DS is not certifiable, naming the mode and the component (exit 1).
    """
    from tli_verify import __version__
    from tli_verify.ds.lyapunov import find_p
    from tli_verify.model import load_model

    mpath = Path(model_path)
    model = load_model(mpath)
    base = Path(cert_path).parent
    modes: dict[str, Any] = {}
    for key, mm in model.modes.items():
        A = mm.ds.A
        P = mm.ds.P
        source = "model"
        solver = _solver_of_fit(mm.fit)
        verdict = check_lyapunov(P, A) if solver is not None else None
        if verdict is None or not verdict.ok:
            first = (verdict.failures()[0] if verdict is not None
                     else "the model's P comes from a solve that was not 'optimal'")
            try:
                P, info = find_p(A)
            except SolverError as exc:
                raise CertificateError(
                    f"{mpath}: mode {key!r}: not certifiable: {first}; no common Lyapunov "
                    f"matrix for its A_k either ({exc})") from None
            source = "certify-sdp"
            solver = {"name": info.solver, "status": info.status, "eps": 1e-6}
            verdict = check_lyapunov(P, A)
            if not verdict.ok:
                raise CertificateError(
                    f"{mpath}: mode {key!r}: not certifiable: {first}; the SDP's P fails the "
                    f"exact check too: {verdict.failures()[0]}")
        lam_p, lam = _eigs(P, A)
        modes[key] = {
            "P": P.tolist(),
            "P_source": source,
            "lambda_min_P": lam_p,
            "lambda_max": lam,
            "solver": solver,
            "cuts": [c.to_dict() for c in mm.cuts],
            "exact": {"P_positive_definite": True,
                      "components_negative_definite": [True] * len(lam)},
        }
    spec = None
    if model.spec_path is not None:
        if not model.spec_path.is_file():
            raise ModelError(f"{mpath}: spec: file {model.spec_path} not found")
        spec = {"path": _relpath(model.spec_path, base), "sha256": sha256_file(model.spec_path)}
    doc: dict[str, Any] = {
        "schema_version": CERT_SCHEMA_VERSION,
        "kind": CERT_KIND,
        "tool": {"name": "tli-verify", "version": __version__},
        "model": {"path": _relpath(mpath, base), "sha256": sha256_file(mpath)},
        "spec": spec,
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
    """

    path: str
    model_path: str | None
    problems: tuple[str, ...] = ()
    passed: tuple[str, ...] = field(default=())

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
    from tli_verify.model import load_model, read_json, validate_schema

    cpath = Path(cert_path)
    if not cpath.is_file():
        raise CertificateError(f"{cpath}: no such certificate file", exit_code=2)
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
        Path(os.path.normpath(cpath.parent / doc["model"]["path"]))
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
    spec = doc["spec"]
    spec_path = Path(os.path.normpath(model.spec_path)) if model.spec_path is not None else None
    if spec_path is not None:
        if spec is None:
            problems.append(f"{mpath} names spec {model.spec} but the certificate covers no spec")
        elif not spec_path.is_file():
            problems.append(f"spec file {spec_path} not found")
        elif sha256_file(spec_path) != spec["sha256"]:
            problems.append(f"{spec_path}: SHA-256 differs from the certificate's: the spec "
                            "changed after certification")
        else:
            passed.append(f"spec {spec_path} matches its SHA-256")
    elif spec is not None:
        problems.append(f"the certificate covers spec {spec['path']} but {mpath} names none")
    cert_modes: Mapping[str, Any] = doc["modes"]
    for key in sorted(set(model.modes) - set(cert_modes)):
        problems.append(f"mode {key!r} of the model is not covered by the certificate")
    for key in sorted(set(cert_modes) - set(model.modes)):
        problems.append(f"mode {key!r} of the certificate does not exist in the model")
    for key in sorted(set(cert_modes) & set(model.modes)):
        problems += _check_mode(key, cert_modes[key], model.modes[key])
        if not any(p.startswith(f"mode {key!r}") for p in problems):
            passed.append(f"mode {key!r}: P > 0 and A_k^T P + P A_k < 0 for all "
                          f"{model.modes[key].ds.n_components} components (exact)")
    return CertCheck(str(cpath), str(mpath), tuple(problems), tuple(passed))


def _check_mode(key: str, entry: Mapping[str, Any], mm: Any) -> list[str]:
    """Every discrepancy between one certified mode and the model, and the exact verdict."""
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
    if entry["P_source"] == "model":
        diff = np.argwhere(P != mm.ds.P)
        if diff.size:
            i, j = (int(v) for v in diff[0])
            out.append(f"{tag}: P[{i}][{j}] = {float(P[i, j])!r} differs from the model's "
                       f"P[{i}][{j}] = {float(mm.ds.P[i, j])!r}")
    lam = entry["lambda_max"]
    if len(lam) != A.shape[0]:
        out.append(f"{tag}: certificate lists {len(lam)} components, the model has "
                   f"{A.shape[0]}")
    cuts = [c.to_dict() for c in mm.cuts]
    if entry["cuts"] != cuts:
        out.append(f"{tag}: the certificate was issued for {len(entry['cuts'])} cut(s) that "
                   f"differ from the model's {len(cuts)}")
    verdict = check_lyapunov(P, A)
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
