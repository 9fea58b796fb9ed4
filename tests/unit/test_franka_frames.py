"""scripts/franka_frames.py: which frames a contact sheet shows (no simulation)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def frames() -> ModuleType:
    path = REPO / "scripts" / "franka_frames.py"
    spec = importlib.util.spec_from_file_location("franka_frames", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["franka_frames"] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


def test_a_nominal_sheet_shows_the_middle_of_each_mode(frames: ModuleType) -> None:
    modes = list("aaaabbbbccccccdddd")
    assert frames.pick(modes) == [1, 5, 10, 15]
    assert len(frames.pick(list("aaaaaaaabb"))) == 4  # fewer modes: evenly spaced ones too


def test_a_perturbed_sheet_shows_the_hands_the_replan_and_the_pour(
        frames: ModuleType) -> None:
    shown_t = frames.Shown
    # frames every 2 control steps: a push in b (steps 20-38, growing), the replan at step
    # 30 back to a, then c with a tilt (steps 74-82), then d
    modes = "b" * 15 + "a" * 20 + "c" * 10 + "d" * 10
    shown = []
    for i, mode in enumerate(modes):
        step = 2 * (i + 1)
        force = torque = 0.0
        if 20 <= step <= 38:
            force = 10.0 + step
        if 74 <= step <= 82:
            force, torque = 30.0, 5.0
        shown.append(shown_t(step * 0.02, step, mode, force, torque))
    picked = frames.pick_perturbed(shown, [30], [("push", 0.4), ("tilt", 1.48)])
    assert [k for k, _ in picked] == [13, 29, 36, 49]
    push, replan, tilt, pour = (c for _, c in picked)
    assert push == "push: 38 N (mode b)"  # the strongest frame before the replan
    assert replan == "replanned: mode b -> a"
    assert tilt == "tilt: 30 N, 5 N m (mode c)"
    assert pour == "mode d (pour)"


def test_a_long_mode_sequence_is_shortened(frames: ModuleType) -> None:
    assert frames.short_modes("a b c d") == "a b c d"
    assert frames.short_modes(" ".join("cd" * 10), limit=4) == "c d c d ... (16 more)"
