"""The Franka project and the policy its files make: the bundled project (:func:`project_dir`,
``sim/franka``), its recorded demonstrations (:func:`bundled_demos`), and :func:`load_policy`,
a variant's executive from a project's model behind its certificate (paper Sec. 7.2).
"""

from __future__ import annotations

import os
from pathlib import Path

from tli_verify.demos import Demonstration, load_demos
from tli_verify.errors import CertificateError, TliError
from tli_verify.io import bundled_dir
from tli_verify.loaded import load_project
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.runtime.setup import VARIANTS as RUNTIME_VARIANTS
from tli_verify.sim.demos import CONTROL_DT
from tli_verify.sim.franka_files import MODEL_NAME

__all__ = ["VARIANTS", "bundled_demos", "load_policy", "project_dir"]

VARIANTS = tuple(v for v in RUNTIME_VARIANTS if v != "BC")
"""The runtime's variants (:data:`tli_verify.runtime.setup.VARIANTS`) the robot runs: all but
``BC``, whose per-mode networks are trained on the kinematic tasks only (the Franka project
has no BC model to load)."""


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
        project = load_project(model=model, certificate=cert)
    except TliError as exc:
        if "certificate" in str(exc):
            raise CertificateError(f"refused: {exc}") from None
        raise
    task = project.task
    if abs(task.dt - CONTROL_DT) > 1e-12:
        raise TliError(f"{task.where}: dt {task.dt:g} s, but the Franka loop controls at "
                       f"{CONTROL_DT:g} s")
    return project.policy(variant)
