"""The pytest plugin of tli-verify (entry point ``tli_verify.testing.plugin``, group ``pytest11``).

Installed with tli-verify, so ``pytest`` loads it. It is inert for a run that uses neither its
options nor its fixtures nor :mod:`tli_verify.testing`: importing it imports neither
hypothesis nor the simulator, and it changes no other test.

Fixtures
--------
``tli_project``
    The :class:`~tli_verify.testing.Project` of ``--tli-project PATH`` (ini ``tli_project``),
    else of the rootdir (session-scoped: resolved and loaded once); the same project
    :func:`tli_verify.testing.cases` draws for when called without one.
``tli_case_dir``
    Where :func:`~tli_verify.testing.assert_satisfies` saves failing cases
    (``--tli-case-dir DIR``, ini ``tli_case_dir``; else the project's ``tests/regressions/``,
    else a temporary directory).

Options
-------
``--tli-project PATH``
    The project (a folder, a model, a spec or a task) of ``tli_project``, of
    ``tli_verify.testing.project()`` without arguments and of ``cases()`` without a project.
``--tli-examples N``, ``--tli-seed S``
    ``max_examples`` and the seed of the hypothesis tests that draw from
    :func:`tli_verify.testing.cases` (a ``@given`` argument built by it) or use the
    ``tli_project`` fixture (ini ``tli_examples``); a seed also turns the example database off
    for them, so the run is the seed's. These tests also get ``deadline=None`` unless they set
    a deadline (a closed-loop run takes far longer than hypothesis's 200 ms default). Other
    hypothesis tests keep their settings.
``--tli-cases DIR`` (repeatable; ini ``tli_cases``, paths relative to the ini file)
    Every ``*.json`` case file directly in DIR becomes a test item that replays it, by the rules
    of the repository's regression cases: a case recorded **without** modulation must still
    show its violation (same oracle modes), and LTL-DS must pass it; a case recorded **with**
    modulation is a bug report -- it fails while its violation reproduces (a bug that must stay
    fixed), unless it carries an ``"open"`` note (a known bug: then it must still reproduce, and
    is reported as xfail). A case whose files changed since it was recorded fails, naming the
    file.
``--tli-case-dir DIR``
    Where failing cases are saved.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:  # pragma: no cover - types only
    from tli_verify.testing.projects import Project

__all__ = ["CaseFile", "CaseItem"]


@dataclass(slots=True)
class _State:
    project: Path | None = None
    case_dir: Path | None = None
    examples: int | None = None
    seed: int | None = None
    cases: list[Path] = field(default_factory=list)
    irregular: list[Path] = field(default_factory=list)  # FIFOs, devices, dangling links
    saved: tuple[Path | None, Path | None] = (None, None)
    touched: bool = False


_KEY = pytest.StashKey[_State]()


# ------------------------------------------------------------------------------ options
def _usage(option: str, lo: int) -> Callable[[str], int]:
    """``int_range(lo)`` of :mod:`tli_verify.arguments` (imported on use: the plugin stays
    inert for a run that does not use it), its error a pytest usage error naming the option."""

    def parse(text: str) -> int:
        from tli_verify.arguments import int_range

        try:
            return int_range(lo)(text)
        except argparse.ArgumentTypeError as exc:
            raise pytest.UsageError(f"{option}: {exc}") from None

    return parse


_count = _usage("--tli-examples", 1)
_seed = _usage("--tli-seed", 0)


def pytest_addoption(parser: pytest.Parser) -> None:
    """The ``tli-verify`` options and ini settings (module docstring)."""
    group = parser.getgroup("tli-verify", "tli-verify property tests and regression cases")
    group.addoption("--tli-project", metavar="PATH", default=None,
                    help="the project under test: a folder, model, spec or task (default: "
                    "the rootdir)")
    group.addoption("--tli-examples", metavar="N", default=None,
                    help="hypothesis max_examples of tests drawing tli_verify.testing.cases")
    group.addoption("--tli-seed", metavar="S", default=None,
                    help="hypothesis seed of tests drawing tli_verify.testing.cases")
    group.addoption("--tli-cases", metavar="DIR", action="append", default=None,
                    help="replay every *.json case file in DIR as a test (repeatable)")
    group.addoption("--tli-case-dir", metavar="DIR", default=None,
                    help="where assert_satisfies saves failing cases (default: the "
                    "project's tests/regressions/, else a temporary directory)")
    parser.addini("tli_project", "tli-verify: the project under test (relative to the ini "
                  "file)", type="string", default="")
    parser.addini("tli_cases", "tli-verify: directories of case files replayed as tests",
                  type="paths", default=[])
    parser.addini("tli_case_dir", "tli-verify: where failing cases are saved (relative to "
                  "the ini file)", type="string", default="")
    parser.addini("tli_examples", "tli-verify: hypothesis max_examples of tests drawing "
                  "tli_verify.testing.cases", type="string", default="")


def _ini_path(config: pytest.Config, value: str) -> Path | None:
    if not value:
        return None
    base = config.inipath.parent if config.inipath is not None else config.rootpath
    return Path(os.path.abspath(base / value))


def _state(config: pytest.Config) -> _State:
    opt = config.option
    inv = config.invocation_params.dir
    st = _State()
    proj = getattr(opt, "tli_project", None)
    st.project = (Path(os.path.abspath(inv / proj)) if proj
                  else _ini_path(config, str(config.getini("tli_project") or "")))
    case_dir = getattr(opt, "tli_case_dir", None)
    st.case_dir = (Path(os.path.abspath(inv / case_dir)) if case_dir
                   else _ini_path(config, str(config.getini("tli_case_dir") or "")))
    examples = getattr(opt, "tli_examples", None) or str(config.getini("tli_examples") or "")
    st.examples = _count(examples) if examples else None
    seed = getattr(opt, "tli_seed", None)
    st.seed = _seed(seed) if seed is not None else None
    dirs = [Path(os.path.abspath(inv / d)) for d in (getattr(opt, "tli_cases", None) or [])]
    if not dirs:
        dirs = [Path(os.path.abspath(p)) for p in config.getini("tli_cases") or []]
    for d in dirs:
        if not d.is_dir():
            raise pytest.UsageError(f"--tli-cases {d}: no such directory")
    st.cases = dirs
    return st


ROOTS: list[Path] = []
"""The rootdirs of the pytest sessions running in this process (innermost last): where
:func:`tli_verify.testing.projects.default_root` looks without ``--tli-project``."""


def pytest_configure(config: pytest.Config) -> None:
    """Read the options; with none given, nothing else happens (nothing is imported)."""
    st = _state(config)
    config.stash[_KEY] = st
    ROOTS.append(Path(config.rootpath))
    if st.project is None and st.case_dir is None and not st.cases:
        return
    from tli_verify.testing.projects import DEFAULTS

    st.saved = (DEFAULTS.project, DEFAULTS.case_dir)
    st.touched = True
    if st.project is not None:
        DEFAULTS.project = st.project
    if st.case_dir is not None:
        DEFAULTS.case_dir = st.case_dir
    if st.cases:  # case files outside the collected paths are collected too
        roots = [Path(os.path.abspath(config.invocation_params.dir / str(a).split("::")[0]))
                 for a in config.args]
        for d in st.cases:
            for f in sorted(d.glob("*.json")):
                if not f.is_file():  # a FIFO, a device, a dangling link: never an argument
                    st.irregular.append(f)  # (pytest would abort on it): a failing item
                    continue
                if not any(f == r or f.is_relative_to(r) for r in roots if r.is_dir()
                           or r == f):
                    config.args.append(str(f))


def pytest_unconfigure(config: pytest.Config) -> None:
    """Restore the process defaults (a pytest run inside a process leaves none behind)."""
    st = config.stash.get(_KEY, None)
    if st is None:
        return
    if ROOTS:
        ROOTS.pop()
    if not st.touched:
        return
    from tli_verify.testing.projects import DEFAULTS

    DEFAULTS.project, DEFAULTS.case_dir = st.saved


def pytest_report_header(config: pytest.Config) -> list[str] | None:
    """One header line naming what the plugin was asked to do (none when inactive)."""
    st = config.stash.get(_KEY, None)
    if st is None:
        return None
    parts = []
    if st.project is not None:
        parts.append(f"project {st.project}")
    if st.examples is not None:
        parts.append(f"examples {st.examples}")
    if st.seed is not None:
        parts.append(f"seed {st.seed}")
    if st.cases:
        parts.append("cases " + ", ".join(str(d) for d in st.cases))
    if st.case_dir is not None:
        parts.append(f"case dir {st.case_dir}")
    return [f"tli-verify: {'; '.join(parts)}"] if parts else None


# ------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="session")
def tli_project() -> Project:
    """The project under test (``--tli-project``, ini ``tli_project``, else the rootdir),
    resolved and loaded once per session: the one :func:`tli_verify.testing.cases` draws for
    without a project."""
    from tli_verify.testing.projects import default_project

    return default_project()


@pytest.fixture(scope="session")
def tli_case_dir(tli_project: Project) -> Path:
    """Where failing cases are saved (``--tli-case-dir``, else the project's
    ``tests/regressions/``, else a temporary directory)."""
    return tli_project.regression_dir


# ------------------------------------------------------------------------------ settings
_MARK = "_tli_verify_cases"  # tli_verify.testing.strategies.MARK (not imported: inert)


def _ours(item: pytest.Item) -> bool:
    """A hypothesis test drawing from :func:`tli_verify.testing.cases` (a ``@given`` argument
    built by it) or using the ``tli_project`` fixture."""
    fn = getattr(item, "obj", None)
    if fn is None or not getattr(fn, "is_hypothesis_test", False):
        return False
    if "tli_project" in getattr(item, "fixturenames", ()):
        return True
    given = getattr(getattr(fn, "hypothesis", None), "_given_kwargs", None)
    return isinstance(given, dict) and any(getattr(s, _MARK, False) is True
                                           for s in given.values())


def pytest_collection_modifyitems(session: pytest.Session, config: pytest.Config,
                                   items: list[pytest.Item]) -> None:
    """A ``*.json`` in a ``--tli-cases`` folder that is not a regular file (a FIFO, a link to
    ``/dev/zero``, a dangling link) is a case item that fails in one line naming it (pytest
    itself would abort the session on it, or never finish reading it).

    Settings of the hypothesis tests of a closed loop (:func:`_ours`): no deadline unless
    the test set one (a run simulates thousands of control steps: hypothesis's 200 ms
    default would fail it at random), ``--tli-examples`` (max_examples) and ``--tli-seed``
    (the seed, and no example database: the run is the seed's). Other tests are untouched."""
    import sys

    st0 = config.stash.get(_KEY, None)
    if st0 is not None and st0.irregular:
        for f in st0.irregular:
            items.extend(CaseFile.from_parent(session, path=f).collect())
        st0.irregular.clear()

    if "hypothesis" not in sys.modules:  # no hypothesis test was collected
        return
    ours = [item for item in items if _ours(item)]
    if not ours:
        return
    st = config.stash.get(_KEY, None)
    from datetime import timedelta

    from hypothesis import settings

    for item in ours:
        fn = item.obj  # type: ignore[attr-defined]
        current = getattr(fn, "_hypothesis_internal_use_settings", None) or settings()
        changes: dict[str, Any] = {}
        if current.deadline == timedelta(milliseconds=200):  # hypothesis's default
            changes["deadline"] = None
        if st is not None and st.examples is not None:
            changes["max_examples"] = st.examples
        if st is not None and st.seed is not None:
            fn._hypothesis_internal_use_seed = st.seed
            changes["database"] = None
        if changes:
            fn._hypothesis_internal_use_settings = settings(current, **changes)


# ------------------------------------------------------------------------------ cases
def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    """A ``*.json`` file directly in a ``--tli-cases`` directory: a regression case."""
    if file_path.suffix != ".json":
        return None
    st = parent.config.stash.get(_KEY, None)
    if st is None or not st.cases:
        return None
    folder = Path(os.path.abspath(file_path)).parent
    if not any(folder == d for d in st.cases):
        return None
    return CaseFile.from_parent(parent, path=file_path)


class CaseFailure(Exception):
    """A regression case that does not replay as its rules say (module docstring)."""


class CaseFile(pytest.File):
    """A case file (``tli verify``'s counterexample.json, or one
    :func:`~tli_verify.testing.assert_satisfies` saved)."""

    def collect(self) -> Iterator[pytest.Item]:
        """One item: ``replay``."""
        yield CaseItem.from_parent(self, name="replay")


class CaseItem(pytest.Item):
    """Replays a case file by the regression rules (module docstring)."""

    def runtest(self) -> None:
        """Replay the case (and, for a no-modulation case, the same case under LTL-DS)."""
        from tli_verify.errors import CampaignError, TliError
        from tli_verify.io import read_json
        from tli_verify.verify.cases import replay_case

        path = self.path
        try:  # a regular file within MAX_INPUT_BYTES, nested at most MAX_NESTING deep
            doc = read_json(path, what="case", error=CampaignError)
        except TliError as exc:
            raise CaseFailure(f"{path.name}: not a readable case file ({exc})") from None
        if not isinstance(doc, dict):
            raise CaseFailure(f"{path.name}: not a case file (a JSON object is expected)")
        try:
            _, verdict, reproduced, notes = replay_case(path)
        except TliError as exc:
            raise CaseFailure(str(exc)) from None
        except RecursionError:  # the backstop: one line, never hundreds
            raise CaseFailure(f"{path.name}: nested too deeply to replay") from None
        if notes:
            raise CaseFailure(f"{path.name}: {'; '.join(notes)}: re-record the case (tli "
                              "verify ... or assert_satisfies) and check it still shows what "
                              "it documents")
        want = doc["expected"]["violation"]
        now = ", ".join(sorted(k.value for k in verdict.kinds)) or "none"
        if doc["modulation"]:
            if doc.get("open"):  # a known, open bug: it must still reproduce until fixed
                if not reproduced:
                    raise CaseFailure(f"{path.name}: no longer reproduces ({want}): the bug "
                                      "is fixed, remove its 'open' note")
                pytest.xfail(f"open: {doc['open']}")
            if reproduced:
                raise CaseFailure(f"{path.name}: the bug reproduces with modulation: "
                                  f"{want} (violations now: {now}; modes "
                                  f"{verdict.oracle_modes[:60]}); "
                                  + "; ".join(v.message for v in verdict.violations[:2]))
            return
        if not reproduced:
            raise CaseFailure(f"{path.name}: recorded without modulation: expected {want}, "
                              f"got {now}: the ablation's failure no longer reproduces")
        if verdict.oracle_modes != doc["expected"]["oracle_modes"]:
            raise CaseFailure(f"{path.name}: oracle modes {verdict.oracle_modes[:60]!r}, "
                              f"recorded {doc['expected']['oracle_modes'][:60]!r}")
        _, fixed, again, _ = replay_case(path, modulation=True)
        if again or not fixed.ok:
            raise CaseFailure(f"{path.name}: LTL-DS (modulation on) does not pass the case: "
                              + "; ".join(v.message for v in fixed.violations[:2]))

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException],
                     style: Any = None) -> str:
        """The one-line reason of a :class:`CaseFailure`, else the usual report."""
        if isinstance(excinfo.value, CaseFailure):
            return str(excinfo.value)
        return str(super().repr_failure(excinfo))

    def reportinfo(self) -> tuple[Path, int | None, str]:
        """``PATH: tli replay PATH``."""
        return self.path, None, f"tli replay {self.path.name}"
