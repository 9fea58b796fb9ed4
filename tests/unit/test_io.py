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


# --------------------------------------------------------------------------------------------
# Output checks, bounded reads, nesting
# --------------------------------------------------------------------------------------------

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tli_verify.errors import DemoError, ModelError, OutputError  # noqa: E402
from tli_verify.io import (  # noqa: E402
    check_nesting,
    check_output_dir,
    check_output_file,
    read_text,
)
from tli_verify.limits import MAX_INPUT_BYTES, MAX_NESTING  # noqa: E402

SEGMENTS = st.sampled_from([".", "..", "d", "f.json", "in.csv", "lnk", "new", "new.json"])


def _tree(root: Path) -> tuple[Path, Path]:
    """root/d/ (directory), root/d/f.json (a file), root/d/in.csv (the input), root/d/lnk
    (a symlink to the input)."""
    d = root / "d"
    d.mkdir(exist_ok=True)
    (d / "f.json").write_text("other\n")
    src = d / "in.csv"
    src.write_text("input\n")
    if not (d / "lnk").exists():
        (d / "lnk").symlink_to(src)
    return d, src


@settings(max_examples=300)
@given(parts=st.lists(SEGMENTS, min_size=1, max_size=5))
def test_check_output_file_agrees_with_what_a_write_would_do(
        parts: list[str], tmp_path_factory: pytest.TempPathFactory) -> None:
    """Oracle: the check passes iff an atomic write succeeds AND leaves the input intact."""
    root = tmp_path_factory.mktemp("o")
    d, src = _tree(root)
    path = d.joinpath(*parts)
    try:
        aliases_input = path.resolve() == src.resolve()  # e.g. d/lnk, d/./in.csv
    except (OSError, RuntimeError):
        aliases_input = False
    try:
        check_output_file(path, inputs=[src])
    except OutputError:
        refused = True
    else:
        refused = False
    missing_then_up = any(  # d/new/../x: the write would first create d/new
        part == ".." and not d.joinpath(*parts[:i]).is_dir() for i, part in enumerate(parts))
    try:
        atomic_write_text(path, "result\n")
        wrote = src.read_text() == "input\n"
    except OutputError:
        wrote = False
    assert refused == (aliases_input or missing_then_up or not wrote), (path, refused, wrote)


@pytest.mark.parametrize("bad", ["", "d", "d/f.json/x.json", "fifo"])
def test_check_output_file_refuses(bad: str, tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    _tree(tmp_path)
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(OutputError):
        check_output_file(bad)


@pytest.mark.parametrize("bad", ["", "d/f.json", "d/f.json/sub", "fifo"])
def test_check_output_dir_refuses(bad: str, tmp_path: Path,
                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    _tree(tmp_path)
    os.mkfifo(tmp_path / "fifo")
    with pytest.raises(OutputError):
        check_output_dir(bad)
    check_output_dir("d/new/deeper")  # a missing directory under a writable one is fine


@pytest.mark.parametrize("target", ["dir", "under-file"])
def test_atomic_write_raises_output_error_not_oserror(target: str, tmp_path: Path) -> None:
    (tmp_path / "f").write_text("x")
    path = tmp_path if target == "dir" else tmp_path / "f" / "x.json"
    with pytest.raises(OutputError):
        atomic_write_text(path, "{}\n")
    assert (tmp_path / "f").read_text() == "x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_read_text_refuses_devices_fifos_and_big_files(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo")
    for path in ("/dev/zero", "/dev/urandom", tmp_path / "fifo"):
        with pytest.raises(ModelError, match="not a regular file"):
            read_text(path, what="model", error=ModelError)
    big = tmp_path / "big.csv"
    big.write_bytes(b"#" * (MAX_INPUT_BYTES + 1))
    with pytest.raises(DemoError, match="MAX_INPUT_BYTES"):
        read_text(big, what="demonstration", error=DemoError)
    with pytest.raises(DemoError, match="is a directory"):
        read_text(tmp_path, what="demonstration", error=DemoError)


def test_read_text_drops_a_byte_order_mark(tmp_path: Path) -> None:
    f = tmp_path / "a.csv"
    f.write_bytes(b"\xef\xbb\xbft,x0\n")
    assert read_text(f, what="demonstration", error=DemoError) == "t,x0\n"


@settings(max_examples=100)
@given(depth=st.integers(0, 3 * MAX_NESTING),
       brackets=st.lists(st.sampled_from(["[", "{"]), min_size=1, max_size=4),
       decoy=st.sampled_from(['"[[[["', "'{{{{'", "# [[[[[[\n", ""]))
def test_check_nesting_counts_real_brackets_only(depth: int, brackets: list[str],
                                                 decoy: str) -> None:
    closer = {"[": "]", "{": "}"}
    opened = [brackets[i % len(brackets)] for i in range(depth)]
    text = "".join(o + decoy for o in opened) + "".join(closer[o] for o in reversed(opened))
    text = (decoy * (2 * MAX_NESTING)) + text
    if depth > MAX_NESTING:
        with pytest.raises(ModelError, match="MAX_NESTING"):
            check_nesting(text, where="x.json", error=ModelError)
    else:
        check_nesting(text, where="x.json", error=ModelError)
