"""Atomic writes: content, permissions, no temporary file left behind."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from tli_verify.io import atomic_write_bytes, atomic_write_text


@pytest.mark.parametrize("mask", [0o022, 0o077])
def test_atomic_write_respects_umask(tmp_path: Path, mask: int) -> None:
    old = os.umask(mask)
    try:
        target = tmp_path / "sub" / "cert.json"
        atomic_write_text(target, "{}\n")
    finally:
        os.umask(old)
    assert target.read_text() == "{}\n"
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~mask
    assert [p.name for p in target.parent.iterdir()] == ["cert.json"]


def test_atomic_write_replaces(tmp_path: Path) -> None:
    target = tmp_path / "a.bin"
    atomic_write_bytes(target, b"one")
    atomic_write_bytes(target, b"two")
    assert target.read_bytes() == b"two"
