"""The model file: parse (published schema, then semantics), serialize, load, save, relocate.

Floats are written with ``repr`` precision and canonical JSON, so a saved model reloads
bit-for-bit -- which the certificate's exact check relies on. Format: :mod:`tli_verify.model`.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import Modulator
from tli_verify.ds.lpvds import LPVDS
from tli_verify.errors import ModelError
from tli_verify.io import (
    atomic_write_text,
    canonical_json,
    field_path,
    read_json,
    validate_schema,
)
from tli_verify.limits import (
    PRIOR_SUM_TOL,
)
from tli_verify.model.types import (
    SCHEMA_VERSION,
    TRANSITION,
    FloatArray,
    Model,
    ModeModel,
    check_covariance,
    check_range,
    check_symmetric,
)
from tli_verify.snapshot import current

__all__ = [
    "IN_MEMORY",
    "load_model",
    "model_from_dict",
    "model_to_dict",
    "relative_to_file",
    "relocate_model",
    "save_model",
]

IN_MEMORY = "in-memory:"
"""Prefix of a demonstration's ``source`` path when it was given as an object, never as a file
(:func:`tli_verify.api.learn`): kept as written when the model is relocated."""


def _matrix(value: Any, shape: tuple[int, ...], where: str) -> FloatArray:
    arr = np.array(value, dtype=object)
    if arr.shape != shape:
        want = "x".join(str(s) for s in shape)
        raise ModelError(f"{where}: expected shape {want}, got "
                         f"{'x'.join(str(s) for s in arr.shape) or 'a scalar'}")
    return np.array(value, dtype=np.float64)


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
        check_range({k: v for k, v in entry.items() if k != "fit"}, ["modes", key], where)
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
        check_symmetric(P, f"{where}: {loc}.P")
        comps = entry["components"]
        means, covs, As, priors = [], [], [], []
        for k, comp in enumerate(comps):
            cloc = f"{where}: {loc}.components[{k}]"
            priors.append(float(comp["prior"]))
            means.append(_matrix(comp["mean"], (n,), f"{cloc}.mean"))
            cov = _matrix(comp["cov"], (n, n), f"{cloc}.cov")
            check_covariance(cov, f"{cloc}.cov")
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
    snap = current()
    if snap is None:
        return _load_model(path)
    model = snap.parse("model", path, lambda: _load_model(path))
    return model if model.path == str(path) else dataclasses.replace(model, path=str(path))


def _load_model(path: str | os.PathLike[str]) -> Model:
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


def relative_to_file(target: str | os.PathLike[str], base_dir: Path) -> str:
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
    spec = relative_to_file(base / model.spec, out_dir) if model.spec is not None else None
    source = None
    if model.source is not None:
        src = json.loads(json.dumps(dict(model.source)))
        for demo in src.get("demos") or []:
            if isinstance(demo, dict) and isinstance(demo.get("path"), str) and \
                    not demo["path"].startswith(IN_MEMORY):
                demo["path"] = relative_to_file(base / demo["path"], out_dir)
        source = MappingProxyType(src)
    return Model(state_names=model.state_names,
                 modes=modes if modes is not None else model.modes,
                 spec=spec, path=str(out_path), source=source)
