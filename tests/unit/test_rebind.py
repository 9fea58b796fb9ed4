"""tli_verify.rebind: one spec-free learned DS set keyed by a spec's modes, nothing refitted."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pytest

from tli_verify.errors import ModelError
from tli_verify.logic.spec import load_spec
from tli_verify.model.serialize import load_model, model_from_dict, model_to_dict
from tli_verify.model.types import Model, ModeModel
from tli_verify.rebind import reading_of, rebind_model


def test_reading_of_parses_full_conjunctions_only() -> None:
    inputs = ("ch", "br", "pot")
    assert reading_of("!ch & br & !pot", inputs) == {"ch": False, "br": True, "pot": False}
    assert reading_of("br & !ch & !pot", inputs) == {"ch": False, "br": True, "pot": False}
    assert reading_of("!ch & br", inputs) is None  # pot not fixed
    assert reading_of("!ch & br & !pot & !x", inputs) is None  # not an input
    assert reading_of("!ch & ch & br & !pot", inputs) is None  # ch twice
    assert reading_of("w1", inputs) is None  # a spec mode name


def _spec_free(repo: Path, tmp_path: Path, spec: str) -> Model:
    """The DS of a shipped bound model renamed back to readings, as ``tli learn`` without a
    spec names them (the inverse of the binding, for the modes the model has)."""
    bound = load_model(repo / "models" / f"{spec}.model.json")
    labels = dict(load_spec(repo / "specs" / f"{spec}.toml").modes or {})
    modes: dict[str, ModeModel] = {}
    for mm in bound.modes.values():
        src = labels[mm.mode]
        nxt = labels[mm.next_mode] if mm.next_mode is not None else None
        key = src if mm.key == mm.mode else f"{src}->{nxt}"
        modes[key] = ModeModel(key=key, mode=src, next_mode=nxt, ds=mm.ds, fit=mm.fit)
    return Model(state_names=bound.state_names, modes=MappingProxyType(modes), spec=None,
                 path=str(tmp_path / "learned.json"))


def test_rebinding_round_trips_the_shipped_cooking_c_model_bit_for_bit(repo: Path,
                                                                        tmp_path: Path) -> None:
    spec_free = _spec_free(repo, tmp_path, "cooking-c")
    out = tmp_path / "models" / "c.model.json"
    out.parent.mkdir()
    again = rebind_model(spec_free, repo / "specs" / "cooking-c.toml", out)
    shipped = load_model(repo / "models" / "cooking-c.model.json")
    assert set(again.modes) == set(shipped.modes)
    for key, mm in again.modes.items():
        ref = shipped.modes[key]
        assert (mm.mode, mm.next_mode) == (ref.mode, ref.next_mode)
        for f in ("attractor", "priors", "means", "covs", "A", "P"):
            assert np.array_equal(getattr(mm.ds, f), getattr(ref.ds, f)), (key, f)
    assert again.spec is not None and again.spec.endswith("specs/cooking-c.toml")
    model_from_dict(model_to_dict(again), where="rebound")  # a valid model file


def test_rebinding_refuses_a_model_learned_with_a_spec_or_named_otherwise(
        repo: Path, tmp_path: Path) -> None:
    bound = load_model(repo / "models" / "cooking-c.model.json")
    with pytest.raises(ModelError, match="learned with a spec"):
        rebind_model(bound, repo / "specs" / "cooking-c.toml", tmp_path / "x.json")
    with pytest.raises(ModelError, match=r"mode '[dwyg]' is not a reading over the inputs"):
        rebind_model(replace(bound, spec=None), repo / "specs" / "cooking-c.toml",
                     tmp_path / "x.json")
