"""``tli_verify.testing`` through its pytest plugin, as a user runs it.

The user's project is a task no shipped file has (the 3-D drawer of ``tests/support/drawer3d``:
a ball among boxes, a latch, a goal mode that is not a sink), with demonstrations, a model and
a certificate made by the CLI. The user's property test (:data:`USER_TEST`, the example of
``docs/howto/property-tests.md``) is a dozen lines run by pytest in a new process, where the
plugin comes from its ``pytest11`` entry point: the ``tli_project`` fixture, ``--tli-examples``
and ``--tli-seed``. Then a real violation (the no-modulation ablation of a copy of the scoop
project, paper Fig. 7): the failure shows the shrunk case and its ``tli replay`` command, the
saved case file validates and ``tli replay`` reproduces it, ``--tli-cases`` replays it as a test
(and fails a stale or fixed-but-open copy), and ``pytest --junitxml`` shows it to CI. Finally
the assertion's one promise that ``verdict.ok`` does not keep: an undecided run never passes.
"""

from __future__ import annotations

import json
import re
import shutil
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest

from tests.support.cli import run
from tests.support.drawer3d import write_project

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs" / "howto" / "property-tests.md"
FILES = ("tasks", "specs", "models", "certificates")

USER_TEST = '''\
from hypothesis import given

from tli_verify.testing import Case, Push, assert_satisfies, cases


@given(case=cases(max_pushes=2))
def test_the_drawer_opens_despite_pushes(tli_project, case):
    assert_satisfies(tli_project, case)


def test_pushed_back_out_of_the_slide(tli_project):
    case = Case((0.2, 0.5, 0.8), (Push(300, (-0.3, 0.0, 0.2)),))
    assert_satisfies(tli_project, case)
'''
"""The user's property test: ``PROJECT/tests/test_drawer.py`` (the docs' example)."""

QUIET = ("-p", "no:cacheprovider", "-W", "error",
         "-W", "ignore:builtin type:DeprecationWarning")  # Spot's SWIG bindings on import
"""Options of the inner pytest runs. The in-process ones (``pytester.runpytest``) drop the
modules they imported when they end, and numpy cannot be imported twice: each such test loads
its project in this process first (which also makes the inner runs fast)."""


@pytest.fixture(scope="module")
def drawer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The user's certified project: task and spec written, then ``tli demos``, ``tli learn``
    and ``tli certify``, as a user runs them."""
    from tli_verify.cli import main

    root = write_project(tmp_path_factory.mktemp("drawer"))
    task, spec = root / "tasks" / "drawer.toml", root / "specs" / "drawer.toml"
    model = root / "models" / "drawer.model.json"
    assert main(["demos", str(task)]) == 0
    demos = sorted(str(p) for p in (root / "demos").glob("drawer_*.csv"))
    assert main(["learn", *demos, "--spec", str(spec), "-o", str(model)]) == 0
    assert main(["certify", str(model)]) == 0
    return root


@pytest.fixture(scope="module")
def scoop(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A user's copy of the scoop files (its task is the bundled one)."""
    root = tmp_path_factory.mktemp("scoop")
    for sub, name in (("models", "scoop.model.json"), ("certificates", "scoop.cert.json"),
                      ("specs", "scoop.toml")):
        (root / sub).mkdir()
        shutil.copy(REPO / sub / name, root / sub / name)
    return root


def _docs_example() -> str:
    blocks = re.findall(r"^```python\n(.*?)^```", DOCS.read_text(encoding="utf-8"),
                        flags=re.S | re.M)
    assert blocks, f"{DOCS}: no python block"
    return str(blocks[0])


def test_the_docs_show_this_example() -> None:
    assert _docs_example() == USER_TEST
    assert len(USER_TEST.strip().splitlines()) <= 15


def test_a_users_property_test_of_their_own_3d_task(drawer: Path,
                                                    pytester: pytest.Pytester) -> None:
    """The docs' example in the user's project folder, in a new pytest process (the plugin
    from its entry point, hypothesis's default settings): both tests pass, ``--tli-examples``
    and ``--tli-seed`` apply, and a run longer than the 200 ms default deadline is no error."""
    for sub in FILES:
        shutil.copytree(drawer / sub, pytester.path / sub)
    (pytester.path / "tests").mkdir()
    (pytester.path / "tests" / "test_drawer.py").write_text(USER_TEST)
    result = pytester.runpytest_subprocess("--tli-examples", "6", "--tli-seed", "3",
                                           "--hypothesis-show-statistics", *QUIET)
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["tli-verify: examples 6; seed 3",
                                 "*- 6 passing, 0 failing, and 0 invalid test cases*"])


def test_seed_and_examples_decide_the_cases(drawer: Path, pytester: pytest.Pytester) -> None:
    """``--tli-seed`` makes the drawn cases the seed's (the same twice, others for another
    seed), ``--tli-examples`` their number; a 3-D task gives 3-D starts and pushes."""
    from tli_verify.testing import project

    project(drawer)  # loaded once in this process, as the in-process runs below load it
    log = pytester.path / "drawn.txt"
    pytester.makepyfile(test_draw=f'''
        from hypothesis import given
        from tli_verify.testing import cases

        @given(case=cases())
        def test_draw(case):
            with open({str(log)!r}, "a") as out:
                out.write(repr(case) + "\\n")
        ''')
    runs = []
    for seed in ("7", "7", "8"):
        log.write_text("")
        result = pytester.runpytest(f"--tli-project={drawer}", "--tli-examples", "5",
                                    "--tli-seed", seed, *QUIET)
        result.assert_outcomes(passed=1)
        runs.append(log.read_text().splitlines())
    assert len(runs[0]) == 5 and runs[0] == runs[1] and runs[2] != runs[0], runs
    assert all(line.startswith("Case(start=(0.2, 0.5, 0.8), pushes=(") for line in runs[0])
    pushes = re.findall(r"displacement=\(([^)]*)\)", "".join(runs[0] + runs[2]))
    assert pushes and all(len(p.split(",")) == 3 for p in pushes)


def test_an_undecided_run_never_passes(drawer: Path, tmp_path: Path) -> None:
    """A run cut short before the certified deadline violates nothing, so ``verdict.ok``
    accepts it; :func:`assert_satisfies` does not (and saves no case: nothing to replay).
    Nor does a forged verdict that was never decided."""
    from tli_verify.testing import Case, assert_satisfies, check, project

    proj = project(drawer)
    case = Case(proj.start or ())
    short = check(proj, case, budget=200)
    assert short.ok and not short.conclusive and not short.reached  # what .ok lets through
    with pytest.raises(AssertionError, match="undecided: reachability was not decided"):
        assert_satisfies(proj, case, budget=200, case_dir=tmp_path)
    full = assert_satisfies(proj, case, case_dir=tmp_path)
    assert full.reached and full.conclusive
    forged = replace(full, conclusive=False, reached=False, goal_step=None)
    assert forged.ok
    with pytest.raises(AssertionError, match="undecided") as err:
        assert_satisfies(proj, case, verdict=forged, case_dir=tmp_path)
    assert "not saved" in str(err.value) and not list(tmp_path.iterdir())


def test_a_violation_fails_with_its_case_its_replay_and_a_saved_case(
        scoop: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A case the ablation fails (the repository's Fig. 7 regression case: it loops): the
    message names the violation, the case and the ``tli replay`` command of the case file it
    saved; the file validates against the case schema, is saved once (its name is its
    digest), and ``tli replay`` reproduces it."""
    from tli_verify.io import validate_schema
    from tli_verify.testing import assert_satisfies, check, project, replay_command
    from tli_verify.verify.strategies import case_from_json

    fig7 = json.loads((REPO / "tests" / "regressions" /
                       "scoop_fig7_looping_no_modulation.json").read_text())
    case = case_from_json(fig7, dim=2)
    ablation = project(scoop, modulation=False)
    with pytest.raises(AssertionError) as err:
        assert_satisfies(ablation, case, case_dir=tmp_path)
    message = str(err.value)
    (saved,) = tmp_path.iterdir()
    assert saved.name.startswith("scoop-no-modulation-looping-")
    assert message.startswith("tli-verify: scoop (no modulation) does not satisfy its spec")
    assert "  - looping (step " in message and f"case: {case!r}" in message
    assert f"saved: {saved}" in message and f"replay: {replay_command(saved)}" in message
    doc = json.loads(saved.read_text())
    validate_schema(doc, "case.schema.json", where=str(saved), error=AssertionError)
    assert case_from_json(doc, dim=2) == case and doc["modulation"] is False
    assert doc["expected"]["violation"] == "looping"
    with pytest.raises(AssertionError):  # the same case again: the same file
        assert_satisfies(ablation, case, case_dir=tmp_path)
    assert list(tmp_path.iterdir()) == [saved]
    code, text, err_text = run(capsys, "replay", str(saved))
    assert code == 1 and "REPRODUCED" in text, (text, err_text)
    assert check(project(scoop), case).ok  # LTL-DS answers it with a cut (paper Thm. 1-2)


def test_saved_cases_replay_as_tests_and_ci_sees_them(scoop: Path, tmp_path: Path,
                                                      pytester: pytest.Pytester) -> None:
    """``--tli-cases DIR``: a saved ablation case passes (its violation still reproduces,
    LTL-DS passes it); a copy whose model changed since and a bug report marked open that no
    longer reproduces fail, naming why; ``--junitxml`` shows them to CI."""
    from tli_verify.testing import check, project, save_case
    from tli_verify.verify.strategies import case_from_json

    fig7 = json.loads((REPO / "tests" / "regressions" /
                       "scoop_fig7_looping_no_modulation.json").read_text())
    case = case_from_json(fig7, dim=2)
    ablation = project(scoop, modulation=False)
    cases = pytester.path / "cases"
    good = save_case(ablation, case, check(ablation, case), case_dir=cases)
    stale = json.loads(good.read_text())
    stale["files"]["model"]["sha256"] = "0" * 64
    (cases / "stale.json").write_text(json.dumps(stale))
    fixed = json.loads(good.read_text())
    fixed.update(modulation=True, open="cut learning fails here")
    (cases / "fixed.json").write_text(json.dumps(fixed))
    xml = pytester.path / "report.xml"
    result = pytester.runpytest(f"--tli-cases={cases}", f"--junitxml={xml}", *QUIET)
    result.assert_outcomes(passed=1, failed=2)
    result.stdout.fnmatch_lines_random([
        "*stale.json: model: *changed since the case was saved*",
        "*fixed.json: no longer reproduces (looping): the bug is fixed, remove its 'open' "
        "note*"])
    suite = ET.parse(xml).getroot().find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("failures")) == ("3", "2")
    failed = {str(c.get("classname")): str(f.get("message")) for c in suite.iter("testcase")
              for f in c.iter("failure")}
    assert sorted(failed) == ["cases.fixed.json", "cases.stale.json"]
    assert "no longer reproduces" in failed["cases.fixed.json"]
    assert "changed since the case was saved" in failed["cases.stale.json"]


ABLATION_TEST = '''
from hypothesis import given
from tli_verify.testing import assert_satisfies, cases


@given(case=cases(max_pushes=1))
def test_the_ablation_survives_a_push(tli_project, case):
    assert_satisfies(tli_project.with_modulation(False), case)
'''


@pytest.mark.slow  # hypothesis shrinks a looping run: ~20 simulations of seconds each
def test_the_plugin_shrinks_a_violation_and_saves_it_once(
        scoop: Path, pytester: pytest.Pytester, capsys: pytest.CaptureFixture[str]) -> None:
    """The ablation's property test through the plugin fails (without modulation the scoop
    loops or leaves its modes in about one case in eight, paper Fig. 7): hypothesis shrinks
    the case, and the failure shows the shrunk case, the case file saved once (on the final
    run, not for every failing run of the shrinker) and its ``tli replay`` command; pytest's
    JUnit XML carries it."""
    from tli_verify.io import validate_schema
    from tli_verify.testing import Case, check, project
    from tli_verify.verify.strategies import case_from_json

    warm = project(scoop, modulation=False)  # in this process: loaded once, imported once
    assert check(warm, Case(warm.start or ())).ok
    pytester.makepyfile(test_ablation=ABLATION_TEST)
    cases, xml = pytester.path / "cases", pytester.path / "report.xml"
    result = pytester.runpytest(f"--tli-project={scoop}", "--tli-examples", "40",
                                "--tli-seed", "0", f"--tli-case-dir={cases}",
                                f"--junitxml={xml}", *QUIET)
    result.assert_outcomes(failed=1)
    out = result.stdout.str()
    assert "tli-verify: scoop (no modulation) does not satisfy its spec on this case:" in out
    (case_file,) = cases.iterdir()
    assert case_file.name.startswith("scoop-no-modulation-")
    assert f"saved: {case_file}" in out
    replay = re.search(r"^E?\s*replay: (tli replay \S+)$", out, flags=re.M)
    assert replay is not None and replay.group(1).endswith(case_file.name), out
    shown = re.search(r"^E?\s*case: (Case\(.*\))$", out, flags=re.M)
    assert shown is not None, out
    doc = json.loads(case_file.read_text())
    validate_schema(doc, "case.schema.json", where=str(case_file), error=AssertionError)
    assert doc["shrunk"] is True and doc["modulation"] is False
    assert repr(case_from_json(doc, dim=2)) == shown.group(1)  # the file holds the shrunk case
    assert len(doc["perturbations"]) <= 1
    code, text, _ = run(capsys, "replay", str(case_file))
    assert code == 1 and "REPRODUCED" in text
    suite = ET.parse(xml).getroot().find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("failures")) == ("1", "1")
    failure = suite.find("testcase/failure")
    assert failure is not None and "replay: tli replay" in (failure.text or "")
