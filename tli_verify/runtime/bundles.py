"""The shipped (spec, model, certificate) bundles of each world and what completes an episode.

Used by ``tli run`` (which bundle a world runs), the campaigns (the goal the oracle and the
policy share) and ``make_evidence``. A goal is a set of modes (default: the automaton's sink
modes) and sensors that must also read true there: a cyclic task such as inspection
(``GF(b & rel)``) has no sink mode, and an episode of it is done at the first ``b & rel``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

__all__ = ["REGISTRY", "Bundle", "bundle_for_spec", "world_of_model"]


@dataclass(frozen=True, slots=True)
class Bundle:
    """A shipped (spec, model, certificate) triple of a world, and what its goal is.

    Attributes
    ----------
    spec : str
        Spec name (``specs/<spec>.toml``); the model is ``models/<spec>.model.json`` and the
        certificate ``certificates/<spec>.cert.json`` unless given.
    goal_modes : tuple of str or None
        Modes that complete an episode (None: the automaton's sink modes).
    goal_inputs : tuple of str
        Sensors that must also read true in the goal mode (inspection: the release ``rel``).
    model, certificate : str or None
        File names under ``models/`` and ``certificates/`` (default from ``spec``).
    """

    spec: str
    goal_modes: tuple[str, ...] | None = None
    goal_inputs: tuple[str, ...] = ()
    model: str | None = None
    certificate: str | None = None

    @property
    def model_file(self) -> str:
        """``<spec>.model.json`` unless given."""
        return self.model or f"{self.spec}.model.json"

    @property
    def certificate_file(self) -> str:
        """``<spec>.cert.json`` unless given."""
        return self.certificate or f"{self.spec}.cert.json"


REGISTRY: dict[str, tuple[Bundle, ...]] = {
    "scoop": (Bundle("scoop"),),
    "cooking": (Bundle("cooking-cb"), Bundle("cooking-bc"), Bundle("cooking-c"),
                # chicken continuously: no sink mode; an episode is done once food is in
                Bundle("cooking-cc", goal_modes=("d",))),
    "color-tracing": (Bundle("color-tracing-a"), Bundle("color-tracing-b"),
                      Bundle("color-tracing-c")),
    # repeated forever: an episode is done at the first release (b & rel)
    "inspection": (Bundle("inspection", goal_modes=("b",), goal_inputs=("rel",)),),
}
"""World -> its shipped bundles; the first is the default, ``--spec`` picks another."""


def bundle_for_spec(spec: str | os.PathLike[str]) -> Bundle | None:
    """The shipped bundle whose spec file has the name of ``spec`` (``specs/<name>.toml``).

    Parameters
    ----------
    spec : path-like
        A spec file path.

    Returns
    -------
    Bundle or None
        None for a spec no world ships (its goal: the automaton's sink modes).
    """
    stem = Path(spec).name.removesuffix(".toml")
    for bundles in REGISTRY.values():
        for bundle in bundles:
            if bundle.spec == stem:
                return bundle
    return None


def world_of_model(model: str | os.PathLike[str]) -> str | None:
    """The world that ships ``models/<name>.model.json`` (its sensor model), or None.

    Parameters
    ----------
    model : path-like
        A model file path; only its file name counts.
    """
    name = Path(model).name
    for world, bundles in REGISTRY.items():
        if any(b.model_file == name for b in bundles):
            return world
    return None
