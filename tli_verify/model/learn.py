"""Learning a model from demonstrations (paper Sec. 4.3, eqs. 4-5).

The demonstrations are segmented by the spec's mode labels (:mod:`tli_verify.segmentation`,
appendix C), and one certified-stable LPV-DS is learned per mode
(:func:`tli_verify.ds.lpvds.learn_lpvds`).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from types import MappingProxyType
from typing import Any

from tli_verify._version import __version__
from tli_verify.defaults import DEFAULT_DT_FLOAT
from tli_verify.demos import load_demos
from tli_verify.ds.lpvds import Clustering, LyapunovKind, learn_lpvds
from tli_verify.errors import ModelError, TliError
from tli_verify.io import sha256_file
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import relative_to_file
from tli_verify.model.types import Model, ModeModel
from tli_verify.segmentation import segment_demos, spec_labeler

__all__ = [
    "learn_model",
]


def _rate_choice_record(info: Any) -> dict[str, float | bool]:
    """The rate choice of a :class:`~tli_verify.ds.lpvds.FitInfo` as model ``fit`` keys (none
    when the rate was forced or the fixed factor)."""
    if info.rate_budget is None:
        return {}
    return {"rate_budget": float(info.rate_budget),
            "rate_reference_rmse": float(info.reference_rmse),
            "rate_rmse": float(info.rate_rmse), "data_rate": float(info.data_rate),
            "rate_within_budget": bool(info.rate_within_budget)}


def learn_model(
    demo_paths: Sequence[str | os.PathLike[str]],
    *,
    out_path: str | os.PathLike[str],
    spec_path: str | os.PathLike[str] | None = None,
    seed: int = 0,
    eps: float = 1e-3,
    rate: float | None = None,
    rate_budget: float | None = 0.03,
    control_dt: float | None = DEFAULT_DT_FLOAT,
    clustering: Clustering = "pc-gmm",
    lyapunov: LyapunovKind = "p-qlf",
    blocks: Sequence[Sequence[int]] = (),
    state_names: Sequence[str] | None = None,
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
        the earlier margin-only learner. Default (None): chosen per DS under
        ``rate_budget``. See :func:`tli_verify.ds.lpvds.learn_lpvds`.
    rate_budget : float, optional
        With ``rate`` None, per DS: fit at rate 0 first, then impose the largest rate of a
        half-octave grid up to the data's own rate whose fit's training velocity RMSE is within
        ``1 + rate_budget`` of the rate-0 fit's (:func:`tli_verify.ds.lyapunov.choose_rate`;
        default ``RATE_BUDGET`` = 0.03). Recorded in each DS's ``fit``: ``rate`` (the chosen
        rate, which ``tli certify`` then proves: the certified decay rate is at least it),
        ``rate_budget``, ``rate_reference_rmse`` (rate-0 fit), ``rate_rmse`` (fit at ``rate``),
        ``data_rate`` and ``rate_within_budget`` (False: even the grid's smallest rate, kept,
        costs more than the budget). None: the fixed quarter of the data's own rate
        (``RATE_FACTOR``), the default before the choice.
    control_dt : float, optional
        Control period at which the learned DS must also decrease ``V`` per explicit step
        (default :data:`~tli_verify.defaults.DEFAULT_DT`, 1/100 s); None for continuous time
        only. Ignored when ``rate`` is 0.
    clustering, lyapunov : str, optional
        See :func:`tli_verify.ds.lpvds.learn_lpvds`.
    blocks : sequence of sequence of int, optional
        Groups of coordinates every ``A_k`` keeps decoupled (:func:`tli_verify.api.learn`
        passes a pose task's orientation; see :func:`tli_verify.ds.lpvds.learn_lpvds`).
        Recorded in each DS's ``fit`` as ``blocks``.
    state_names : sequence of str, optional
        The coordinates' names (the spec's task's ``[state] names``: :func:`tli_verify.api.learn`
        passes them); default ``x0 .. x{n-1}``.

    Returns
    -------
    Model
        Not yet written; see :func:`save_model`.

    Raises
    ------
    DemoError, SpecError, SolverError
        Bad demonstrations, a spec without modes, a solver status other than optimal.
    """
    out_dir = Path(out_path).parent
    if spec_path is not None:

        spec = load_spec(spec_path)
        labeler, modes, labels = spec_labeler(spec)
        demos = load_demos(demo_paths, sensor_names=spec.inputs)
        seg = segment_demos(demos, labeler=labeler, modes=modes, labels=labels)
    else:
        demos = load_demos(demo_paths)
        seg = segment_demos(demos)
    if state_names is None:
        names = tuple(f"x{i}" for i in range(demos[0].dim))
    else:
        names = tuple(str(v) for v in state_names)
        if len(names) != demos[0].dim:
            raise ModelError(f"the task names {len(names)} state coordinates "
                             f"({', '.join(names)[:200]}), the demonstrations have "
                             f"{demos[0].dim}")
    seen: set[int] = set()
    for group in blocks:
        for c in group:
            if not 0 <= int(c) < demos[0].dim:
                raise ModelError(f"blocks: coordinate {c} is outside the state's "
                                 f"0..{demos[0].dim - 1}")
            if int(c) in seen:
                raise ModelError(f"blocks: coordinate {c} is in two groups")
            seen.add(int(c))
    learned: dict[str, ModeModel] = {}
    for key, data in seg.data.items():
        try:
            ds, info = learn_lpvds(data.x, data.dx, data.attractor, seed=seed, eps=eps,
                                   rate=rate, rate_budget=rate_budget, control_dt=control_dt,
                                   clustering=clustering, lyapunov=lyapunov, blocks=blocks)
        except TliError as exc:  # e.g. an infeasible SDP: say which mode's data it was
            raise type(exc)(f"mode {key!r} ({len(data.x)} samples): {exc}") from None
        fit = {"clustering": info.clustering, "lyapunov": info.lyapunov,
               "n_components": info.n_components, "eps": info.eps, "rate": info.rate,
               "seed": info.seed, "solver": info.solver, "status": info.status,
               "n_samples": info.n_samples}
        if info.control_dt is not None:
            fit["control_dt"] = info.control_dt
        fit.update(_rate_choice_record(info))
        if info.blocks:
            fit["blocks"] = [list(g) for g in info.blocks]
        learned[key] = ModeModel(key=key, mode=data.mode, next_mode=data.next_mode, ds=ds,
                                 fit=MappingProxyType(fit))
    source = {"tool": f"tli-verify {__version__}",
              "demos": [{"path": relative_to_file(p, out_dir), "sha256": sha256_file(p)}
                        for p in demo_paths]}
    return Model(state_names=names, modes=MappingProxyType(learned),
                 spec=relative_to_file(spec_path, out_dir) if spec_path is not None else None,
                 path=str(out_path), source=MappingProxyType(source))
