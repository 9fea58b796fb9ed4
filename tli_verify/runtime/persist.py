"""Save a model with the cuts learned online as a new, certified model file.

The certificate proves the model's own ``P`` (continuous time, sampled data at ``dt``, decay
rate); cuts are covered by it (modulation keeps ``V`` decreasing, paper Thm. 1), and the
certificate binds the file's exact bytes, cuts included, so the gate accepts the new pair.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

from tli_verify.defaults import DEFAULT_DT
from tli_verify.io import atomic_write_bytes
from tli_verify.model.serialize import relocate_model, save_model
from tli_verify.model.types import Model

__all__ = ["save_certified"]


def save_certified(model: Model, model_path: str | os.PathLike[str],
                   cert_path: str | os.PathLike[str], *,
                   dt: Fraction | str = DEFAULT_DT) -> Model:
    """Write ``model`` (with its cuts) to ``model_path`` and a re-issued certificate.

    Both files are written atomically; the model file is written only after its certificate
    has been issued (for a temporary copy), so a model that does not certify leaves nothing
    behind, and an existing file at either path is replaced only by a certified pair.

    Parameters
    ----------
    model : Model
        E.g. ``policy.model`` after an episode (cuts learned online).
    model_path, cert_path : path-like
        The new files (relative paths inside are rewritten for their directories).
    dt : Fraction or str, optional
        Control period the certificate proves.

    Returns
    -------
    Model
        The model as written (its ``path`` is ``model_path``).

    Raises
    ------
    CertificateError
        A DS does not certify (nothing is written).
    ModelError
        The model does not validate (nothing is written).
    """
    from tli_verify.certification.certificate import issue_certificate, write_certificate

    out = Path(model_path)
    cert = Path(cert_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    cert.parent.mkdir(parents=True, exist_ok=True)
    moved = relocate_model(model, out)
    tmp = out.with_name(f".{out.name}.{os.getpid()}.tmp")
    try:
        save_model(moved, tmp)
        issue_certificate(tmp, cert_path=cert, dt=dt)  # raises before anything is final
        atomic_write_bytes(out, tmp.read_bytes())
    finally:
        tmp.unlink(missing_ok=True)
    write_certificate(issue_certificate(out, cert_path=cert, dt=dt), cert)
    return moved
