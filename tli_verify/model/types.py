"""The model's values: one LPV-DS (and its cuts) per mode or mode transition.

:class:`ModeModel` (the policy of one mode or transition) and :class:`Model` (all of them,
with the spec they were learned for) are validated on construction against the limits of
:mod:`tli_verify.limits` (:func:`numeric_limits`: the numbers a certificate records).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import Modulator, check_control_period
from tli_verify.ds.lpvds import LPVDS
from tli_verify.errors import ModelError
from tli_verify.io import (
    field_path,
)
from tli_verify.limits import (
    COV_MAX_CONDITION,
    COV_MIN_EIGENVALUE,
    MAX_ABS_COVARIANCE,
    MAX_ABS_VALUE,
    PRIOR_SUM_TOL,
)

__all__ = [
    "SCHEMA_VERSION",
    "TRANSITION",
    "ModeModel",
    "Model",
    "check_covariance",
    "check_range",
    "check_symmetric",
    "numeric_limits",
]


FloatArray = npt.NDArray[np.float64]


SCHEMA_VERSION = 1


TRANSITION = "->"


_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_]+$")


def numeric_limits() -> dict[str, float]:
    """The numeric ranges every loaded model satisfies (for the certificate to record).

    Within them the velocity ``f(x)`` (paper eq. 4), its mixing weights and ``M(x) f(x)``
    (eq. 7) are finite and well defined at every state with ``|x_i| <= max_abs_value``
    (:mod:`tli_verify.limits`).

    Returns
    -------
    dict
        ``max_abs_value`` (every number of the model but the covariances, and the states at
        which the velocity is guaranteed finite), ``max_abs_covariance``, ``cov_min_eigenvalue``
        and ``cov_max_condition`` (every GMM covariance is symmetric positive definite within
        these bounds), ``prior_sum_tolerance`` (priors > 0 sum to 1 within it).
    """
    return {"max_abs_value": MAX_ABS_VALUE, "max_abs_covariance": MAX_ABS_COVARIANCE,
            "cov_min_eigenvalue": COV_MIN_EIGENVALUE, "cov_max_condition": COV_MAX_CONDITION,
            "prior_sum_tolerance": PRIOR_SUM_TOL}


def check_range(value: Any, parts: list[str | int], where: str) -> None:
    """Every number under ``value`` is within ``MAX_ABS_VALUE`` (``MAX_ABS_COVARIANCE`` under a
    ``cov`` field); errors name the entry."""
    stack: list[tuple[Any, list[str | int]]] = [(value, parts)]
    while stack:
        v, loc = stack.pop()
        if isinstance(v, bool):
            continue
        if isinstance(v, int | float):
            cov = "cov" in loc
            bound = MAX_ABS_COVARIANCE if cov else MAX_ABS_VALUE
            if not abs(v) <= bound:  # also NaN
                shown = f"{v:.6g}" if isinstance(v, float) else (
                    str(v) if abs(v) < 10**30 else f"an integer of {len(str(abs(v)))} digits")
                name = "MAX_ABS_COVARIANCE" if cov else "MAX_ABS_VALUE"
                raise ModelError(f"{where}: {field_path(loc)}: {shown} is outside the declared "
                                 f"range |v| <= {bound:g} ({name})")
        elif isinstance(v, list):
            stack.extend((item, [*loc, i]) for i, item in enumerate(v))
        elif isinstance(v, dict):
            stack.extend((item, [*loc, k]) for k, item in v.items())


def check_covariance(cov: FloatArray, where: str) -> None:
    """Symmetric positive definite, safely invertible: eigenvalues and condition bounded."""
    check_symmetric(cov, where)
    eig = np.linalg.eigvalsh(cov)
    lo, hi = float(eig[0]), float(eig[-1])
    if not lo > 0:
        raise ModelError(f"{where}: not symmetric positive definite (smallest eigenvalue "
                         f"{lo:.3g})")
    if lo < COV_MIN_EIGENVALUE:
        raise ModelError(f"{where}: smallest eigenvalue {lo:.3g} is below "
                         f"{COV_MIN_EIGENVALUE:g} (COV_MIN_EIGENVALUE): its inverse would "
                         "overflow")
    if hi / lo > COV_MAX_CONDITION:
        raise ModelError(f"{where}: condition number {hi / lo:.3g} exceeds "
                         f"{COV_MAX_CONDITION:g} (COV_MAX_CONDITION): not safely invertible")


@dataclass(frozen=True, slots=True, eq=False)
class ModeModel:
    """The policy of one mode, or of one mode transition.

    Attributes
    ----------
    key : str
        Key in the model file (``mode`` or ``"mode->next"``).
    mode : str
        Mode name.
    next_mode : str or None
        Next mode of a per-transition DS (or the unique observed one).
    ds : LPVDS
        The nominal DS ``f``.
    cuts : tuple of Cut
        Cuts learned online (paper Sec. 5.2); empty after learning.
    fit : mapping or None
        How it was learned (informational).
    """

    key: str
    mode: str
    next_mode: str | None
    ds: LPVDS
    cuts: tuple[Cut, ...] = ()
    fit: Mapping[str, Any] | None = None
    _modulator: Any = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        """Freeze ``fit`` and build the modulator once for this cut set (paper eq. 7).

        Raises
        ------
        ModelError
            A cut of the wrong dimension, or one that leaves ``x*`` outside.
        """
        object.__setattr__(self, "cuts", tuple(self.cuts))
        if self.fit is not None and not isinstance(self.fit, MappingProxyType):
            object.__setattr__(self, "fit", MappingProxyType(dict(self.fit)))
        if self.cuts:
            object.__setattr__(self, "_modulator",
                               Modulator.build(self.cuts, self.ds.attractor, lyapunov=self.ds.P))

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle by value (a mappingproxy does not pickle); the modulator is rebuilt."""
        return (ModeModel, (self.key, self.mode, self.next_mode, self.ds, self.cuts,
                            dict(self.fit) if self.fit is not None else None))

    @property
    def modulator(self) -> Any:
        """The :class:`~tli_verify.boundary.modulation.Modulator` of the cuts (None without)."""
        return self._modulator

    def velocity(self, X: npt.ArrayLike, *, dt: float | None = None) -> FloatArray:
        """``M(x) f(x)`` (paper eq. 7 with the corner guard), or ``f(x)`` without cuts.

        The modulator is built once per cut set (in ``__post_init__``), not per call.

        Parameters
        ----------
        X : array_like, shape (N, n) or (n,)
        dt : float, optional
            Control period of a sampled-data loop (see :meth:`Model.velocity`).

        Returns
        -------
        ndarray, same shape as ``X``
        """
        check_control_period(dt)
        return self.modulate(X, self.ds.velocity(X), dt=dt)

    def modulate(self, X: npt.ArrayLike, F: npt.ArrayLike, *, dt: float | None = None
                 ) -> FloatArray:
        """``M(x) F`` for DS velocities ``F = f(X)`` already evaluated (``F`` without cuts).

        Lets a caller evaluate one DS for many modes' states at once (the batched executive:
        models that differ only in their learned cuts share the DS) and modulate per cut set.

        Parameters
        ----------
        X : array_like, shape (N, n) or (n,)
        F : array_like, same shape as ``X``
            ``self.ds.velocity(X)``.
        dt : float, optional
            Control period (see :meth:`velocity`; checked there).

        Returns
        -------
        ndarray, same shape as ``X``
        """
        F = np.asarray(F, dtype=np.float64)
        if self._modulator is None:
            return F
        single = F.ndim == 1
        Xa = np.atleast_2d(np.asarray(X, dtype=np.float64))
        out = self._modulator(Xa, np.atleast_2d(F), dt=dt)
        return np.asarray(out[0] if single else out, dtype=np.float64)

    def with_cuts(self, cuts: Sequence[Cut]) -> ModeModel:
        """A copy with the given cuts (validated, modulator rebuilt)."""
        return ModeModel(key=self.key, mode=self.mode, next_mode=self.next_mode, ds=self.ds,
                         cuts=tuple(cuts), fit=self.fit)


@dataclass(frozen=True, slots=True, eq=False)
class Model:
    """A loaded model file: per-mode (or per-transition) LPV-DS with cuts.

    Attributes
    ----------
    state_names : tuple of str
        Names of the ``n`` state coordinates.
    modes : mapping of str to ModeModel
        Key -> policy.
    spec : str or None
        The spec path as written in the file (relative to the model file).
    path : str or None
        The file it was loaded from.
    source : mapping or None
        Provenance (demonstration files and hashes, tool version).
    """

    state_names: tuple[str, ...]
    modes: Mapping[str, ModeModel]
    spec: str | None = None
    path: str | None = None
    source: Mapping[str, Any] | None = field(default=None)

    @property
    def dim(self) -> int:
        """State dimension n."""
        return len(self.state_names)

    @property
    def spec_path(self) -> Path | None:
        """The spec file resolved against the model file's directory (None if none).

        Resolved the way the operating system opens it (symlinks first, then ``..``), so the
        file certify hashes, the gate checks and the runtime loads is one and the same."""
        if self.spec is None:
            return None
        base = Path(self.path).parent if self.path else Path(".")
        return Path(os.path.realpath(base / self.spec))

    def key(self, mode: str, next_mode: str | None = None) -> str:
        """The key of the DS to run in ``mode`` (towards ``next_mode`` for per-transition DS).

        Raises
        ------
        ModelError
            If the model has no DS for that mode (or transition).
        """
        if next_mode is not None:
            k = f"{mode}{TRANSITION}{next_mode}"
            if k in self.modes:
                return k
        if mode in self.modes:
            return mode
        options = sorted(k for k, m in self.modes.items() if m.mode == mode)
        what = mode if next_mode is None else f"{mode}{TRANSITION}{next_mode}"
        hint = (f"; per-transition DS of this mode: {', '.join(options)} (pass next_mode)"
                if options else f"; known keys: {', '.join(sorted(self.modes))}")
        raise ModelError(f"{self.path or 'model'}: no DS for {what!r}{hint}")

    def velocity(self, X: npt.ArrayLike, mode: str, *, next_mode: str | None = None,
                 dt: float | None = None) -> FloatArray:
        """Velocity of the mode's policy: ``M(x) f(x)`` with the mode's cuts (paper eq. 7).

        Parameters
        ----------
        X : array_like, shape (N, n) or (n,)
            States.
        mode : str
            Mode name or model key (``"a"`` or ``"a->b"``).
        next_mode : str, optional
            For per-transition DS: the next mode the automaton plans.
        dt : float, optional
            Control period of the loop that applies the velocity; with it no step ``x + dt v``
            crosses a cut (:meth:`tli_verify.boundary.modulation.Modulator.__call__`).

        Returns
        -------
        ndarray, shape (N, n) or (n,)
        """
        return self.modes[self.key(mode, next_mode)].velocity(X, dt=dt)

    def nominal_velocity(self, X: npt.ArrayLike, mode: str, *,
                         next_mode: str | None = None) -> FloatArray:
        """``f(x)`` of the mode's LPV-DS without modulation (paper eq. 4)."""
        return self.modes[self.key(mode, next_mode)].ds.velocity(X)

    def __post_init__(self) -> None:
        if not isinstance(self.modes, MappingProxyType):
            object.__setattr__(self, "modes", MappingProxyType(dict(self.modes)))
        if self.source is not None and not isinstance(self.source, MappingProxyType):
            object.__setattr__(self, "source", MappingProxyType(dict(self.source)))

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickle by value (mappingproxies do not pickle), e.g. to send to worker processes."""
        source = json.loads(json.dumps(dict(self.source))) if self.source is not None else None
        return (Model, (self.state_names, dict(self.modes), self.spec, self.path, source))

    def with_cuts(self, key: str, cuts: Sequence[Cut]) -> Model:
        """A copy of the model whose DS ``key`` has the given cuts."""
        if key not in self.modes:
            raise ModelError(f"no DS {key!r} in the model")
        modes = dict(self.modes)
        modes[key] = self.modes[key].with_cuts(cuts)
        return Model(state_names=self.state_names, modes=MappingProxyType(modes),
                     spec=self.spec, path=self.path, source=self.source)

    def keys_of(self, mode: str) -> tuple[str, ...]:
        """Every DS key of a mode (the plain key and its per-transition keys), sorted."""
        return tuple(sorted(k for k, m in self.modes.items() if m.mode == mode))

    def region_cuts(self, mode: str) -> tuple[Cut, ...]:
        """The cuts learned for a mode's region: the union over its DS keys, in order."""
        seen: dict[tuple[tuple[float, ...], tuple[float, ...]], Cut] = {}
        for k in self.keys_of(mode):
            for c in self.modes[k].cuts:
                seen.setdefault((tuple(c.normal.tolist()), tuple(c.point.tolist())), c)
        return tuple(seen.values())

    def add_cut(self, key: str, cut: Cut) -> Model:
        """A new model with ``cut`` added to the region of a mode (paper Sec. 5.2).

        The cut bounds the *mode's region*, so every DS of that mode -- the plain one and the
        per-transition ones -- gets it (they share the cuts learned for the region).

        Parameters
        ----------
        key : str
            A mode name or a DS key (``"a"`` or ``"a->b"``); the cut goes to every DS of its
            mode.
        cut : Cut

        Returns
        -------
        Model
            This model is unchanged.

        Raises
        ------
        ModelError
            ``key`` is unknown; ``cut`` is not a :class:`Cut`, has a normal that is not a unit
            vector, a dimension other than the model's, or leaves the attractor of one of the
            mode's DS on or outside its plane (``x*`` must be strictly inside).
        """
        if key in self.modes:
            mode = self.modes[key].mode
        elif self.keys_of(key):
            mode = key
        else:
            raise ModelError(f"{self.path or 'model'}: no DS or mode {key!r} to cut "
                             f"(known keys: {', '.join(sorted(self.modes))})")
        if not isinstance(cut, Cut):
            raise ModelError(f"a cut must be a Cut, got {type(cut).__name__}")
        if cut.dim != self.dim:
            raise ModelError(f"cut has dimension {cut.dim}, the model has {self.dim} states")
        norm = float(np.linalg.norm(cut.normal))
        if not abs(norm - 1.0) <= 1e-6:
            raise ModelError(f"cut normal must be a unit vector, its norm is {norm:.9g}")
        modes = dict(self.modes)
        for k in self.keys_of(mode):
            mm = self.modes[k]
            h = cut.offset(mm.ds.attractor)
            scale = max(1.0, float(np.linalg.norm(cut.point - mm.ds.attractor)))
            if not h > 1e-9 * scale:
                raise ModelError(f"cut for mode {mode!r} leaves the attractor of DS {k!r} on or "
                                 f"outside its plane (w . (p - x*) = {h:.6g}); x* must be "
                                 "strictly inside")
            modes[k] = mm.with_cuts((*mm.cuts, cut))
        return Model(state_names=self.state_names, modes=MappingProxyType(modes),
                     spec=self.spec, path=self.path, source=self.source)


def check_symmetric(M: FloatArray, where: str) -> None:
    bad = np.argwhere(M != M.T)
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise ModelError(f"{where}: not symmetric (entry [{i}][{j}] != [{j}][{i}])")
