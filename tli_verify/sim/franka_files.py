"""The files of a Franka project -- spec, model and certificate --, their hashes and the policy
they make.

The bundled project is :func:`project_dir` (``sim/franka``), its recorded demonstrations
:func:`bundled_demos`; :func:`load_policy` builds a variant's executive from a project's model
behind its certificate. :func:`project_files` finds the files (the spec is the one the model
names; the certificate is ``<certificates>/franka-scoop.cert.json``, stem :data:`MODEL_NAME`)
and :func:`hash_files` hashes them when a physical campaign starts, so that the evidence binds
the files the trials ran on (:mod:`tli_verify.sim.physics_evidence` refuses a file changed in
between).
"""

from __future__ import annotations

import os
from pathlib import Path

from tli_verify.demos import Demonstration, load_demos
from tli_verify.errors import CertificateError, TliError
from tli_verify.io import bundled_dir, sha256_file
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.setup import VARIANTS as RUNTIME_VARIANTS
from tli_verify.runtime.setup import load_setup, make_policy
from tli_verify.sim.demos import CONTROL_DT
from tli_verify.tasks.project import resolve

__all__ = [
    "MODEL_NAME",
    "VARIANTS",
    "bundled_demos",
    "hash_files",
    "load_policy",
    "project_dir",
    "project_files",
]


MODEL_NAME = "franka-scoop"
"""Stem of the Franka project's model, certificate and evidence files."""
VARIANTS = tuple(v for v in RUNTIME_VARIANTS if v != "BC")
"""The runtime's variants (:data:`tli_verify.runtime.setup.VARIANTS`) the robot runs: all but
``BC``, whose per-mode networks are trained on the kinematic tasks only (the Franka project
has no BC model to load)."""


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


def project_dir() -> Path:
    """The bundled Franka project: ``sim/franka`` with ``specs/``, ``models/``,
    ``certificates/`` and ``demos/franka/`` (outside the repository's deployed ``models/``:
    the gate requires campaign evidence this policy does not have yet, ``docs/howto/franka.md``)."""
    return bundled_dir("sim") / "franka"


def bundled_demos() -> list[Demonstration]:
    """The recorded Franka demonstrations (:func:`project_dir` ``/demos/franka``)."""
    return load_demos(sorted((project_dir() / "demos" / "franka").glob("*.csv")))


def load_policy(variant: str, *, root: str | os.PathLike[str] | None = None,
                certificates: str | os.PathLike[str] | None = None) -> LTLDSPolicy:
    """The executive of ``variant`` for the bundled Franka scoop model, behind its certificate.

    Parameters
    ----------
    variant : str
        One of :data:`VARIANTS`.
    root : path-like, optional
        Project directory with ``specs/``, ``models/`` (default: the parent of
        ``certificates`` when given, else the bundled ``sim/franka``).
    certificates : path-like, optional
        Directory of ``franka-scoop.cert.json`` (default ``<root>/certificates``).

    Raises
    ------
    CertificateError
        (exit 1) The certificate is missing, does not re-check, or does not cover the model
        (naming the certificate).
    """
    if variant not in VARIANTS:
        raise TliError(f"unknown variant {variant!r} (one of {', '.join(VARIANTS)})")
    if root is not None:
        base = Path(root)
    elif certificates is not None:
        base = Path(certificates).parent  # a project: models/ and specs/ next to it
    else:
        base = project_dir()
    model = base / "models" / f"{MODEL_NAME}.model.json"
    cert = (Path(certificates) / f"{MODEL_NAME}.cert.json" if certificates is not None
            else None)
    if cert is not None and not cert.is_file():
        raise CertificateError(f"{cert}: refused: no certificate for models/"
                               f"{MODEL_NAME}.model.json (certify it with tli certify)")
    try:
        resolved = resolve(model=model, certificate=cert)
    except TliError as exc:
        if "certificate" in str(exc):
            raise CertificateError(f"refused: {exc}") from None
        raise
    setup = load_setup(resolved)
    if abs(setup.task.dt - CONTROL_DT) > 1e-12:
        raise TliError(f"{setup.task.where}: dt {setup.task.dt:g} s, but the Franka loop "
                       f"controls at {CONTROL_DT:g} s")
    return make_policy(setup, variant)
