"""The headless OpenGL choice of ``tli sim franka --video`` (tli_verify.sim.render).

The probes are replaced by recorded outcomes here (a real probe starts a Python process and
opens an OpenGL context; tests/integration/test_sim_video.py runs real ones).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tli_verify.commands import exit_code
from tli_verify.errors import TliError
from tli_verify.sim import render
from tli_verify.sim.render import Probe


class FakeProbe:
    """A probe answering from a table (``backend -> detail``; ``""``: it renders), recording
    the order of the calls."""

    def __init__(self, **failing: str) -> None:
        self.failing = failing
        self.calls: list[str] = []

    def __call__(self, backend: str, **_: object) -> Probe:
        self.calls.append(backend)
        detail = self.failing.get(backend, "")
        return Probe(backend, not detail, detail)


def test_egl_failing_falls_back_to_osmesa() -> None:
    probe = FakeProbe(egl="EGLError: no display")
    assert render.choose_backend({}, probe) == "osmesa"
    assert probe.calls == ["egl", "osmesa"]


def test_egl_working_is_chosen_without_trying_osmesa() -> None:
    probe = FakeProbe(osmesa="libOSMesa not found")
    assert render.choose_backend({"MUJOCO_GL": ""}, probe) == "egl"
    assert probe.calls == ["egl"]


def test_none_working_is_one_line_naming_each_backend_and_what_to_install() -> None:
    probe = FakeProbe(egl="EGLError: no display", osmesa="libOSMesa not found")
    with pytest.raises(TliError) as info:
        render.choose_backend({}, probe)
    msg = str(info.value)
    assert exit_code(info.value) == 2 and "\n" not in msg
    assert msg.startswith("--video: no headless OpenGL context")
    assert "MUJOCO_GL=egl: EGLError: no display" in msg
    assert "MUJOCO_GL=osmesa: libOSMesa not found" in msg
    assert "libegl1" in msg and "libosmesa6" in msg
    assert probe.calls == ["egl", "osmesa"]


@pytest.mark.parametrize("user", ["osmesa", "glfw", "egl"])
def test_the_users_backend_is_the_only_one_tried(user: str) -> None:
    probe = FakeProbe()
    assert render.choose_backend({"MUJOCO_GL": f" {user} "}, probe) == user
    assert probe.calls == [user]


def test_the_users_failing_backend_is_not_replaced() -> None:
    probe = FakeProbe(osmesa="libOSMesa not found")
    with pytest.raises(TliError, match=r"MUJOCO_GL=osmesa \(set in the environment\) opens no "
                       r"OpenGL context: libOSMesa not found; unset MUJOCO_GL") as info:
        render.choose_backend({"MUJOCO_GL": "osmesa"}, probe)
    assert "libosmesa6" in str(info.value)
    assert probe.calls == ["osmesa"]  # egl would work, but the user asked for osmesa


def test_select_backend_sets_mujoco_gl_to_the_fallback(monkeypatch: pytest.MonkeyPatch) -> None:
    probe = FakeProbe(egl="EGLError: no display")
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(render, "backend_in_effect", lambda: None)  # MuJoCo not imported yet
    monkeypatch.setattr(render, "probe_backend", probe)
    assert render.select_backend() == "osmesa"
    assert os.environ["MUJOCO_GL"] == "osmesa"
    assert probe.calls == ["egl", "osmesa"]


def test_select_backend_after_mujoco_was_imported_keeps_its_backend(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Once imported, MuJoCo's backend cannot change: reported, never probed or overridden."""
    probe = FakeProbe()
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    monkeypatch.setattr(render, "backend_in_effect", lambda: "egl")
    monkeypatch.setattr(render, "probe_backend", probe)
    assert render.select_backend() == "egl"
    assert probe.calls == [] and os.environ["MUJOCO_GL"] == "osmesa"


def test_a_failing_probe_reports_its_last_error_line(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """A real subprocess (an interpreter that fails like MuJoCo does), no MuJoCo needed."""
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho 'Traceback (most recent call last):' >&2\n"
                    "echo 'RuntimeError: invalid value for MUJOCO_GL: '$MUJOCO_GL >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(render.sys, "executable", str(fake))
    res = render.probe_backend("nonsense")
    assert res == Probe("nonsense", False, "RuntimeError: invalid value for MUJOCO_GL: nonsense")
    fake.write_text("#!/bin/sh\nexit 0\n")
    assert render.probe_backend("nonsense") == Probe("nonsense", True)


@given(h=st.integers(0, 700), w=st.integers(0, 700))
def test_frame_sizes_are_multiples_of_8(h: int, w: int) -> None:
    valid = h >= 16 and w >= 16 and h % 8 == 0 and w % 8 == 0
    if valid:
        assert render.Recorder(size=(h, w)).size == (h, w)
    else:
        with pytest.raises(TliError, match="multiples of 8"):
            render.Recorder(size=(h, w))


def test_saving_without_frames_writes_nothing(tmp_path: Path) -> None:
    rec = render.Recorder()
    with pytest.raises(TliError, match="no frames were rendered"):
        rec.save(tmp_path / "out.mp4")
    assert list(tmp_path.iterdir()) == []
