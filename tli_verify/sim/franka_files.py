"""The files of a Franka project -- spec, model and certificate -- and their hashes.

:func:`project_files` finds them (the spec is the one the model names; the certificate is
``<certificates>/franka-scoop.cert.json``, stem :data:`MODEL_NAME`) and :func:`hash_files` hashes
them when a physical campaign starts, so that the evidence binds the files the trials ran on
(:mod:`tli_verify.sim.physics_evidence` refuses a file changed in between). Light on purpose:
``tli sim`` reads :data:`MODEL_NAME` before it may import MuJoCo (the policy they make:
:mod:`tli_verify.sim.franka_project`).
"""

from __future__ import annotations

import os
from pathlib import Path

from tli_verify.errors import TliError
from tli_verify.io import sha256_file

__all__ = [
    "MODEL_NAME",
    "hash_files",
    "project_files",
]


MODEL_NAME = "franka-scoop"
"""Stem of the Franka project's model, certificate and evidence files."""


def project_files(root: str | os.PathLike[str],
                  certificates: str | os.PathLike[str] | None = None) -> dict[str, Path]:
    """The spec (the one the model names), model and certificate of a Franka project.

    Raises
    ------
    TliError
        (exit 2) The model does not load or names no spec.
    """
    from tli_verify.model.serialize import load_model

    base = Path(root)
    model = base / "models" / f"{MODEL_NAME}.model.json"
    if not model.is_file():
        raise TliError(f"{model}: no Franka scoop model in the project")
    spec = load_model(model).spec_path
    if spec is None:
        raise TliError(f"{model}: names no spec")
    return {"spec": Path(spec), "model": model,
            "certificate": (Path(certificates) if certificates is not None
                            else base / "certificates") / f"{MODEL_NAME}.cert.json"}


def hash_files(root: str | os.PathLike[str],
               certificates: str | os.PathLike[str] | None = None
               ) -> tuple[tuple[str, str, str], ...]:
    """``(name, path, SHA-256)`` of the project's spec, model and certificate (the certificate
    may be missing: then the policy refuses to load)."""
    return tuple((k, str(p), sha256_file(p) if p.is_file() else "")
                 for k, p in project_files(root, certificates).items())
