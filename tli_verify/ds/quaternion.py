"""An orientation DS on the unit quaternions: LPV-DS in the tangent space at the attractor.

After SE(3) LPV-DS (Sun & Figueroa, IROS 2024, its ``quaternion_ds`` part), written anew here.
Quaternions are scalar-first ``q = (w, x, y, z)`` throughout (files may declare either
convention, :func:`tli_verify.demos.load_pose_demo` converts).

Tangent coordinates (the double cover handled)
    A rotation has two unit quaternions, ``q`` and ``-q``. For the attractor ``q*`` the error
    quaternion ``e = q*^{-1} (x) q`` is put in the hemisphere ``w >= 0`` (equivalently:
    ``q`` in the hemisphere of ``q*``, ``<q, q*> >= 0``) and mapped by the logarithm of SO(3),

        xi = log_{q*}(q) = theta u,   e = (cos(theta/2), sin(theta/2) u),  0 <= theta <= pi,

    the rotation vector of ``q*^{-1} q`` (radians, in the attractor's frame). ``xi`` depends
    on the rotation only: ``log_{q*}(q) = log_{q*}(-q)``, so the DS below is a function of the
    rotation, not of the sign of its quaternion (the anchor doubles its mixture to the same
    end). The inverse is ``q = exp_{q*}(xi) = q* (x) (cos(|xi|/2), sin(|xi|/2) xi/|xi|)``.
    ``log_{q*}`` is a bijection from the rotations at angle ``< pi`` from ``q*`` onto the
    open ball ``|xi| < pi`` (smooth there, with smooth inverse ``exp_{q*}``).

The DS
    ``xi_dot = f(xi) = sum_k gamma_k(xi) A_k xi`` -- an LPV-DS (:class:`~tli_verify.ds.lpvds.LPVDS`)
    with attractor ``0`` in tangent coordinates, learned by the same convex programs as position
    (:func:`~tli_verify.ds.lpvds.learn_lpvds`: mixture, P-QLF ``P``, Lyapunov-constrained
    least squares, cvxpy + Clarabel), with its own Lyapunov function ``V(xi) = xi^T P xi``.
    The orientation is *defined* by ``xi``: the controller keeps ``xi`` and recovers the
    commanded orientation as ``exp_{q*}(xi)``; no approximation of the map enters.

Stability argument
    With ``P > 0``, ``A_k^T P + P A_k < 0`` and, at the control period ``dt``,
    ``(I + dt A_k)^T P (I + dt A_k) - P < 0`` for every k, each controller step
    ``xi+ = xi + dt f(xi) = (I + dt sum_k gamma_k A_k) xi`` decreases ``V`` (the P-norm is
    convex and the ``gamma_k`` are convex weights). The tangent chart is valid while
    ``|xi| < pi``: every sub-level set ``{V < c}`` with ``c <= lambda_min(P) pi^2`` lies in
    that ball, so a start with ``V(xi_0) < c`` keeps ``V`` below ``c`` and the whole run stays
    in the chart, converging to ``xi = 0``, i.e. to the rotation of ``q*``. The certificate
    (:mod:`tli_verify.certification.orientation`) decides all of it in exact arithmetic, with
    ``c`` stated as a rational below ``lambda_min(P) pi^2``.

Coupling with position: the pose DS is the pair (position LPV-DS on ``x``, this DS on ``xi``),
decoupled; ``V_pose = V_x + V_xi`` decreases whenever both do, so the two certificates together
certify the pose.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.ds.lpvds import LPVDS, FitInfo, learn_lpvds
from tli_verify.ds.lyapunov import RATE_BUDGET
from tli_verify.errors import ModelError
from tli_verify.io import atomic_write_text, canonical_json, read_json
from tli_verify.rotations import (
    canonical_hemisphere,
    quat_exp,
    quat_log,
    quat_multiply,
    rotation_angle,
)

__all__ = [
    "ORIENTATION_MODEL_KIND",
    "QuaternionDS",
    "canonical_hemisphere",
    "learn_quaternion_ds",
    "load_orientation_model",
    "quat_exp",
    "quat_log",
    "quat_multiply",
    "rotation_angle",
    "write_orientation_model",
]

FloatArray = npt.NDArray[np.float64]

ORIENTATION_MODEL_KIND = "tli-verify/orientation-ds"
"""``kind`` of an orientation model file (:func:`write_orientation_model`)."""


@dataclass(frozen=True, slots=True, eq=False)
class QuaternionDS:
    """An orientation DS: LPV-DS in the tangent coordinates at ``q*`` (module docstring).

    Attributes
    ----------
    attractor : ndarray, shape (4,)
        ``q*``, unit, scalar-first.
    tangent : LPVDS
        The DS ``xi_dot = sum_k gamma_k(xi) A_k xi`` in tangent coordinates (dimension 3,
        attractor 0); its ``P`` is the orientation Lyapunov matrix.
    """

    attractor: FloatArray
    tangent: LPVDS

    def __post_init__(self) -> None:
        q = np.array(self.attractor, dtype=np.float64)
        if q.shape != (4,) or not np.all(np.isfinite(q)) \
                or abs(float(np.linalg.norm(q)) - 1.0) > 1e-9:
            raise ModelError(f"orientation attractor must be a unit quaternion (w, x, y, z), "
                             f"got {self.attractor!r}")
        if self.tangent.dim != 3 or np.any(self.tangent.attractor != 0.0):
            raise ModelError("the tangent-space DS must be 3-dimensional with attractor 0")
        q.setflags(write=False)
        object.__setattr__(self, "attractor", q)

    @property
    def P(self) -> FloatArray:
        """Orientation Lyapunov matrix, shape (3, 3)."""
        return self.tangent.P

    @property
    def A(self) -> FloatArray:
        """Linear systems in tangent coordinates, shape (K, 3, 3)."""
        return self.tangent.A

    def tangent_coordinates(self, Q: npt.ArrayLike) -> FloatArray:
        """``xi = log_{q*}(q)``, shape (N, 3) or (3,)."""
        return quat_log(Q, self.attractor)

    def tangent_velocity(self, Q: npt.ArrayLike) -> FloatArray:
        """``xi_dot = f(log_{q*}(q))``, shape (N, 3) or (3,)."""
        return self.tangent.velocity(self.tangent_coordinates(Q))

    def lyapunov(self, Q: npt.ArrayLike) -> FloatArray:
        """``V = xi^T P xi`` at each orientation, shape (N,) or ()."""
        return self.tangent.lyapunov(self.tangent_coordinates(Q))

    def rollout(self, q0: npt.ArrayLike, *, dt: float, steps: int) -> FloatArray:
        """The controller's run from ``q0``: ``xi+ = xi + dt f(xi)``, ``q = exp_{q*}(xi)``.

        Parameters
        ----------
        q0 : array_like, shape (4,)
            Start, at a rotation angle ``< pi`` from ``q*``.
        dt : float
            Control period.
        steps : int
            Number of steps.

        Returns
        -------
        ndarray, shape (steps + 1, 4)
            Orientations, scalar-first, in the hemisphere of ``q*``.

        Raises
        ------
        ModelError
            The start is at angle ``pi`` (or more) from ``q*``: outside the tangent chart.
        """
        xi = self.tangent_coordinates(np.asarray(q0, dtype=np.float64))
        if not float(np.linalg.norm(xi)) < math.pi - 1e-9:
            raise ModelError("start orientation is a half turn from the attractor: outside the "
                             "tangent chart of the orientation DS")
        out = np.empty((steps + 1, 3))
        out[0] = xi
        for i in range(steps):
            xi = xi + dt * self.tangent.velocity(xi)
            out[i + 1] = xi
        return quat_exp(out, self.attractor)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready parameters (floats round-trip exactly through JSON)."""
        t = self.tangent
        return {"attractor": self.attractor.tolist(), "priors": t.priors.tolist(),
                "means": t.means.tolist(), "covs": t.covs.tolist(), "A": t.A.tolist(),
                "P": t.P.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, where: str = "orientation") -> QuaternionDS:
        """Inverse of :meth:`to_dict`.

        Raises
        ------
        ModelError
            A field is missing or malformed (named with ``where``).
        """
        try:
            tangent = LPVDS(attractor=np.zeros(3), priors=np.asarray(data["priors"], float),
                            means=np.asarray(data["means"], float),
                            covs=np.asarray(data["covs"], float),
                            A=np.asarray(data["A"], float), P=np.asarray(data["P"], float))
            return cls(attractor=np.asarray(data["attractor"], float), tangent=tangent)
        except KeyError as exc:
            raise ModelError(f"{where}: missing field {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{where}: malformed orientation DS: {exc}") from None


def tangent_data(times: Sequence[npt.ArrayLike], quaternions: Sequence[npt.ArrayLike],
                 attractor: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Tangent coordinates and their time derivatives of every demonstration.

    Parameters
    ----------
    times : sequence of array_like, each shape (T_d,)
        Strictly increasing time stamps.
    quaternions : sequence of array_like, each shape (T_d, 4)
        Unit quaternions (scalar-first).
    attractor : array_like, shape (4,)

    Returns
    -------
    Xi : ndarray, shape (sum T_d, 3)
    dXi : ndarray, shape (sum T_d, 3)
        Second-order finite differences of ``xi`` on each demonstration's time grid.

    Raises
    ------
    ModelError
        A sample is a half turn (or more) from ``q*``: outside the tangent chart.
    """
    xs, dxs = [], []
    for t, Q in zip(times, quaternions, strict=True):
        xi = quat_log(np.asarray(Q, dtype=np.float64), attractor)
        far = np.linalg.norm(xi, axis=1) >= math.pi - 1e-6
        if np.any(far):
            raise ModelError(f"orientation sample {int(np.flatnonzero(far)[0])} is a half turn "
                             "from the attractor: outside the tangent chart")
        xs.append(xi)
        dxs.append(np.gradient(xi, np.asarray(t, dtype=np.float64), axis=0, edge_order=2))
    return np.concatenate(xs), np.concatenate(dxs)


def learn_quaternion_ds(
    times: Sequence[npt.ArrayLike],
    quaternions: Sequence[npt.ArrayLike],
    attractor: npt.ArrayLike | None = None,
    *,
    seed: int = 0,
    rate_budget: float | None = RATE_BUDGET,
    control_dt: float | None = DEFAULT_DT_FLOAT,
    max_components: int = 12,
) -> tuple[QuaternionDS, FitInfo]:
    """Learn a certified orientation DS from orientation demonstrations.

    Parameters
    ----------
    times : sequence of array_like, each shape (T_d,)
        Time stamps of each demonstration.
    quaternions : sequence of array_like, each shape (T_d, 4)
        Unit quaternions (scalar-first), hemisphere-continuous or not (either sign).
    attractor : array_like, shape (4,), optional
        ``q*``; default: the mean of the demonstrations' last orientations (normalised, signs
        aligned to the first).
    seed : int, optional
        Seed of the mixture.
    rate_budget, control_dt, max_components
        As :func:`~tli_verify.ds.lpvds.learn_lpvds` (the rate choice under the budget and the
        sampled-data constraint at ``control_dt`` by default, as ``tli learn``).

    Returns
    -------
    ds : QuaternionDS
    info : FitInfo
        Of the tangent-space LPV-DS.
    """
    if attractor is None:
        ends = np.array([np.asarray(Q, dtype=np.float64)[-1] for Q in quaternions])
        ends = canonical_hemisphere(ends, ends[0])
        q_star = ends.mean(axis=0)
    else:
        q_star = np.asarray(attractor, dtype=np.float64)
    norm = float(np.linalg.norm(q_star))
    if not (np.isfinite(norm) and norm > 0.0):
        raise ModelError("orientation attractor is zero or not finite")
    q_star = q_star / norm
    if q_star[0] < 0.0:  # the same rotation, stated with w >= 0
        q_star = -q_star
    Xi, dXi = tangent_data(times, quaternions, q_star)
    tangent, info = learn_lpvds(Xi, dXi, np.zeros(3), seed=seed, rate_budget=rate_budget,
                                control_dt=control_dt, max_components=max_components)
    return QuaternionDS(attractor=q_star, tangent=tangent), info


def write_orientation_model(ds: QuaternionDS, path: str | os.PathLike[str], *,
                            fit: FitInfo | None = None) -> None:
    """Write an orientation DS as canonical JSON (atomic; floats round-trip exactly).

    Fields: ``kind`` (:data:`ORIENTATION_MODEL_KIND`), ``version`` (1), ``convention``
    (``"scalar-first"``: the attractor is ``(w, x, y, z)``), ``orientation``
    (:meth:`QuaternionDS.to_dict`), and ``fit`` (how it was learned, when given).

    Parameters
    ----------
    ds : QuaternionDS
    path : path-like
    fit : FitInfo, optional
    """
    import dataclasses

    doc: dict[str, Any] = {"kind": ORIENTATION_MODEL_KIND, "version": 1,
                           "convention": "scalar-first", "orientation": ds.to_dict()}
    if fit is not None:
        doc["fit"] = dataclasses.asdict(fit)
    atomic_write_text(path, canonical_json(doc))


def load_orientation_model(path: str | os.PathLike[str]) -> QuaternionDS:
    """Read an orientation model file (:func:`write_orientation_model`).

    Raises
    ------
    ModelError
        Unreadable, not JSON, another kind of file, or malformed parameters (naming the file).
    """
    doc = read_json(path, what="orientation model", error=ModelError)
    if not isinstance(doc, dict) or doc.get("kind") != ORIENTATION_MODEL_KIND:
        raise ModelError(f"{path}: not an orientation model (kind must be "
                         f"{ORIENTATION_MODEL_KIND!r})")
    if doc.get("version") != 1 or doc.get("convention") != "scalar-first":
        raise ModelError(f"{path}: version must be 1 and convention 'scalar-first'")
    body = doc.get("orientation")
    if not isinstance(body, dict):
        raise ModelError(f"{path}: orientation: missing or not an object")
    return QuaternionDS.from_dict(body, where=f"{path}: orientation")
