"""The model file: one LPV-DS (and its cuts) per mode or mode transition.

Format (JSON, validated against the published schema ``tli_verify/schemas/model.schema.json``
and then semantically: dimensions, symmetry, every number within ``|v| <= 1e6``, covariances
positive definite with bounded eigenvalues and condition number, priors summing to 1, unit cut
normals; the limits are in :mod:`tli_verify.limits` and :func:`numeric_limits`)::

    {
      "schema_version": 1,
      "state_names": ["x0", "x1"],
      "spec": "../specs/scoop.toml",          # relative to the model file, or null
      "source": {"tool": "tli-verify 0.1.0", "demos": [{"path": "...", "sha256": "..."}]},
      "modes": {
        "a": {
          "mode": "a", "next_mode": "b",      # optional for plain keys
          "attractor": [x*_0, x*_1],
          "P": [[..], [..]],                  # V(x) = (x - x*)^T P (x - x*)
          "components": [{"prior": pi_k, "mean": [..], "cov": [[..]], "A": [[..]]}, ...],
          "cuts": [{"normal": [..], "point": [..]}],
          "fit": {"clustering": "pc-gmm", "lyapunov": "p-qlf", "eps": 0.001, ...}
        },
        "b->c": {"mode": "b", "next_mode": "c", ...}   # a per-transition DS (appendix F)
      }
    }

The DS of a key is ``f(x) = sum_k gamma_k(x) A_k (x - x*)`` (paper eq. 4) and the policy of the
mode is the modulated ``M(x) f(x)`` (paper eq. 5, Sec. 5.2) once the mode has cuts.
Floats are written with ``repr`` precision, so a saved model reloads bit-for-bit -- which the
certificate's exact check relies on.
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
from tli_verify.ds.lpvds import LPVDS, Clustering, LyapunovKind
from tli_verify.errors import ModelError, TliError
from tli_verify.io import (
    atomic_write_text,
    canonical_json,
    field_path,
    read_json,
    validate_schema,
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
    "ModeModel",
    "Model",
    "field_path",
    "learn_model",
    "load_model",
    "model_from_dict",
    "model_to_dict",
    "numeric_limits",
    "read_json",
    "relocate_model",
    "save_model",
    "validate_schema",
]

FloatArray = npt.NDArray[np.float64]

SCHEMA_VERSION = 1
TRANSITION = "->"
_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_]+$")


def numeric_limits() -> dict[str, float]:
    """The numeric ranges every loaded model satisfies (for the certificate to record).

    Within them the velocity ``f(x)`` (paper eq. 4), its mixing weights and ``M(x) f(x)``
    (eq. 5) are finite and well defined at every state with ``|x_i| <= max_abs_value``
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


def _check_range(value: Any, parts: list[str | int], where: str) -> None:
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


def _check_covariance(cov: FloatArray, where: str) -> None:
    """Symmetric positive definite, safely invertible: eigenvalues and condition bounded."""
    _symmetric(cov, where)
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


# --------------------------------------------------------------------------------------------
# Model
# --------------------------------------------------------------------------------------------

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
        """Freeze ``fit`` and build the modulator once for this cut set (paper eq. 5).

        Raises
        ------
        ModelError
            A cut of the wrong dimension, or one that leaves ``x*`` outside.
        """
        from tli_verify.boundary.modulation import Modulator

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
        """``M(x) f(x)`` (paper eq. 5 with the corner guard), or ``f(x)`` without cuts.

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
        from tli_verify.boundary.modulation import check_control_period

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

    def velocity(self, X: npt.ArrayLike, mode: str, next_mode: str | None = None, *,
                 dt: float | None = None) -> FloatArray:
        """Velocity of the mode's policy: ``M(x) f(x)`` with the mode's cuts (paper eq. 5).

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

    def nominal_velocity(self, X: npt.ArrayLike, mode: str,
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


def _matrix(value: Any, shape: tuple[int, ...], where: str) -> FloatArray:
    arr = np.array(value, dtype=object)
    if arr.shape != shape:
        want = "x".join(str(s) for s in shape)
        raise ModelError(f"{where}: expected shape {want}, got "
                         f"{'x'.join(str(s) for s in arr.shape) or 'a scalar'}")
    return np.array(value, dtype=np.float64)


def _symmetric(M: FloatArray, where: str) -> None:
    bad = np.argwhere(M != M.T)
    if bad.size:
        i, j = (int(v) for v in bad[0])
        raise ModelError(f"{where}: not symmetric (entry [{i}][{j}] != [{j}][{i}])")


def model_from_dict(data: Any, *, where: str = "model", path: str | None = None) -> Model:
    """Validate a parsed model document (schema, then semantics) and build the model.

    Raises
    ------
    ModelError
        ``"<where>: <field path>: <problem>"``: a schema violation, a number outside
        :func:`numeric_limits` (``modes.a.components[0].cov[1][1]: 1e+308 is outside ...``),
        a covariance that is not safely invertible, priors that do not sum to 1.
    """
    validate_schema(data, "model.schema.json", where=where, error=ModelError)
    for key, entry in data["modes"].items():
        _check_range({k: v for k, v in entry.items() if k != "fit"}, ["modes", key], where)
    names = tuple(data["state_names"])
    n = len(names)
    modes: dict[str, ModeModel] = {}
    for key, entry in data["modes"].items():
        loc = field_path(["modes", key])
        if TRANSITION in key:
            head, _, tail = key.partition(TRANSITION)
            if entry.get("mode") != head or entry.get("next_mode") != tail:
                raise ModelError(f"{where}: {loc}: a per-transition key '<mode>{TRANSITION}<next>' "
                                 f"needs \"mode\": {head!r} and \"next_mode\": {tail!r}")
        mode = entry.get("mode", key)
        if TRANSITION not in key and mode != key:
            raise ModelError(f"{where}: {loc}.mode: {mode!r} differs from the key {key!r}")
        attractor = _matrix(entry["attractor"], (n,), f"{where}: {loc}.attractor")
        P = _matrix(entry["P"], (n, n), f"{where}: {loc}.P")
        _symmetric(P, f"{where}: {loc}.P")
        comps = entry["components"]
        means, covs, As, priors = [], [], [], []
        for k, comp in enumerate(comps):
            cloc = f"{where}: {loc}.components[{k}]"
            priors.append(float(comp["prior"]))
            means.append(_matrix(comp["mean"], (n,), f"{cloc}.mean"))
            cov = _matrix(comp["cov"], (n, n), f"{cloc}.cov")
            _check_covariance(cov, f"{cloc}.cov")
            covs.append(cov)
            As.append(_matrix(comp["A"], (n, n), f"{cloc}.A"))
        total = float(np.sum(priors))
        if not abs(total - 1.0) <= PRIOR_SUM_TOL:
            raise ModelError(f"{where}: {loc}.components: priors sum to {total!r}, not 1 "
                             f"(tolerance {PRIOR_SUM_TOL:g}, PRIOR_SUM_TOL)")
        cuts = []
        for c, raw in enumerate(entry["cuts"]):
            cut = Cut.from_dict(raw, where=f"{where}: {loc}.cuts[{c}]")
            if cut.dim != n:
                raise ModelError(f"{where}: {loc}.cuts[{c}]: dimension {cut.dim}, the model "
                                 f"has {n} states")
            cuts.append(cut)
        try:
            ds = LPVDS(attractor=attractor, priors=np.array(priors), means=np.array(means),
                       covs=np.array(covs), A=np.array(As), P=P)
        except ModelError as exc:
            raise ModelError(f"{where}: {loc}: {exc}") from None
        if cuts:
            from tli_verify.boundary.modulation import Modulator

            try:
                Modulator.build(cuts, attractor, lyapunov=P)
            except ModelError as exc:
                raise ModelError(f"{where}: {loc}.cuts: {exc}") from None
        fit = entry.get("fit")
        modes[key] = ModeModel(key=key, mode=mode, next_mode=entry.get("next_mode"), ds=ds,
                               cuts=tuple(cuts),
                               fit=MappingProxyType(dict(fit)) if fit is not None else None)
    source = data.get("source")
    return Model(state_names=names, modes=MappingProxyType(modes), spec=data.get("spec"),
                 path=path, source=MappingProxyType(dict(source)) if source else None)


def load_model(path: str | os.PathLike[str]) -> Model:
    """Load and validate a model file (public API: ``tli_verify.load_model``).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Model
        Frozen; ``model.velocity(X, mode="a")`` maps ``(N, n)`` states to ``(N, n)`` velocities.

    Raises
    ------
    ModelError
        Naming the file and the JSON field, e.g.
        ``models/x.json: modes.a.components[2].cov: not symmetric positive definite``.
    """
    data = read_json(path, what="model", error=ModelError)
    return model_from_dict(data, where=str(path), path=str(path))


def _mode_to_dict(m: ModeModel) -> dict[str, Any]:
    ds = m.ds
    entry: dict[str, Any] = {
        "mode": m.mode,
        "next_mode": m.next_mode,
        "attractor": ds.attractor.tolist(),
        "P": ds.P.tolist(),
        "components": [
            {"prior": float(ds.priors[k]), "mean": ds.means[k].tolist(),
             "cov": ds.covs[k].tolist(), "A": ds.A[k].tolist()}
            for k in range(ds.n_components)
        ],
        "cuts": [c.to_dict() for c in m.cuts],
    }
    if m.fit is not None:
        entry["fit"] = dict(m.fit)
    return entry


def model_to_dict(model: Model) -> dict[str, Any]:
    """The JSON document of a model (inverse of :func:`model_from_dict`)."""
    doc: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "state_names": list(model.state_names),
        "spec": model.spec,
        "modes": {k: _mode_to_dict(m) for k, m in model.modes.items()},
    }
    if model.source is not None:
        doc["source"] = json.loads(json.dumps(dict(model.source)))
    return doc


def save_model(model: Model, path: str | os.PathLike[str]) -> None:
    """Write a model file atomically (canonical JSON, exact float round-trip)."""
    doc = model_to_dict(model)
    model_from_dict(doc, where=str(path))  # never write a file we would refuse to load
    atomic_write_text(path, canonical_json(doc))


def _relpath(target: str | os.PathLike[str], base_dir: Path) -> str:
    """``target`` relative to ``base_dir`` (POSIX separators), for portable files."""
    return Path(os.path.relpath(Path(target).resolve(), base_dir.resolve())).as_posix()


def relocate_model(model: Model, out_path: str | os.PathLike[str], *,
                   modes: Mapping[str, ModeModel] | None = None) -> Model:
    """The model as it will be written at ``out_path``: relative paths rewritten.

    Parameters
    ----------
    model : Model
    out_path : path-like
        The new file.
    modes : mapping of str to ModeModel, optional
        Replacement DS (default: the model's).

    Returns
    -------
    Model
    """
    base = Path(model.path).parent if model.path else Path(".")
    out_dir = Path(out_path).parent
    spec = _relpath(base / model.spec, out_dir) if model.spec is not None else None
    source = None
    if model.source is not None:
        src = json.loads(json.dumps(dict(model.source)))
        for demo in src.get("demos") or []:
            if isinstance(demo, dict) and isinstance(demo.get("path"), str):
                demo["path"] = _relpath(base / demo["path"], out_dir)
        source = MappingProxyType(src)
    return Model(state_names=model.state_names,
                 modes=modes if modes is not None else model.modes,
                 spec=spec, path=str(out_path), source=source)


def _rate_choice_record(info: Any) -> dict[str, float]:
    """The rate choice of a :class:`~tli_verify.ds.lpvds.FitInfo` as model ``fit`` keys (none
    when the rate was forced or the fixed factor)."""
    if info.rate_budget is None:
        return {}
    return {"rate_budget": float(info.rate_budget),
            "rate_reference_rmse": float(info.reference_rmse),
            "rate_rmse": float(info.rate_rmse), "data_rate": float(info.data_rate)}


def learn_model(
    demo_paths: Sequence[str | os.PathLike[str]],
    *,
    out_path: str | os.PathLike[str],
    spec_path: str | os.PathLike[str] | None = None,
    seed: int = 0,
    eps: float = 1e-3,
    rate: float | None = None,
    rate_budget: float | None = 0.03,
    control_dt: float | None = 1e-3,
    clustering: Clustering = "pc-gmm",
    lyapunov: LyapunovKind = "p-qlf",
) -> Model:
    """Demonstrations -> segments -> one certified-to-be LPV-DS per mode (paper Sec. 5.1).

    Parameters
    ----------
    demo_paths : sequence of path-like
        Demonstration CSV files (:mod:`tli_verify.demos`).
    out_path : path-like
        Where the model will be written (relative paths in the file are relative to it).
    spec_path : path-like, optional
        Spec whose ``[modes]`` labels define the modes; without it, each distinct sensor
        reading is a mode (:mod:`tli_verify.segmentation`).
    seed : int, optional
        Seed of the clustering (same seed, same model).
    eps : float, optional
        LMI margin ``A_k^T P + P A_k <= -eps I``.
    rate : float, optional
        Certified decay rate of ``V`` forced on every DS (1/time); ``0`` with ``eps=1e-3``:
        the learner before issue 9 (margin only). Default (None): chosen per DS under
        ``rate_budget``. See :func:`tli_verify.ds.lpvds.learn_lpvds`.
    rate_budget : float, optional
        With ``rate`` None, per DS: fit at rate 0 first, then impose the largest rate of a
        half-octave grid up to the data's own rate whose fit's training velocity RMSE is within
        ``1 + rate_budget`` of the rate-0 fit's (:func:`tli_verify.ds.lyapunov.choose_rate`;
        default ``RATE_BUDGET`` = 0.03). Recorded in each DS's ``fit``: ``rate`` (the chosen
        rate, which ``tli certify`` then proves: the certified decay rate is at least it),
        ``rate_budget``, ``rate_reference_rmse`` (rate-0 fit), ``rate_rmse`` (fit at ``rate``)
        and ``data_rate``. None: the fixed quarter of the data's own rate (``RATE_FACTOR``),
        the default before the choice.
    control_dt : float, optional
        Control period at which the learned DS must also decrease ``V`` per explicit step
        (default 1 ms); None for continuous time only. Ignored when ``rate`` is 0.
    clustering, lyapunov : str, optional
        See :func:`tli_verify.ds.lpvds.learn_lpvds`.

    Returns
    -------
    Model
        Not yet written; see :func:`save_model`.

    Raises
    ------
    DemoError, SpecError, SolverError
        Bad demonstrations, a spec without modes, a solver status other than optimal.
    """
    from tli_verify import __version__
    from tli_verify.demos import load_demos
    from tli_verify.ds.lpvds import learn_lpvds
    from tli_verify.io import sha256_file
    from tli_verify.segmentation import segment_demos, spec_labeler

    out_dir = Path(out_path).parent
    if spec_path is not None:
        from tli_verify.logic.spec import load_spec

        spec = load_spec(spec_path)
        labeler, modes, labels = spec_labeler(spec)
        demos = load_demos(demo_paths, sensor_names=spec.inputs)
        seg = segment_demos(demos, labeler=labeler, modes=modes, labels=labels)
    else:
        demos = load_demos(demo_paths)
        seg = segment_demos(demos)
    names = tuple(f"x{i}" for i in range(demos[0].dim))
    learned: dict[str, ModeModel] = {}
    for key, data in seg.data.items():
        try:
            ds, info = learn_lpvds(data.x, data.dx, data.attractor, seed=seed, eps=eps,
                                   rate=rate, rate_budget=rate_budget, control_dt=control_dt,
                                   clustering=clustering, lyapunov=lyapunov)
        except TliError as exc:  # e.g. an infeasible SDP: say which mode's data it was
            raise type(exc)(f"mode {key!r} ({len(data.x)} samples): {exc}") from None
        fit = {"clustering": info.clustering, "lyapunov": info.lyapunov,
               "n_components": info.n_components, "eps": info.eps, "rate": info.rate,
               "seed": info.seed, "solver": info.solver, "status": info.status,
               "n_samples": info.n_samples}
        if info.control_dt is not None:
            fit["control_dt"] = info.control_dt
        fit.update(_rate_choice_record(info))
        learned[key] = ModeModel(key=key, mode=data.mode, next_mode=data.next_mode, ds=ds,
                                 fit=MappingProxyType(fit))
    source = {"tool": f"tli-verify {__version__}",
              "demos": [{"path": _relpath(p, out_dir), "sha256": sha256_file(p)}
                        for p in demo_paths]}
    return Model(state_names=names, modes=MappingProxyType(learned),
                 spec=_relpath(spec_path, out_dir) if spec_path is not None else None,
                 path=str(out_path), source=MappingProxyType(source))
