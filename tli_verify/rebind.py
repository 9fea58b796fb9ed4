"""Bind one set of learned DS to a spec's modes, without relearning (paper appendix G).

Paper appendix "Generalization" (cooking, Fig. 10): per-transition DS learned once are reused,
*without relearning*, under several task automata (``specs/cooking-cb/bc/c/cc.toml``). Learned
without a spec (``tli learn`` without ``--spec``), a model has one DS per demonstrated *sensor*
transition, its modes named by the full reading (``"!ch & br & !pot"``,
:func:`tli_verify.segmentation.sensor_state_labeler`). :func:`rebind_model` renames those DS to
the modes of one spec through its ``[modes]`` labels and writes nothing new into them: each DS
of the bound model is the learned DS object itself (attractor, GMM, ``A_k`` and ``P`` bit for
bit), so every spec's model carries the same numbers and each is certified for its own spec.

Which keys the bound model gets, for the spec's task automaton (its runnable modes and its
mode transitions ``m -> m'``, ``m != m'``):

* ``"m->m'"`` for each transition whose learned sensor transition (label of ``m`` -> label of
  ``m'``) has a per-transition DS;
* ``"m"`` (plain) where the learned reading of ``m`` has a plain DS and the automaton needs it:
  ``m`` is a sink (a goal the task stays in), or some transition out of ``m`` has no
  per-transition DS. Its ``next_mode`` is the automaton successor of ``m`` whose label the
  learned DS heads for, when there is exactly one.

A mode with no DS at all, or whose transitions are only partly covered with no plain DS to fall
back on, is refused (:class:`~tli_verify.errors.DemoError`, exit 2) naming the mode and the
sensor reading no demonstration covers (paper Asm. 3), so a bound model always passes the
gate's coverage check or is not written.
"""

from __future__ import annotations

import os
from pathlib import Path
from types import MappingProxyType
from typing import Any

from tli_verify.errors import DemoError, ModelError
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import label_holds, load_spec
from tli_verify.model.serialize import relocate_model
from tli_verify.model.types import Model, ModeModel

__all__ = ["reading_of", "rebind_model"]

TRANSITION = "->"


def reading_of(name: str, inputs: tuple[str, ...]) -> dict[str, bool] | None:
    """The reading a label-free mode name stands for (``"!ch & br & !pot"``), or None.

    Parameters
    ----------
    name : str
        A mode name of a model learned without a spec.
    inputs : tuple of str
        The spec's inputs; the name must fix each of them exactly once.

    Returns
    -------
    dict of str to bool, or None
        None when ``name`` is not a full conjunction over ``inputs``.
    """
    values: dict[str, bool] = {}
    for part in name.split("&"):
        lit = part.strip()
        neg = lit.startswith("!")
        ap = lit[1:].strip() if neg else lit
        if ap not in inputs or ap in values:
            return None
        values[ap] = not neg
    return values if set(values) == set(inputs) else None


def rebind_model(learned: Model, spec_path: str | os.PathLike[str],
                 out_path: str | os.PathLike[str]) -> Model:
    """The learned DS, keyed by the modes of the spec at ``spec_path`` (module docstring).

    Parameters
    ----------
    learned : Model
        Loaded from a file written by ``tli learn`` *without* ``--spec`` (modes named by
        readings over the spec's inputs).
    spec_path : path-like
        The spec to bind to (must have a ``[modes]`` table and be realizable).
    out_path : path-like
        Where the bound model will be written (its spec and demo paths are made relative to
        it; see :func:`tli_verify.model.serialize.save_model`).

    Returns
    -------
    Model
        Each DS is the learned :class:`~tli_verify.ds.lpvds.LPVDS` object (no cuts); the
        ``source`` records the learned key of every bound key (``"learned_keys"``).

    Raises
    ------
    ModelError
        The learned model names a spec, or a mode that is not a reading over the spec's
        inputs; a spec mode's label holds for two learned readings that both have a DS for
        what it needs (ambiguous).
    DemoError
        A mode the automaton runs has no demonstrated DS, or a transition out of it has none
        and there is no plain DS (paper Asm. 3).
    """
    if learned.spec is not None:
        raise ModelError(f"{learned.path}: learned with a spec ({learned.spec}); rebinding "
                         "needs a model learned without --spec (modes named by readings)")
    spec = load_spec(spec_path)
    if not spec.modes:
        raise ModelError(f"{spec_path}: no [modes] table: nothing to bind the DS to")
    inputs = tuple(spec.inputs)
    readings: dict[str, dict[str, bool]] = {}
    for mm in learned.modes.values():
        for name in (mm.mode, mm.next_mode):
            if name is None or name in readings:
                continue
            r = reading_of(name, inputs)
            if r is None:
                raise ModelError(f"{learned.path}: mode {name!r} is not a reading over the "
                                 f"inputs of {spec_path} ({', '.join(inputs)})")
            readings[name] = r
    automaton = synthesize(spec)
    runnable = sorted({s.mode for s in automaton.states})
    succ: dict[str, set[str]] = {m: set() for m in runnable}
    for a, b in automaton.mode_transitions():
        if a != b:
            succ.setdefault(a, set()).add(b)

    def names_of(mode: str) -> list[str]:
        return sorted(n for n, r in readings.items() if label_holds(spec, mode, r))

    def unique(candidates: list[str], what: str) -> str | None:
        if len(candidates) > 1:
            raise ModelError(f"{learned.path}: {what}: several learned DS fit "
                             f"({', '.join(candidates)}); the binding would be ambiguous")
        return candidates[0] if candidates else None

    bound: dict[str, ModeModel] = {}
    origin: dict[str, str] = {}
    for m in runnable:
        mine = names_of(m)
        covered = set()
        for m2 in sorted(succ.get(m, ())):
            theirs = names_of(m2)
            key = unique([f"{a}{TRANSITION}{b}" for a in mine for b in theirs
                          if f"{a}{TRANSITION}{b}" in learned.modes], f"transition {m}->{m2}")
            if key is not None:
                ds = learned.modes[key]
                new = f"{m}{TRANSITION}{m2}"
                bound[new] = ModeModel(key=new, mode=m, next_mode=m2, ds=ds.ds, fit=ds.fit)
                origin[new] = key
                covered.add(m2)
        missing = sorted(succ.get(m, set()) - covered)
        if covered and not missing:
            continue
        plain = unique([a for a in mine if a in learned.modes], f"mode {m}")
        if plain is None:
            label = spec.modes[m]
            if not covered:
                raise DemoError(f"{spec_path}: mode {m!r} (label {label!r}) has no learned DS: "
                                "no demonstration visits its reading (paper Asm. 3)")
            raise DemoError(f"{spec_path}: mode {m!r} (label {label!r}) has no learned DS "
                            f"towards {', '.join(missing)} and no plain DS: no demonstration "
                            f"goes from its reading to {spec.modes[missing[0]]!r} "
                            "(paper Asm. 3)")
        ds = learned.modes[plain]
        nxt = None
        if ds.next_mode is not None:
            nxt = unique([m2 for m2 in sorted(succ.get(m, ()))
                          if label_holds(spec, m2, readings[ds.next_mode])],
                         f"next mode of {m}")
        bound[m] = ModeModel(key=m, mode=m, next_mode=nxt, ds=ds.ds, fit=ds.fit)
        origin[m] = plain
    source: dict[str, Any] = dict(learned.source or {})
    source["learned_keys"] = dict(sorted(origin.items()))
    base = Path(learned.path).parent if learned.path else Path(".")
    spec_rel = os.path.relpath(Path(spec_path).resolve(), base.resolve())
    staged = Model(state_names=learned.state_names, modes=MappingProxyType(bound),
                   spec=Path(spec_rel).as_posix(), path=learned.path,
                   source=MappingProxyType(source))
    return relocate_model(staged, out_path)

