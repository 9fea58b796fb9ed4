"""The installable package: a wheel built from the repository, installed into a clean virtual
environment, runs ``tli`` (``--version``, the gate on its bundled project, ``tli demo``) from
an empty folder, outside any checkout.

The wheel is built offline from a copy of the source tree (``pip wheel --no-deps
--no-build-isolation``: the setuptools of this environment, no download, and no ``build/`` left
in the checkout). The clean environment (``python -m venv --without-pip``) gets the wheel with
``--no-deps``; its dependencies are made visible by one path line in a ``.pth`` file naming
this environment's site-packages. A path line does not process that folder's own ``.pth``
files, so the editable install of the checkout (``__editable__.tli_verify-*.pth`` and its
finder) is not loaded: the tests check that ``tli_verify`` is imported from the new
environment.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import sysconfig
import time
import tomllib
import zipfile
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SOURCE_FILES = ("pyproject.toml", "setup.py", "MANIFEST.in", "README.md")
"""The files of the source tree a build reads, besides the package and the bundled project."""


def setup_constant(name: str) -> tuple[str, ...]:
    """A tuple of strings assigned at the top of ``setup.py`` (read, never executed)."""
    tree = ast.parse((REPO / "setup.py").read_text(encoding="utf-8"))
    for node in tree.body:
        target = node.targets[0] if isinstance(node, ast.Assign) else (
            node.target if isinstance(node, ast.AnnAssign) else None)
        if isinstance(target, ast.Name) and target.id == name and node.value is not None:
            value = ast.literal_eval(node.value)
            assert isinstance(value, tuple) and all(isinstance(v, str) for v in value)
            return value
    raise AssertionError(f"setup.py assigns no {name}")


BUNDLED_DIRS = setup_constant("BUNDLED_DIRS")
BUNDLED_FILES = setup_constant("BUNDLED_FILES")


def clean_env() -> dict[str, str]:
    """The environment of a user's shell: nothing that points Python at the checkout."""
    env = {k: v for k, v in os.environ.items()
           if k not in {"PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "VIRTUAL_ENV",
                        "TLI_SIM_ASSETS", "PYTHONSAFEPATH"}}
    env.update(MPLBACKEND="Agg", PYTHONNOUSERSITE="1")
    return env


def sh(*argv: str | Path, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    done = subprocess.run([str(a) for a in argv], cwd=cwd, env=clean_env(), capture_output=True,
                          text=True, timeout=timeout, check=False)
    return done


def ok(done: subprocess.CompletedProcess[str]) -> str:
    assert done.returncode == 0, (done.args, done.stdout[-3000:], done.stderr[-3000:])
    return done.stdout


@dataclass(frozen=True)
class Installed:
    wheel: Path
    venv: Path
    python: Path
    tli: Path
    site: Path
    source: Path
    seconds: dict[str, float]


def _copy_source(dest: Path) -> None:
    """The files a build reads, as a fresh tree, plus two files the wheel must never ship (a
    fetched MuJoCo asset, a bytecode cache)."""
    ignore = shutil.ignore_patterns("__pycache__", "*.py[cod]")
    for name in SOURCE_FILES:
        shutil.copy2(REPO / name, dest / name)
    shutil.copytree(REPO / "tli_verify", dest / "tli_verify", ignore=ignore)
    for rel in BUNDLED_DIRS:
        shutil.copytree(REPO / rel, dest / rel, ignore=ignore)
    for rel in BUNDLED_FILES:
        (dest / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / rel, dest / rel)
    sentinel = dest / "sim" / "assets" / "mujoco_menagerie" / "franka_emika_panda" / "panda.xml"
    sentinel.parent.mkdir(parents=True)
    sentinel.write_text("<mujoco/>\n")
    (dest / "specs" / "__pycache__").mkdir()
    (dest / "specs" / "__pycache__" / "stale.cpython-311.pyc").write_bytes(b"\0")


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    """Build the wheel, make a clean venv, install the wheel into it (no dependencies)."""
    base = tmp_path_factory.mktemp("wheel")
    seconds: dict[str, float] = {}
    source, wheels, venv = base / "src", base / "wheels", base / "venv"
    source.mkdir()
    _copy_source(source)
    t0 = time.perf_counter()
    ok(sh(sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
          "--no-index", "--wheel-dir", wheels, source, cwd=base))
    seconds["build"] = time.perf_counter() - t0
    (wheel,) = wheels.glob("tli_verify-*.whl")
    t0 = time.perf_counter()
    ok(sh(sys.executable, "-m", "venv", "--without-pip", venv, cwd=base))
    python = venv / "bin" / "python"
    ok(sh(sys.executable, "-m", "pip", "--python", python, "install", "--quiet", "--no-deps",
          "--no-index", wheel, cwd=base))
    site = Path(ok(sh(python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))",
                      cwd=base)).strip())
    deps = dict.fromkeys(sysconfig.get_path(k) for k in ("purelib", "platlib"))
    (site / "_tli_verify_test_dependencies.pth").write_text("".join(f"{d}\n" for d in deps))
    seconds["venv+install"] = time.perf_counter() - t0
    return Installed(wheel=wheel, venv=venv, python=python, tli=venv / "bin" / "tli",
                     site=site, source=source, seconds=seconds)


def _files_under(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in sorted(root.rglob("*"))
            if p.is_file() and "__pycache__" not in p.parts}


# --------------------------------------------------------------------------------------------
# Cheap: no build
# --------------------------------------------------------------------------------------------

def test_the_sdist_manifest_carries_what_the_build_copies() -> None:
    """``MANIFEST.in`` (the sdist) and ``setup.py`` (the wheel) list the same bundled project."""
    lines = [ln.split() for ln in (REPO / "MANIFEST.in").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    grafted = {w[1] for w in lines if w[0] == "graft"}
    included = {w[1] for w in lines if w[0] == "include"}
    assert ["prune", "sim/assets"] in lines
    for rel in BUNDLED_DIRS:
        assert rel in grafted or any(rel.startswith(g + "/") for g in grafted), rel
    assert set(BUNDLED_FILES) <= included
    assert grafted <= {*BUNDLED_DIRS, "sim/franka"}  # nothing shipped that the wheel drops


def test_bundled_files_are_found_by_the_one_resolver_only() -> None:
    """No module but ``tli_verify/io.py`` (``bundled_root``/``bundled_dir``, through
    ``importlib.resources``) finds files relative to the package's own location: that breaks
    in an installed wheel, where the bundled project is ``tli_verify/data/``.
    ``_version.py`` reads ``pyproject.toml`` in a bare checkout, by design."""
    import re

    locating = re.compile(r"Path\(__file__\)|os\.path\.dirname\(__file__|\.parents\[|"
                          r"resources\.files\(")
    allowed = {"tli_verify/io.py", "tli_verify/_version.py"}
    found = [str(p.relative_to(REPO)) for p in sorted((REPO / "tli_verify").rglob("*.py"))
             if str(p.relative_to(REPO)) not in allowed
             and locating.search(p.read_text(encoding="utf-8"))]
    assert found == []
    from tli_verify.io import BUNDLED_FOLDERS

    assert {rel.split("/")[0] for rel in BUNDLED_DIRS} == set(BUNDLED_FOLDERS)


# --------------------------------------------------------------------------------------------
# The wheel, in a clean virtual environment
# --------------------------------------------------------------------------------------------

def test_the_wheel_installs_cleanly_and_runs_from_an_empty_folder(installed: Installed,
                                                                  tmp_path: Path) -> None:
    """What the wheel holds, where the clean venv imports it from, ``tli --version`` and the
    gate on the installed bundled project (no re-run), all from an empty folder."""
    names = set(zipfile.ZipFile(installed.wheel).namelist())
    shipped = {n.removeprefix("tli_verify/data/") for n in names
               if n.startswith("tli_verify/data/")}
    expected = set()
    for rel in BUNDLED_DIRS:
        expected |= {str(p.relative_to(installed.source)) for p in
                     (installed.source / rel).rglob("*")
                     if p.is_file() and "__pycache__" not in p.parts}
    assert shipped == expected | set(BUNDLED_FILES)
    for rel in ("specs/scoop.toml", "tasks/scoop.toml", "demos/scoop_1.csv",
                "models/scoop.model.json", "certificates/scoop.cert.json",
                "certificates/scoop.campaign.json", "sim/franka/specs/franka-scoop.toml",
                "sim/franka/models/franka-scoop.model.json", "sim/PROVENANCE.md"):
        assert rel in shipped, rel
    assert not [n for n in names if "assets/" in n or "__pycache__" in n or
                n.endswith(".pyc")], "the wheel ships MuJoCo assets or bytecode"
    assert "tli_verify/schemas/campaign.schema.json" in names

    empty = tmp_path / "empty"
    empty.mkdir()
    probe = ("import sys, tli_verify, importlib.metadata as md\n"
             "from tli_verify.io import bundled_root\n"
             "from tli_verify.sim.assets import assets_dir\n"
             "print(tli_verify.__file__)\n"
             "print(md.distribution('tli-verify').locate_file(''))\n"
             "print(bundled_root())\n"
             "print(assets_dir())\n"
             "print(tli_verify.__version__)\n"
             "print(sorted(m for m in sys.modules if 'editable' in m))\n")
    module, dist, root, assets, ver, editable = ok(
        sh(installed.python, "-c", probe, cwd=empty)).splitlines()
    package = installed.site / "tli_verify"
    assert Path(module) == package / "__init__.py"
    assert Path(dist) == installed.site
    assert Path(root) == package / "data"
    assert Path(assets) == package / "data" / "sim" / "assets"
    assert editable == "[]"
    with (REPO / "pyproject.toml").open("rb") as f:
        pyproject = tomllib.load(f)["project"]["version"]
    assert ver == pyproject == version("tli-verify")
    assert ok(sh(installed.tli, "--version", cwd=empty)) == f"tli-verify {pyproject}\n"

    before = _files_under(package)
    gate = ("import sys\n"
            "from tli_verify.deploy.gate import run_gate\n"
            "from tli_verify.io import bundled_root\n"
            "report = run_gate(bundled_root(), rerun=0)\n"  # the static checks; no re-run
            "print(len(report.items))\n"
            "for b in report.blockers: print(b.path, b.message)\n"
            "sys.exit(0 if report.ok else 1)\n")
    checks = ok(sh(installed.python, "-c", gate, cwd=empty)).split()
    assert int(checks[0]) > 30
    assert _files_under(package) == before, "the gate wrote into the installation"
    assert list(empty.iterdir()) == []


@pytest.mark.slow  # about 90 s on 2 shared cores: the whole demo pipeline
def test_tli_demo_runs_from_an_empty_folder_with_the_installed_wheel(installed: Installed,
                                                                      tmp_path: Path) -> None:
    """``tli demo --out out``, in an empty folder, with only the wheel installed (no checkout,
    no MuJoCo assets): every stage runs on the bundled project, the gate passes, and nothing is
    written outside ``out/`` (not into the installation either)."""
    empty = tmp_path / "empty"
    empty.mkdir()
    package = installed.site / "tli_verify"
    before = _files_under(package)
    t0 = time.perf_counter()
    done = sh(installed.tli, "demo", "--out", "out", cwd=empty, timeout=900)
    seconds = time.perf_counter() - t0
    out = ok(done)
    assert "re-checks exactly" in out
    assert "[run] gate on the shipped tasks/specs/models/certificates: pass" in out, out
    assert "results written under out/" in out
    for rel in ("automata/scoop.json", "automata/scoop.dot", "motion/scoop.model.json",
                "motion/scoop.cert.json", "motion/scoop_modes.png",
                "single-mode/single_mode.md", "run/LTL-DS.json", "run/no-modulation.json",
                "run/scoop_modulation.png"):
        assert (empty / "out" / rel).is_file(), rel
    assert (empty / "out" / "scoop").is_dir()
    assert [p.name for p in empty.iterdir()] == ["out"]
    assert _files_under(package) == before, "tli demo wrote into the installation"
    print(f"tli demo from the wheel: {seconds:.0f} s (build {installed.seconds})")
