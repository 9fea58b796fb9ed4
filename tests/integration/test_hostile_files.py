"""Issue 31, classes 2 and 4: the gate trusts nothing it did not check, and bad input in task
files, formulas, foreign specs, paths and plug-ins is exit 2 with one line -- never exit 0
with no output (a plug-in's ``SystemExit``), never exit 70 (an ``OverflowError``, a
``RecursionError``, ``ENAMETOOLONG``).

The cases are drawn from each class: hypothesis draws huge integers and out-of-range floats for
every numeric field of a task file, chain lengths and operators for formulas, nesting for
Spectra and slugs files, and forged campaign settings; the plug-in cases are the product of
where a plug-in fails (import, build, ``read``, ``initial_latent``, its names) and how
(``SystemExit(0)``, ``SystemExit(3)``, an exception, a reading of the wrong shape or type).
"""

from __future__ import annotations

import importlib
import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.cli import run
from tli_verify.errors import InputError, TaskError

REPO = Path(__file__).resolve().parents[2]
SCOOP = (REPO / "tasks" / "scoop.toml").read_text()
HYP = settings(max_examples=40, deadline=None, derandomize=True,
               suppress_health_check=list(HealthCheck))


def _one_error_line(err: str) -> str:
    assert err.startswith("error: ") and err.count("\n") == 1, err
    return err


# ------------------------------------------------------------------ class 4: task-file numbers
NUMERIC_FIELDS = {  # (the text in tasks/scoop.toml, a replacement template, the field named)
    "lag": ("lag = 0 ", "lag = {v} ", "lag"),
    "dt": ("dt = 0.01 ", "dt = {v} ", "dt"),
    "state.lower": ("lower = [-8.0, -8.0]", "lower = [{v}, -8.0]", "state.lower"),
    "state.upper": ("upper = [8.0, 8.0]", "upper = [8.0, {v}]", "state.upper"),
    "box side": ("lower = [2.0, -inf], upper = [6.0, 6.0]",
                 "lower = [2.0, -inf], upper = [{v}, 6.0]", "regions.pink"),
    "window": ("window = 700", "window = {v}", "window"),
    "max_magnitude": ("max_magnitude = 16.0", "max_magnitude = {v}", "max_magnitude"),
    "nominal start": ("nominal = [[-5.0, 4.5]]", "nominal = [[{v}, 4.5]]", "nominal"),
}


def _huge_numbers() -> st.SearchStrategy[str]:
    return st.one_of(
        st.integers(309, 4000).map(lambda k: "1" + "0" * k),  # an int beyond a double
        st.integers(309, 4000).map(lambda k: "-9" + "9" * k),
        st.sampled_from(["1e308", "-1e308", "1.7976931348623157e308", "9e307"]),
        st.integers(7, 300).map(lambda k: f"1e{k}"))  # finite, beyond MAX_ABS_VALUE or limits


@HYP
@given(field=st.sampled_from(sorted(NUMERIC_FIELDS)), value=_huge_numbers())
def test_a_huge_number_in_a_task_file_is_refused_naming_the_field(
        tmp_path_factory: pytest.TempPathFactory, field: str, value: str) -> None:
    old, template, named = NUMERIC_FIELDS[field]
    assert old in SCOOP
    text = SCOOP.replace(old, template.format(v=value), 1)
    path = tmp_path_factory.mktemp("num") / "t.toml"
    path.write_text(text)
    from tli_verify.tasks.taskfile import load_task

    with pytest.raises(TaskError) as info:
        load_task(path)
    assert named in str(info.value), (field, value, str(info.value))


def test_every_command_that_reads_a_task_refuses_a_huge_integer(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``task check``, ``demos``, ``run``, ``verify`` and the gate: exit 2 (the gate: 1,
    blocked), one line naming the field; before, an OverflowError (exit 70)."""
    root = tmp_path / "p"
    for rel in ("specs/scoop.toml", "models/scoop.model.json", "certificates/scoop.cert.json",
                "certificates/scoop.campaign.json"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, root / rel)
    (root / "tasks").mkdir()
    task = root / "tasks" / "scoop.toml"
    task.write_text(SCOOP.replace("lag = 0 ", "lag = 1" + "0" * 400 + " ", 1))
    model = str(root / "models" / "scoop.model.json")
    for argv in (["task", "check", str(task)], ["demos", str(task), "--out", str(tmp_path)],
                 ["run", "--model", model, "--steps", "5", "--out", str(tmp_path / "o")],
                 ["verify", "--model", model, "--examples", "2", "--out", str(tmp_path / "v")]):
        code, _, err = run(capsys, *argv)
        assert code == 2, (argv, code, err)
        assert "lag" in _one_error_line(err), argv
    code, out, err = run(capsys, "gate", str(root))
    assert code == 1 and "lag" in out and "internal error" not in err, (code, out, err)


def test_a_start_region_outside_the_workspace_is_refused_at_load(tmp_path: Path) -> None:
    from tli_verify.tasks.taskfile import load_task

    text = SCOOP.replace("[starts]\n", "[regions.far]\nbox = { lower = [20.0, 20.0], upper = "
                         "[30.0, 30.0] }\n\n[starts]\nregion = \"far\"\n", 1)
    path = tmp_path / "t.toml"
    path.write_text(text)
    with pytest.raises(TaskError, match=r"starts\.region: region 'far' lies outside"):
        load_task(path)


# ------------------------------------------------------------------ class 4: formula depth
@HYP
@given(op=st.sampled_from(["&", "|", "^", "<->", "->", "!", "("]),
       n=st.integers(1, 2400))
def test_a_task_formula_loads_and_evaluates_or_is_refused_at_load(
        tmp_path_factory: pytest.TempPathFactory, op: str, n: int) -> None:
    """One depth limit (MAX_FORMULA_DEPTH), checked at load: a formula that loads is
    evaluated without recursion trouble (chains of ``&``, ``|``, ``^``, ``<->`` are loops)."""
    if op == "!":
        formula = "!" * n + "yellow"
    elif op == "(":
        formula = "(" * n + "yellow" + ")" * n
    else:
        formula = f" {op} ".join(["yellow"] * (n + 1))
    text = SCOOP.replace('r = "yellow & !delivered"', f'r = "{formula}"', 1)
    path = tmp_path_factory.mktemp("f") / "t.toml"
    path.write_text(text)
    from tli_verify.tasks.taskfile import load_task

    try:
        task = load_task(path)
    except TaskError as exc:
        assert "MAX_FORMULA_DEPTH" in str(exc) or "longer than" in str(exc) or \
            "operators and names" in str(exc), str(exc)
        assert len(str(exc)) < 400
        return
    X = np.array([[0.0, -6.0], [0.0, 0.0]])
    readings = task.sensors(X)
    assert readings.shape == (2, 3)


FOREIGN = {
    "spectra-parens": ("x.spectra", lambda n: "module M\nenv boolean a;\nsys boolean b;\n"
                       "gar G " + "(" * n + "b" + ")" * n + ";\n"),
    "spectra-not": ("x.spectra", lambda n: "module M\nenv boolean a;\nsys boolean b;\n"
                    "gar G " + "!" * n + "b;\n"),
    "spectra-and": ("x.spectra", lambda n: "module M\nenv boolean a;\nsys boolean b;\n"
                    "gar G " + " & ".join(["b"] * n) + ";\n"),
    "spectra-implies": ("x.spectra", lambda n: "module M\nenv boolean a;\nsys boolean b;\n"
                        "gar G " + " -> ".join(["b"] * n) + ";\n"),
    "slugsin-not": ("x.slugsin", lambda n: "[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n"
                    + "! " * n + "b\n"),
    "slugsin-xor": ("x.slugsin", lambda n: "[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n"
                    + "^ b " * n + "b\n"),
    "slugsin-and": ("x.slugsin", lambda n: "[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n"
                    + "& b " * n + "b\n"),
    "structuredslugs-parens": ("x.structuredslugs", lambda n: "[INPUT]\na\n[OUTPUT]\nb\n"
                               "[SYS_TRANS]\n" + "(" * n + "b" + ")" * n + "\n"),
    "structuredslugs-not": ("x.structuredslugs", lambda n: "[INPUT]\na\n[OUTPUT]\nb\n"
                            "[SYS_TRANS]\n" + "!" * n + "b\n"),
}


@HYP
@given(kind=st.sampled_from(sorted(FOREIGN)), n=st.integers(1, 6000))
def test_a_deep_foreign_spec_imports_or_is_refused_in_one_line(
        tmp_path_factory: pytest.TempPathFactory, kind: str, n: int) -> None:
    """Spectra, structured slugs and slugsin: exit 0 or 2, never a RecursionError (70)."""
    from tli_verify.errors import SpecError
    from tli_verify.logic.foreign import import_spec_file

    name, make = FOREIGN[kind]
    path = tmp_path_factory.mktemp("s") / name
    path.write_text(make(n))
    try:
        import_spec_file(path)
    except SpecError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 400, str(exc)[:400]


# ------------------------------------------------------------------ class 4: long path names
LONG = "x" * 300


@pytest.mark.parametrize("argv", [
    ["task", "check", "{tmp}/" + LONG + ".toml"],
    ["init", "{tmp}/" + LONG],
    ["demos", "scoop", "--out", "{tmp}/" + LONG],
    ["task", "list", "--project", "{tmp}/" + LONG],
    ["evidence", "{tmp}/" + LONG],
    ["learn", "{tmp}/" + LONG + ".csv", "-o", "{tmp}/m.json"],
    ["certify", "models/scoop.model.json", "-o", "{tmp}/" + LONG + ".json"],
    ["spec", "import", "{tmp}/" + LONG + ".spectra", "-o", "{tmp}/s.toml"],
    ["gate", "{tmp}/" + LONG],
])
def test_a_path_component_over_255_bytes_is_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, _, err = run(capsys, *argv)
    assert code == 2, (argv[:2], code, err)
    assert "255" in _one_error_line(err) or "too long" in err, err
    assert list(tmp_path.iterdir()) == []


def test_init_refuses_an_empty_directory_name(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "init", "")
    assert code == 2 and "empty path" in err, err
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ class 2: plug-ins
PLUGIN = '''\
import numpy as np
MODE = {mode!r}
class Sensors:
    latent_names = ()
    cell_based = False
    @property
    def sensor_names(self):
        if MODE == "names-exit":
            raise SystemExit(0)
        if MODE == "names-dup":
            return ("r", "r", "t")
        return ("r", "s", "t")
    def initial_latent(self, batch):
        if MODE == "latent-exit":
            raise SystemExit(0)
        if MODE == "latent-shape":
            return np.zeros((batch, 2), dtype=bool)
        return np.zeros((batch, 0), dtype=bool)
    def read(self, x_prev, x, latent):
        b = len(x)
        if MODE == "read-exit0":
            raise SystemExit(0)
        if MODE == "read-exit3":
            raise SystemExit(3)
        if MODE == "read-error":
            raise RuntimeError("sensor offline")
        if MODE == "read-columns":
            return np.zeros((b, 2), dtype=bool), latent
        if MODE == "read-batch":
            return np.zeros((b + 1, 3), dtype=bool), latent
        if MODE == "read-float":
            return np.full((b, 3), 0.5), latent
        if MODE == "read-none":
            return None
        if MODE == "read-triple":
            return np.zeros((b, 3), dtype=bool), latent, latent
        return np.zeros((b, 3), dtype=bool), latent
def sensors(*, dim, partition):
    if MODE == "build-exit":
        raise SystemExit(0)
    if MODE == "build-error":
        raise ValueError("no calibration")
    if MODE == "build-none":
        return None
    return Sensors()
if MODE == "load-exit":
    raise SystemExit(0)
if MODE == "load-error":
    raise ImportError("missing driver")
'''
AT_LOAD = ["load-exit", "load-error", "build-exit", "build-error", "build-none", "names-exit",
           "names-dup"]
AT_READ = ["latent-exit", "latent-shape", "read-exit0", "read-exit3", "read-error",
           "read-columns", "read-batch", "read-float", "read-none", "read-triple"]


@pytest.fixture(scope="module")
def plugins(tmp_path_factory: pytest.TempPathFactory) -> Path:
    site = tmp_path_factory.mktemp("site")
    info = site / "hostile31-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hostile31\nVersion: 1.0\n")
    lines = ["[tli_verify.tasks]"]
    for mode in [*AT_LOAD, *AT_READ, "good"]:
        mod = "h31_" + mode.replace("-", "_")
        (site / f"{mod}.py").write_text(PLUGIN.format(mode=mode))
        lines.append(f"h31-{mode} = {mod}:sensors")
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return site


def _plugin_task(root: Path, mode: str) -> Path:
    start, end = SCOOP.index("[regions.pink]"), SCOOP.index("[starts]")
    text = SCOOP[:start] + SCOOP[end:SCOOP.index("[demonstrator]")]
    text = text.replace("[state]", f'sensor_model = "h31-{mode}"\n\n[state]', 1)
    path = root / "tasks" / "scoop.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.fixture
def on_path(plugins: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    monkeypatch.syspath_prepend(str(plugins))
    importlib.invalidate_caches()
    yield plugins
    for name in [m for m in sys.modules if m.startswith("h31_")]:
        sys.modules.pop(name, None)


@pytest.mark.parametrize("mode", AT_LOAD)
def test_a_plugin_failing_at_load_is_one_line_naming_it(
        on_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], mode: str) -> None:
    """``tli task check`` (before: exit 0 and no output for a SystemExit(0))."""
    task = _plugin_task(tmp_path, mode)
    code, _, err = run(capsys, "task", "check", str(task))
    assert code == 2, (mode, code, err)
    line = _one_error_line(err)
    assert f"h31-{mode}" in line and str(task) in line, line


@pytest.mark.parametrize("mode", AT_READ)
def test_a_plugin_failing_when_read_is_a_task_error_naming_it(
        on_path: Path, tmp_path: Path, mode: str) -> None:
    from tli_verify.tasks.taskfile import load_task

    task = load_task(_plugin_task(tmp_path, mode))
    with pytest.raises(TaskError) as info:
        task.sensors(np.zeros((4, 2)))
    assert f"h31-{mode}" in str(info.value) and "scoop.toml" in str(info.value)
    assert isinstance(info.value, InputError)


@pytest.mark.parametrize("mode", ["read-exit0", "read-error", "read-columns", "latent-exit"])
def test_the_gate_blocks_on_a_plugin_failing_in_its_rerun(
        on_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], mode: str) -> None:
    """Evidence bound to the plug-in task: the gate's re-run reads the sensors, the plug-in
    fails, the gate blocks naming it (before: ``SystemExit(0)`` made ``tli gate`` exit 0 with
    no output)."""
    from tests.support.evidence import attach_evidence

    for rel in ("specs/scoop.toml", "models/scoop.model.json",
                "certificates/scoop.cert.json"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, tmp_path / rel)
    _plugin_task(tmp_path, mode)
    attach_evidence(tmp_path)
    code, out, err = run(capsys, "gate", str(tmp_path), "--rerun", "2", "--json")
    assert code == 1, (code, out, err)
    blocked = [json.loads(line) for line in out.splitlines()
               if line.startswith("{") and '"ok": false' in line]
    assert any(f"h31-{mode}" in b["message"] and b["check"] == "rerun" for b in blocked), out
    assert "internal error" not in err


# ------------------------------------------------------------------ class 2: forged settings
def _scoop_settings() -> dict[str, Any]:
    doc = json.loads((REPO / "certificates" / "scoop.campaign.json").read_text())
    return dict(doc["campaign"]["settings"])


def test_the_settings_the_cli_records_pass() -> None:
    from tli_verify.tasks.registry import find_task
    from tli_verify.verify.evidence import settings_problems

    for name, task in (("scoop", "scoop"), ("color-tracing-a", "color-tracing"),
                       ("inspection", "inspection")):
        doc = json.loads((REPO / "certificates" / f"{name}.campaign.json").read_text())
        assert settings_problems(doc["campaign"]["settings"], find_task(task)) == [], name


FORGERIES = st.one_of(
    st.tuples(st.floats(-8, 8), st.floats(-8, 8)).filter(lambda p: list(p) != [-5.0, 4.5])
    .map(lambda p: {"start": list(p)}),
    st.tuples(st.floats(-8, 8), st.floats(-8, 8)).map(
        lambda p: {"start": list(p), "random_starts": True}),
    st.lists(st.sampled_from(["free", "motion", "task"]), max_size=2, unique=True)
    .map(lambda v: {"levels": v}),
    st.integers(1, 50).map(lambda v: {"max_cycles": v}),
    st.integers(1, 10**6).map(lambda v: {"lag": v}),
    st.sampled_from([0, -1, 10**9, True, "100"]).map(lambda v: {"batch_size": v}),
    st.sampled_from([-1, 101, 2.5, None]).map(lambda v: {"max_pushes": v}),
    st.sampled_from(["yes", 1, None]).map(lambda v: {"random_starts": v}),
    st.text(min_size=1, max_size=8).filter(
        lambda k: k not in _scoop_settings()).map(lambda k: {k: 1}),
)


@HYP
@given(edit=FORGERIES)
def test_settings_no_cli_command_could_record_are_refused(edit: dict[str, Any]) -> None:
    from tli_verify.tasks.registry import find_task
    from tli_verify.verify.evidence import settings_problems

    forged = {**_scoop_settings(), **edit}
    assert settings_problems(forged, find_task("scoop")), edit


def test_the_gate_blocks_evidence_with_a_start_no_cli_option_records(project: Path) -> None:
    """The issue's forgery: a consistent digest and a recorded start from which the campaign
    happens to work. The gate refuses the settings, and its re-run never uses them."""
    from tests.support.evidence import attach_evidence
    from tli_verify.deploy.gate import run_gate

    attach_evidence(project, settings={"window": 700, "max_pushes": 3, "batch_size": 100,
                                       "random_starts": False, "start": [4.0, 7.0]})
    report = run_gate(project, rerun=0)
    assert not report.ok
    assert any("not the task's first nominal start" in b.message for b in report.blockers)


@HYP
@given(nominal=st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8)), max_size=4),
       examples=st.integers(1, 10_000), seed=st.integers(0, 2**32 - 10_001))
def test_the_gates_rerun_draws_its_own_starts(nominal: list[tuple[float, float]],
                                              examples: int, seed: int) -> None:
    """Half the re-run (rounded up) starts in the task's start region, the rest on its nominal
    starts; the counts add up; every part has a seed of its own below 2^32."""
    from tli_verify.deploy.gate import rerun_starts

    plan = rerun_starts(nominal, examples, seed)
    assert sum(c for _, c, _ in plan) == examples
    assert plan[0][0] is None and plan[0][1] >= (examples + 1) // 2
    assert all(s is None or s in [tuple(p) for p in nominal] for s, _, _ in plan)
    assert all(0 <= sd and sd + c <= 2**32 for _, c, sd in plan)
    if nominal and examples >= 2 * len(nominal):
        assert {s for s, _, _ in plan[1:]} == {tuple(p) for p in nominal}


# ------------------------------------------------------------------ class 3: unbounded work
def _memory_doubling(n: int) -> str:
    """A slugsin formula whose memory cells double ``n`` times (2^n nodes written out)."""
    cells = " ".join(f"& ? {i} ? {i}" for i in range(n))
    return f"[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n$ {n + 1} b {cells}\n"


BOMBS = {
    "slugsin memory doubling 40x": ("x.slugsin", _memory_doubling(40), "MAX_FORMULA_NODES"),
    "slugsin memory doubling 25x": ("x.slugsin", _memory_doubling(25), "MAX_FORMULA_NODES"),
    "spectra boolean[4096][4096]": ("x.spectra", "module M\nenv boolean a;\n"
                                    "sys boolean[4096][4096] b;\ngar G b[0][0];\n",
                                    "MAX_IMPORT_CELLS"),
    "spectra Int[64][64][64]": ("x.spectra", "module M\nenv boolean a;\n"
                                "sys Int(0..3)[64][64][64] b;\ngar G b[0][0][0] = 1;\n",
                                "MAX_IMPORT_CELLS"),
    "spectra forall over 10^6": ("x.spectra", "module M\nenv boolean a;\n"
                                 "sys Int(0..1000000) b;\n"
                                 "gar G forall i in Int(0..1000000). b != i | a;\n",
                                 "MAX_IMPORT_CELLS"),
    "spectra nested forall 100x100": ("x.spectra", "module M\nenv boolean a;\n"
                                      "sys Int(0..99) b;\nsys Int(0..99) c;\n"
                                      "gar G forall i in Int(0..99). forall j in Int(0..99). "
                                      "b != i | c != j | a;\n", "MAX_IMPORT_CELLS"),
}


@pytest.mark.parametrize("case", sorted(BOMBS))
def test_spec_import_refuses_a_bomb_before_the_work(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str) -> None:
    """A few hundred bytes that ask for 2^40 nodes, 16M variables or 10^6 copies: exit 2 at
    once (before: killed at 60 s / 3 GB), naming the limit; nothing written."""
    import time

    name, text, limit = BOMBS[case]
    src = tmp_path / name
    src.write_text(text)
    out = tmp_path / "out.toml"
    t0 = time.perf_counter()
    code, _, err = run(capsys, "spec", "import", str(src), "-o", str(out))
    assert code == 2, (case, code, err[:300])
    assert limit in _one_error_line(err) and len(err) < 500 and str(src) in err
    assert time.perf_counter() - t0 < 10
    assert not out.exists()


def test_spec_import_never_writes_what_no_reader_accepts(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The translation is held to MAX_INPUT_BYTES before it is written, and the error names
    the input, in one short line (before: a 10 MB TOML no command could read back)."""
    gar = "gar G forall i in Int(0..4095). b != i | a;\n"
    src = tmp_path / "big.spectra"
    src.write_text("module M\nenv boolean a;\nsys Int(0..4095) b;\n" + gar * 12)
    assert src.stat().st_size < 1000
    out = tmp_path / "out.toml"
    code, _, err = run(capsys, "spec", "import", str(src), "-o", str(out))
    assert code == 2, (code, err[:300])
    assert "MAX_INPUT_BYTES" in _one_error_line(err) and str(src) in err and len(err) < 500
    assert not out.exists()


@pytest.mark.parametrize(("where", "edit"), [
    ("a script's duration", ('label = "scoop"', 'label = "scoop"\nduration = 10000.0')),
    ("the default duration", ("duration = 12.0", "duration = 10000.0")),
    ("dt", ("dt = 0.05\n", "dt = 0.0001\n")),
])
def test_demos_and_learn_agree_on_the_sample_limit(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str,
        edit: tuple[str, str]) -> None:
    """A demonstrator asking for more samples than ``tli learn`` reads is refused when the
    task loads (before: a per-script duration skipped the check, 10^8 samples, MemoryError)."""
    old, new = edit
    assert old in SCOOP
    task = tmp_path / "t.toml"
    task.write_text(SCOOP.replace(old, new, 1).replace('spec = "../specs/scoop.toml"\n', ""))
    code, _, err = run(capsys, "demos", str(task), "--out", str(tmp_path / "d"))
    assert code == 2, (where, code, err)
    assert "MAX_DEMO_SAMPLES" in _one_error_line(err)
    assert not (tmp_path / "d").exists()


def test_learn_refuses_more_rows_than_demos_may_write(tmp_path: Path) -> None:
    from tli_verify.demos import load_demo
    from tli_verify.errors import DemoError
    from tli_verify.limits import MAX_DEMO_SAMPLES

    rows = "\n".join(f"{i},0,0" for i in range(MAX_DEMO_SAMPLES + 1))
    path = tmp_path / "d.csv"
    path.write_text("t,x0,x1\n" + rows + "\n")
    with pytest.raises(DemoError, match="MAX_DEMO_SAMPLES"):
        load_demo(path)


# ------------------------------------------------------------------ class 6: messages
@pytest.mark.parametrize("shape", [
    "ellipsoid = { center = [0.0, 0.0], matrix = [[1e308, 0.0], [0.0, 1e308]] }",
    "ball = { center = [1e308, 0.0], radius = 1.0 }",
    "polytope = { A = [[1e308, 0.0], [-1e308, 0.0]], b = [1.0, 1.0] }",
    "box = { lower = [-1e308, 0.0], upper = [1e308, 1.0] }",
])
def test_huge_shapes_give_one_error_line_and_no_numpy_warning(tmp_path: Path,
                                                              shape: str) -> None:
    """A real process: stderr is exactly one ``error:`` line (before: numpy RuntimeWarnings
    first, then a misleading "not positive definite (smallest eigenvalue nan)")."""
    import subprocess

    path = tmp_path / "t.toml"
    path.write_text('name = "huge"\n[state]\nlower = [-2.0, -2.0]\nupper = [2.0, 2.0]\n'
                    f'[regions.p]\n{shape}\n[sensors]\np = "p"\n')
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", "task", "check", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "regions.p" in _one_error_line(proc.stderr) and "Warning" not in proc.stderr


def test_the_gates_rerun_never_starts_where_the_evidence_says(tmp_path: Path) -> None:
    """The re-run ignores the recorded start: one no task could hold (outside the workspace)
    changes nothing -- the gate's own starts are used (before: the re-run started there and
    failed, or, with a start chosen to work, trusted it)."""
    import dataclasses

    from tli_verify.deploy.gate import rerun_campaign
    from tli_verify.verify.evidence import check_evidence

    for rel in ("tasks/scoop.toml", "specs/scoop.toml", "models/scoop.model.json",
                "certificates/scoop.cert.json", "certificates/scoop.campaign.json"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, tmp_path / rel)
    model = tmp_path / "models" / "scoop.model.json"
    check = check_evidence(tmp_path / "certificates" / "scoop.campaign.json", model_path=model)
    assert check.ok, check.problems
    forged = {**dict(check.settings), "start": [100.0, 100.0], "random_starts": False}
    check = dataclasses.replace(check, settings=tuple(sorted(forged.items())))
    ok, message = rerun_campaign(check, model, 4)
    assert ok, message
    assert "its own starts (2 from starts drawn in the task's start region, 2 from its 1 " \
        "nominal start(s)" in message


@pytest.mark.parametrize("mode", AT_READ)
def test_task_check_reads_a_plugin_once_and_names_it(
        on_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], mode: str) -> None:
    """``tli task check`` calls the plug-in's ``read()`` once on a sample state: a reading of
    the wrong shape or type, an exception, ``SystemExit(0)`` or ``SystemExit(3)`` is exit 2 and
    one line naming the plug-in and the task file (before: ``task check`` passed, and the
    failure came later, in ``tli run``, ``tli verify`` or the gate)."""
    task = _plugin_task(tmp_path, mode)
    code, out, err = run(capsys, "task", "check", str(task))
    assert code == 2, (mode, code, out, err)
    line = _one_error_line(err)
    assert f"h31-{mode}" in line and str(task) in line, line
    assert out == ""


def test_task_check_passes_a_plugin_that_reads_well(
        on_path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = _plugin_task(tmp_path, "good")
    code, out, err = run(capsys, "task", "check", str(task))
    assert code == 0 and err == "" and "sensors r, s, t" in out, (code, out, err)


@HYP
@given(lo=st.tuples(st.floats(-9e4, 9e4), st.floats(-9e4, 9e4)),
       side=st.tuples(st.floats(1.0, 1e4), st.floats(1.0, 1e4)),
       scales=st.lists(st.sampled_from([1e-12, 1e-10, 1e-6, 1.0, 1e3, 1e5]), min_size=4,
                       max_size=4),
       empty=st.booleans())
def test_a_polytope_is_called_empty_only_when_it_is(
        tmp_path_factory: pytest.TempPathFactory, lo: tuple[float, float],
        side: tuple[float, float], scales: list[float], empty: bool) -> None:
    """A box written as ``A x <= b`` with each row scaled (tiny or large coefficients, the
    same set): non-empty polytopes load, empty ones (upper below lower) are "empty" (before:
    rows of 1e-10 with b beyond the LP's tolerance were called empty)."""
    from tli_verify.tasks.taskfile import load_task

    hi = (lo[0] + side[0], lo[1] + side[1])
    if empty:
        lo, hi = (hi[0], lo[1]), (lo[0], hi[1])  # x0 >= hi0 > lo0 >= x0: nothing
    rows = [([1.0, 0.0], hi[0]), ([-1.0, 0.0], -lo[0]), ([0.0, 1.0], hi[1]),
            ([0.0, -1.0], -lo[1])]
    A = [[s * a for a in row] for s, (row, _) in zip(scales, rows, strict=True)]
    b = [s * v for s, (_, v) in zip(scales, rows, strict=True)]
    path = tmp_path_factory.mktemp("poly") / "t.toml"
    path.write_text('name = "poly"\n[state]\nlower = [-1e5, -1e5]\nupper = [1e5, 1e5]\n'
                    f"[regions.p]\npolytope = {{ A = {A!r}, b = {b!r} }}\n"
                    '[sensors]\np = "p"\n')
    if not empty:
        task = load_task(path)
        assert task.partition is not None
        return
    with pytest.raises(TaskError) as info:
        load_task(path)
    assert "empty polytope" in str(info.value) or "cannot decide" in str(info.value), \
        str(info.value)


def test_spec_import_error_lines_are_bounded_and_name_the_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 3 MB identifier quoted by the importer: one line of at most MAX_MESSAGE_CHARS (+
    ``error: ``) that starts with the input file and says why at its end (before: a 3 MB
    line; with the translation refused, a 12 MB line naming the output file)."""
    from tli_verify.errors import MAX_MESSAGE_CHARS

    src = tmp_path / "long.spectra"
    src.write_text("module M\nenv boolean a;\nsys boolean b;\ngar G " + "q" * 3_000_000
                   + ";\n")
    out = tmp_path / "out.toml"
    code, _, err = run(capsys, "spec", "import", str(src), "-o", str(out))
    assert code == 2
    line = _one_error_line(err)
    assert len(line) <= MAX_MESSAGE_CHARS + len("error: \n"), len(line)
    assert line.startswith(f"error: {src}:4: unknown identifier")
    assert "characters cut" in line and str(out) not in line
    assert not out.exists()


@HYP
@given(head=st.text(min_size=1, max_size=60), middle=st.text(max_size=5000),
       tail=st.text(min_size=1, max_size=60))
def test_every_error_message_is_one_bounded_line(head: str, middle: str, tail: str) -> None:
    """Any TliError: one line, at most MAX_MESSAGE_CHARS, its start (the file) and end (the
    reason) kept when its middle is cut."""
    from tli_verify.errors import MAX_MESSAGE_CHARS, SpecError

    h, t = " ".join(head.split()), " ".join(tail.split())
    msg = str(SpecError(f"HEAD{h} {middle} {t}TAIL"))
    assert "\n" not in msg and len(msg) <= MAX_MESSAGE_CHARS
    assert msg.startswith("HEAD" + h[:20]) and msg.endswith(t[-20:] + "TAIL")


@HYP
@given(field=st.sampled_from(["backend", "workers"]),
       value=st.one_of(st.sampled_from(["threads", "mpi", "", "PROCESS", 0, 257, 100_000,
                                        True, 2.5]),
                       st.text(min_size=1, max_size=32).filter(
                           lambda t: t not in ("process", "dask", "serial"))))
def test_how_a_campaign_ran_is_validated_with_the_cli_choices(
        tmp_path_factory: pytest.TempPathFactory, field: str, value: Any) -> None:
    """``campaign.backend`` and ``campaign.workers`` (beyond the kinematic settings): only
    what ``--backend`` and ``--workers`` take; the digest is recomputed, so the evidence is
    otherwise consistent (before: any short string, up to 100,000 workers)."""
    from tli_verify.verify.evidence import check_evidence, evidence_digest

    root = tmp_path_factory.mktemp("ev")
    for rel in ("tasks/scoop.toml", "specs/scoop.toml", "models/scoop.model.json",
                "certificates/scoop.cert.json", "certificates/scoop.campaign.json"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, root / rel)
    path = root / "certificates" / "scoop.campaign.json"
    doc = json.loads(path.read_text())
    doc["campaign"][field] = value
    doc["digest"] = evidence_digest(doc)
    path.write_text(json.dumps(doc))
    check = check_evidence(path)
    assert not check.ok
    assert any(f"campaign.{field}" in p or "malformed" in p for p in check.problems), \
        check.problems


@HYP
@given(pushes=st.integers(0, 64), tilts=st.integers(0, 64))
def test_a_physical_campaign_records_what_tli_sim_records(pushes: int, tilts: int) -> None:
    """``physics.pushes`` / ``physics.tilts``: the CLI records 1 and 1 per perturbed trial;
    the schema admits 0..64, the gate only 1 and 1 (before: anything from 1 to 64, which its
    re-run then ran)."""
    from tli_verify.sim.physics_checks import check_physics_block

    doc = json.loads((REPO / "sim" / "franka" / "certificates" /
                      "franka-scoop.campaign.json").read_text())
    doc["physics"].update(pushes=pushes, tilts=tilts)
    problems = check_physics_block(doc, "e.json", [])
    bad = [p for p in problems if "push(es)" in p]
    assert bool(bad) == ((pushes, tilts) != (1, 1)), (pushes, tilts, problems)
