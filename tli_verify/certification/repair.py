"""``tli certify --repair``: a new model whose own P certifies (the one-P rule, paper Thm. 1).

Paper Thm. 1 (the modulated DS keeps ``V`` decreasing and never leaves its mode) holds for the
``P`` the modulation's corner guard uses, which is the model's ``P``. A certificate must
therefore prove that very ``P``: :func:`tli_verify.certification.certificate.issue_certificate`
refuses a model whose ``P`` fails. Searching another ``P`` is an explicit step that writes a
*new* model, so the runtime and the certificate cannot disagree: this module.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

from tli_verify.certification.exact import check_lyapunov
from tli_verify.ds.lpvds import LPVDS
from tli_verify.ds.lyapunov import find_p
from tli_verify.errors import CertificateError, SolverError
from tli_verify.model.serialize import load_model, relocate_model
from tli_verify.model.types import ModeModel

if TYPE_CHECKING:
    from tli_verify.model.types import Model

__all__ = ["RepairResult", "repair_model"]


@dataclass(frozen=True, slots=True)
class RepairResult:
    """What :func:`repair_model` changed.

    Attributes
    ----------
    model : Model
        The new model (not yet written), located at the new path.
    repaired : tuple of str
        Keys whose ``P`` was replaced.
    kept : tuple of str
        Keys whose own ``P`` already certifies.
    """

    model: Model
    repaired: tuple[str, ...]
    kept: tuple[str, ...]


def repair_model(model_path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
                 dt: Fraction) -> RepairResult:
    """Replace every ``P`` that does not certify with one found by an SDP and checked exactly.

    Parameters
    ----------
    model_path : path-like
        The model to repair.
    out_path : path-like
        Where the new model will be written (its spec and demonstration paths are rewritten
        relative to it).
    dt : Fraction
        Control period of the sampled-data conditions.

    Returns
    -------
    RepairResult

    Raises
    ------
    CertificateError
        A DS has no common quadratic Lyapunov function, or the SDP's ``P`` fails the exact check
        (exit 1, naming the mode).
    """
    model = load_model(model_path)
    modes = dict(model.modes)
    repaired, kept = [], []
    for key, mm in model.modes.items():
        if check_lyapunov(mm.ds.P, mm.ds.A, dt=dt).ok:
            kept.append(key)
            continue
        try:
            P, info = find_p(mm.ds.A, dt=float(dt))
        except SolverError as exc:
            raise CertificateError(f"{model_path}: mode {key!r}: no common quadratic Lyapunov "
                                   f"function at dt = {dt} ({exc})") from None
        verdict = check_lyapunov(P, mm.ds.A, dt=dt)
        if not verdict.ok:
            raise CertificateError(f"{model_path}: mode {key!r}: the SDP's P fails the exact "
                                   f"check: {verdict.failures()[0]}")
        ds = mm.ds
        new_ds = LPVDS(attractor=ds.attractor, priors=ds.priors, means=ds.means, covs=ds.covs,
                       A=ds.A, P=P)
        fit = dict(mm.fit or {})
        fit["P_repair"] = {"solver": info.solver, "status": info.status,
                           "dt": str(dt), "from": Path(model_path).name}
        modes[key] = ModeModel(key=mm.key, mode=mm.mode, next_mode=mm.next_mode, ds=new_ds,
                               cuts=mm.cuts, fit=MappingProxyType(fit))
        repaired.append(key)
    new = relocate_model(model, out_path, modes=MappingProxyType(modes))
    return RepairResult(new, tuple(repaired), tuple(kept))
