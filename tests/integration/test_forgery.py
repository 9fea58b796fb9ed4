"""Forged certificates: only the exact rational re-check can refuse them (paper eq. 5).

A forger who edits a model can recompute everything a hash protects: the model's SHA-256 in the
certificate, the recorded eigenvalues and the certificate's digest. Such a certificate passes
every integrity check; what it claims (``P > 0`` and ``A_k^T P + P A_k < 0``) is false. These
tests forge two of them, starting from a certificate freshly issued by the tool for a stable copy
of the bundled scoop model (so fields the format gains later are produced by the issuer, not
written by hand), and require that ``tli check-cert`` and ``tli gate`` refuse them (exit 1), with
the exact re-check named as the reason.

1. *Unstable model.* One component ``A_0`` of mode ``a`` is negated: its eigenvalues move to the
   right half plane, and ``A_0^T P + P A_0`` is positive definite.
2. *Below floating-point resolution.* Mode ``b`` gets ``A_k = -I`` and a ``P`` whose second
   ``LDL^T`` pivot is ``-2.4e-17`` (``-1.5e-17 ||P||``) exactly: ``P`` is indefinite and so is
   ``A_k^T P + P A_k = -2 P``. The error of a floating-point eigenvalue or Cholesky computation
   is of order ``n eps ||P|| ~ 4e-16 ||P||``, 30 times larger than that pivot, so no float check
   can decide the sign: on the machine this was written on ``eigvalsh`` returns ``+5.6e-17`` for
   ``P`` and ``-1.1e-16`` for ``-2 P`` and ``cholesky(P)`` succeeds; any float check with a
   tolerance above its own error accepts it everywhere. The test asserts the machine-independent
   part (the exact pivot, and acceptance by a tolerant float check) and that the exact check
   refuses it.

Each forgery is a detector test: with the exact verdict removed from
``tli_verify.certification.certificate._check_mode`` both are accepted and these tests fail (checked
by hand when they were written; see the commit message).
"""

from __future__ import annotations

import json
import shutil
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.evidence import attach_evidence
from tli_verify.certification.certificate import (
    certificate_digest,
    check_certificate,
    issue_certificate,
    write_certificate,
)
from tli_verify.certification.exact import positive_definite, to_fractions
from tli_verify.cli import main
from tli_verify.io import canonical_json, sha256_file

# P of forgery 2: P[1][1] is the largest float below P[1][0]^2 / P[0][0] (found by a seeded
# search for a P that this machine's eigvalsh and cholesky both call positive definite).
SUBTLE_P = [[0.5512303663035244, -0.7334772992621839],
            [-0.7334772992621839, 0.9759784319224423]]


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def fresh(tmp_path: Path, repo: Path) -> Path:
    """A project with a stable copy of the scoop model and a certificate issued just now."""
    for sub, name in (("models", "scoop.model.json"), ("specs", "scoop.toml")):
        (tmp_path / sub).mkdir()
        shutil.copy(repo / sub / name, tmp_path / sub / name)
    (tmp_path / "certificates").mkdir()
    cert = tmp_path / "certificates" / "scoop.cert.json"
    write_certificate(issue_certificate(tmp_path / "models" / "scoop.model.json",
                                        cert_path=cert, dt="1/100"), cert)  # the task's dt
    attach_evidence(tmp_path)  # binding-only campaign evidence: the gate's other checks pass
    return tmp_path


def _forge(root: Path, mode: str, *, A: list[Any] | None = None,
           P: list[list[float]] | None = None) -> tuple[Path, Path]:
    """Edit the model's mode, then make the certificate consistent with it again.

    Everything a hash or a float comparison protects is recomputed the way
    ``issue_certificate`` computes it: the model's SHA-256, ``P`` (the model's, so certificate
    and runtime share it), the eigenvalues, and the digest.
    """
    model_path = root / "models" / "scoop.model.json"
    cert_path = root / "certificates" / "scoop.cert.json"
    model = json.loads(model_path.read_text())
    entry = model["modes"][mode]
    if A is not None:
        for comp, a in zip(entry["components"], A, strict=True):
            comp["A"] = a
    if P is not None:
        entry["P"] = P
    model_path.write_text(canonical_json(model))

    cert = json.loads(cert_path.read_text())
    cert["model"]["sha256"] = sha256_file(model_path)
    Pm = np.array(entry["P"], dtype=np.float64)
    As = np.array([c["A"] for c in entry["components"]], dtype=np.float64)
    rec = cert["modes"][mode]
    rec["P"] = entry["P"]
    rec["lambda_min_P"] = float(np.linalg.eigvalsh(Pm).min())
    rec["lambda_max"] = [float(np.linalg.eigvalsh(a.T @ Pm + Pm @ a).max()) for a in As]
    cert["digest"] = certificate_digest(cert)
    cert_path.write_text(canonical_json(cert))
    return model_path, cert_path


def _assert_refused(root: Path, cert: Path, mode: str, capsys: pytest.CaptureFixture[str],
                    reason: str) -> None:
    """check-cert and gate exit 1, the exact re-check is the reason, and nothing else is."""
    check = check_certificate(cert)
    assert not check.ok
    exact = [p for p in check.problems if p.startswith(f"mode {mode!r}")
             and "(exact re-check)" in p]
    assert any(reason in p for p in exact), check.problems
    # the forgery is self-consistent: no integrity check notices it
    assert not any("digest" in p or "SHA-256" in p or "differs" in p for p in check.problems)

    code, out, err = _run(capsys, "check-cert", str(cert))
    assert code == 1
    assert any(line.startswith("FAIL") and reason in line and "(exact re-check)" in line
               for line in out.splitlines()), out
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err

    code, out, err = _run(capsys, "gate", str(root))
    assert code == 1
    blocks = [line for line in out.splitlines() if line.startswith("BLOCK")]
    assert any("certificate" in line and "(exact re-check)" in line and reason in line
               for line in blocks), out
    assert err.startswith("error: gate blocked") and "Traceback" not in err


def test_fresh_certificate_passes(fresh: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Control: before the forgery, the same project passes check-cert and the gate."""
    cert = fresh / "certificates" / "scoop.cert.json"
    assert _run(capsys, "check-cert", str(cert))[0] == 0
    code, out, _ = _run(capsys, "gate", str(fresh))
    assert code == 0, out


def test_forged_certificate_of_an_unstable_model(fresh: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    model = json.loads((fresh / "models" / "scoop.model.json").read_text())
    A = [c["A"] for c in model["modes"]["a"]["components"]]
    A0 = np.array(A[0])
    A[0] = (-A0).tolist()
    assert np.linalg.eigvals(-A0).real.min() > 0  # the forged vertex is unstable
    _, cert = _forge(fresh, "a", A=A)
    doc = json.loads(cert.read_text())
    assert doc["modes"]["a"]["lambda_max"][0] > 0  # recorded honestly: only re-checking tells
    _assert_refused(fresh, cert, "a", capsys,
                    "component 0: A_k^T P + P A_k is not negative definite")


def test_forged_p_below_float_resolution(fresh: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    P = np.array(SUBTLE_P)
    Pq = to_fractions(P)
    pivot = Pq[1][1] - Pq[1][0] * Pq[0][1] / Pq[0][0]
    norm = float(np.linalg.norm(P, 2))
    eps = float(np.finfo(np.float64).eps)
    # exactly indefinite, by a pivot far below what a float computation resolves
    assert pivot < 0
    assert -pivot < Fraction(eps * norm) / 10
    assert not positive_definite(Pq).positive
    # a float eigenvalue check with a tolerance above its own error (~ n eps ||P||) accepts it
    tol = 1e-13 * norm
    assert np.linalg.eigvalsh(P).min() > -tol
    assert np.linalg.eigvalsh(-2.0 * P).max() < tol

    model = json.loads((fresh / "models" / "scoop.model.json").read_text())
    K = len(model["modes"]["b"]["components"])
    _, cert = _forge(fresh, "b", A=[(-np.eye(2)).tolist()] * K, P=SUBTLE_P)
    _assert_refused(fresh, cert, "b", capsys,
                    "P is not positive definite (leading principal minor of order 2")
