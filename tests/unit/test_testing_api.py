"""``tli_verify.testing`` without a simulation: its import cost, the plugin's inertness for a run
that does not use it, its option checks, the strategies' defaults and refusals, and the JUnit
XML of a campaign."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from hypothesis import given, settings

from tests.support.drawer3d import write_project
from tli_verify.testing import cases
from tli_verify.verify.strategies import Case

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[2]


def _python(code: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "PYTEST_ADDOPTS"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=REPO, env=env, timeout=120, check=True)
    return proc.stdout.strip()


def test_importing_the_testing_api_and_the_plugin_is_cheap() -> None:
    """Neither hypothesis, numpy nor the simulator load until a name is used."""
    heavy = ("hypothesis", "numpy", "scipy", "cvxpy", "tli_verify.verify",
             "tli_verify.runtime", "tli_verify.testing.projects")
    out = _python("import sys, tli_verify.testing, tli_verify.testing.plugin; "
                  f"print([m for m in {heavy!r} if m in sys.modules])")
    assert out == "[]"
    out = _python("import sys, tli_verify.testing as t; t.Project; "
                  "print('hypothesis' in sys.modules, 'tli_verify.testing.projects' in "
                  "sys.modules, sorted(set(t.__all__) - set(dir(t))))")
    assert out == "False True []"


def test_the_plugin_is_inert_for_a_run_that_does_not_use_it(pytester: pytest.Pytester) -> None:
    """Loaded from its entry point in a new process, it imports nothing of tli-verify's,
    prints no header line and leaves a hypothesis test's settings alone."""
    pytester.makeconftest('''
        import sys

        def pytest_sessionfinish(session):
            loaded = sorted(m for m in sys.modules if m.startswith("tli_verify")
                            and m not in ("tli_verify", "tli_verify._lazy",
                                          "tli_verify.testing", "tli_verify.testing.plugin"))
            print("\\nTLI-MODULES", loaded,
                  session.config.pluginmanager.has_plugin("tli_verify.testing.plugin"))
        ''')
    pytester.makepyfile('''
        from hypothesis import given, settings, strategies as st

        @given(st.integers())
        def test_x(x):
            pass

        def test_settings_untouched():
            # the profile's own deadline (hypothesis's built-in "ci" profile has none, on CI)
            assert test_x._hypothesis_internal_use_settings.deadline == settings().deadline
        ''')
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-s")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["TLI-MODULES [] True"])
    assert "tli-verify:" not in result.stdout.str()


@pytest.mark.parametrize(("argv", "needle"), [
    (["--tli-examples", "0"], "--tli-examples: must be >= 1, got 0"),
    (["--tli-examples", "many"], "--tli-examples: expected an integer, got 'many'"),
    (["--tli-seed", "-1"], "--tli-seed: must be >= 0, got -1"),
    (["--tli-cases", "no/such/dir"], "no such directory"),
])
def test_bad_plugin_options_are_usage_errors(argv: list[str], needle: str,
                                             pytester: pytest.Pytester) -> None:
    pytester.makepyfile("def test_nothing():\n    pass\n")
    result = pytester.runpytest(*argv, "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert needle in result.stderr.str()


@pytest.fixture(scope="module")
def drawer_task(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 3-D drawer's task file (no model needed to draw its cases)."""
    return write_project(tmp_path_factory.mktemp("drawer")) / "tasks" / "drawer.toml"


def test_cases_of_a_task_follow_its_defaults_in_any_dimension(drawer_task: Path) -> None:
    """A task file alone: its nominal start, window, push count and magnitude bound."""
    from tli_verify.tasks.registry import find_task

    task = find_task(drawer_task)
    seen: list[Case] = []

    @settings(max_examples=30, database=None, derandomize=True)
    @given(cases(drawer_task))
    def draw(case: Case) -> None:
        seen.append(case)
        assert case.start == task.starts.nominal[0]
        assert len(case.pushes) <= task.perturbations.max_pushes
        steps = [p.step for p in case.pushes]
        assert steps == sorted(set(steps)) and all(1 <= s <= task.perturbations.window
                                                   for s in steps)
        for p in case.pushes:
            assert len(p.displacement) == 3
            assert p.magnitude <= task.perturbations.max_magnitude + 1e-9
            assert (p.target is not None) == (p.level == "task")

    draw()
    assert any(c.pushes for c in seen)


@pytest.mark.parametrize(("options", "needle"), [
    ({"max_pushes": 101}, "max_pushes: expected an integer in [0, 100]"),
    ({"window": 0}, "window: expected an integer in [1, 100000]"),
    ({"max_pushes": 1, "min_pushes": 2}, "min_pushes: expected an integer in [0, 1]"),
    ({"levels": ("shove",)}, "levels: expected a non-empty subset of free, motion, task"),
    ({"start": (0.1, 0.2)}, "start: expected 3 coordinates"),
    ({"start": (0.1, 0.2, 7.0)}, "outside the workspace"),
    ({"start": (0.1, 0.2, 0.3), "random_starts": True}, "choose one"),
    ({"max_magnitude": float("nan")}, "max_magnitude: expected a finite number"),
])
def test_bad_strategy_options_are_value_errors(options: dict[str, object], needle: str,
                                               drawer_task: Path) -> None:
    with pytest.raises(ValueError, match=r"^cases: ") as err:
        cases(drawer_task, **options)  # type: ignore[arg-type]
    assert needle in str(err.value)


def test_cases_of_something_else_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="expected a Project, a task"):
        cases(42)


# ------------------------------------------------------------------------------ JUnit XML
def _result():  # type: ignore[no-untyped-def]
    """A campaign of three runs: satisfied, violating (its counterexample), undecided."""
    from tli_verify.verify.campaign import CampaignResult
    from tli_verify.verify.config import CampaignConfig
    from tli_verify.verify.oracle import Verdict, Violation, ViolationKind
    from tli_verify.verify.simulate import RunOutcome

    def verdict(violations: tuple[Violation, ...] = (), *, conclusive: bool = True
                ) -> Verdict:
        return Verdict(violations=violations, reached=conclusive and not violations,
                       goal_step=9 if conclusive else None, deadline_step=50,
                       conclusive=conclusive, assumptions_ok=True, cycles=0, failures=0,
                       robustness=0.5, oracle_modes="abab")

    bad = Violation(ViolationKind.LOOPING, 40, "the modes cycle\x01 5 times <&>")
    outcomes = (RunOutcome(0, verdict(), 9, 0, "ab"), RunOutcome(1, verdict((bad,)), 60, 0,
                                                                   "abab"),
                RunOutcome(2, verdict(conclusive=False), 20, 0, "a"))
    return CampaignResult(
        config=CampaignConfig(examples=3, seed=4, modulation=False, max_pushes=1, window=9),
        runs=3, violations={"looping": 1}, task_satisfied=1, cuts_added=0, coverage={},
        counterexample={"index": 1, "shrunk": True}, first_counterexample_at=2,
        failure_bound=None, partial=False, outcomes=outcomes, seconds=1.5, inconclusive=1,
        files={"model": {"path": "models/m.json", "sha256": "ab" * 32}}, task_name="scoop")


def test_junit_xml_of_a_campaign(tmp_path: Path) -> None:
    from tli_verify.testing.junit import write_junit

    path = write_junit(_result(), tmp_path / "ci" / "campaign.xml",
                       counterexample="out/verify/counterexample.json")
    assert [p.name for p in path.parent.iterdir()] == ["campaign.xml"]
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    (suite,) = root.findall("testsuite")
    assert {k: suite.get(k) for k in ("tests", "failures", "errors", "skipped")} == {
        "tests": "3", "failures": "1", "errors": "0", "skipped": "1"}
    assert suite.get("name") == "tli verify: scoop (no modulation, seed 4)"
    props = {p.get("name"): p.get("value") for p in suite.iter("property")}
    assert props["seed"] == "4" and props["model.sha256"] == "ab" * 32
    assert props["counterexample"] == "out/verify/counterexample.json"
    runs = suite.findall("testcase")
    assert [c.get("name") for c in runs] == ["run 1", "run 2", "run 3"]
    assert runs[0].find("failure") is None and runs[0].find("skipped") is None
    failure = runs[1].find("failure")
    assert failure is not None and failure.get("type") == "looping"
    assert failure.get("message") == "the modes cycle 5 times <&>"  # control chars dropped
    assert "tli replay out/verify/counterexample.json" in (failure.text or "")
    skipped = runs[2].find("skipped")
    assert skipped is not None and "undecided" in (skipped.get("message") or "")


def test_ini_settings_in_pyproject(pytester: pytest.Pytester) -> None:
    """The settings a project puts under ``[tool.pytest.ini_options]`` (paths relative to
    it), shown in the report header."""
    (pytester.path / "regressions").mkdir()
    pytester.makepyprojecttoml('''
        [tool.pytest.ini_options]
        tli_cases = ["regressions"]
        tli_examples = "7"
        tli_case_dir = "saved"
        ''')
    pytester.makepyfile("def test_nothing():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    result.stdout.fnmatch_lines([f"tli-verify: examples 7; cases {pytester.path / 'regressions'};"
                                 f" case dir {pytester.path / 'saved'}"])


def test_case_dirs_outside_the_collected_paths_are_collected_too(
        pytester: pytest.Pytester) -> None:
    (pytester.path / "tests").mkdir()
    (pytester.path / "tests" / "test_a.py").write_text("def test_a():\n    pass\n")
    (pytester.path / "cases").mkdir()
    (pytester.path / "cases" / "one.json").write_text("{}")
    (pytester.path / "cases" / "notes.txt").write_text("not a case")
    result = pytester.runpytest("tests", "--tli-cases", "cases", "--collect-only", "-q",
                                "-p", "no:cacheprovider")
    result.stdout.fnmatch_lines(["tests/test_a.py::test_a", "cases/one.json::replay",
                                 "2 tests collected*"])
