"""Hostile inputs never crash the tool, never lose data and never get certified.

Every case runs the real ``tli`` command line and requires exit 2 (bad input) with ONE
``error:`` line naming the culprit -- never the internal-error exit 70, an abort, a hang, or an
overwritten input. Classes: (1) output paths, (2) outputs equal to an input, (3) resource
limits, (4) non-finite numbers, (9) ``tli demo`` from another folder, (10) clearer messages.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.support.cli import run
from tli_verify.cli import main
from tli_verify.limits import MAX_NESTING, MAX_STATE_DIM

# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------


def assert_bad_input(code: int, err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert "internal error" not in err and "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def _limit_memory() -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


def run_subprocess(args: list[str], cwd: Path, timeout: float = 60) -> subprocess.CompletedProcess:
    """``tli`` in a child with 3 GB of address space and a timeout: a hang or a memory blow-up
    (``/dev/zero`` read whole) fails the test instead of taking the machine down."""
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]),
               MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "tli_verify.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout,
                          preexec_fn=_limit_memory, check=False)


@pytest.fixture
def project(tmp_path: Path, repo: Path) -> Path:
    """A copy of the bundled scoop project: its demos, specs, model, certificate and evidence
    (the gate re-runs a sample of each model's campaign: one model keeps that cheap)."""
    for sub in ("demos", "specs", "models", "certificates"):
        (tmp_path / sub).mkdir()
        for f in sorted((repo / sub).glob("scoop*")):
            shutil.copy(f, tmp_path / sub / f.name)
    return tmp_path


def read_only_dir(tmp_path: Path) -> Path:
    """A directory this process cannot write in (``/sys`` when running as root)."""
    if os.geteuid() != 0:
        d = tmp_path / "ro"
        d.mkdir()
        d.chmod(0o555)
        return d
    sysfs = Path("/sys")
    try:
        (sysfs / ".tli-probe").touch()
    except OSError:
        return sysfs
    pytest.skip("running as root without a read-only directory")


# --------------------------------------------------------------------------------------------
# class 1: output paths
# --------------------------------------------------------------------------------------------

COMMANDS: dict[str, Callable[[Path, str], list[str]]] = {
    "learn": lambda p, o: ["learn", str(p / "demos" / "scoop_1.csv"), "-o", o],
    "certify": lambda p, o: ["certify", str(p / "models" / "scoop.model.json"), "-o", o],
    "spec automaton": lambda p, o: ["spec", "automaton", str(p / "specs" / "scoop.toml"),
                                    "-o", o],
    "experiment": lambda p, o: ["experiment", "single-mode", "--quick", "--trials", "1",
                                "--no-figures", "--out", o],
    "demo": lambda p, o: ["demo", "--out", o],
}
FILE_OUTPUT = {"learn", "certify", "spec automaton"}
BAD_OUTPUTS = ("read-only", "existing directory", "under a regular file", "empty", "device")


def bad_output(kind: str, command: str, project: Path, tmp_path: Path) -> tuple[str, str]:
    """(the output argument, a fragment the error must contain)."""
    name = "x.json"
    if kind == "read-only":
        return str(read_only_dir(tmp_path) / name), "not writable"
    if kind == "existing directory":
        d = project / "adir"
        d.mkdir(exist_ok=True)
        if command in FILE_OUTPUT:
            return str(d), "is a directory"
        (project / "afile").write_text("keep me\n")  # a directory output that is a file
        return str(project / "afile"), "not a directory"
    if kind == "under a regular file":
        (project / "afile").write_text("keep me\n")
        return str(project / "afile" / name), "under a regular file"
    if kind == "empty":
        return "", "empty path"
    fifo = project / "a-fifo"  # a FIFO of our own: never replace a system device in a test
    if not fifo.exists():
        os.mkfifo(fifo)
    return str(fifo), "not a regular file" if command in FILE_OUTPUT else "not a directory"


@pytest.mark.parametrize("kind", BAD_OUTPUTS)
@pytest.mark.parametrize("command", list(COMMANDS))
def test_bad_output_paths_exit_2(command: str, kind: str, project: Path, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    out, fragment = bad_output(kind, command, project, tmp_path)
    before = {p: p.read_bytes() for p in project.rglob("*") if p.is_file()}
    code, _, err = run(capsys, *COMMANDS[command](project, out))
    assert_bad_input(code, err, fragment)
    assert {p: p.read_bytes() for p in project.rglob("*") if p.is_file()} == before
    if kind == "device":
        assert (project / "a-fifo").is_fifo()


# --------------------------------------------------------------------------------------------
# class 2: an output equal to an input
# --------------------------------------------------------------------------------------------

def _spellings(target: Path, project: Path) -> st.SearchStrategy[str]:
    """Ways of naming ``target``: relative, ``./``, ``..`` detours, a symlink, a hard link."""
    rel = target.relative_to(project)
    parts = list(rel.parts)

    @st.composite
    def spelled(draw: st.DrawFn) -> str:
        how = draw(st.sampled_from(["abs", "dot", "detour", "symlink", "hardlink"]))
        if how == "abs":
            return str(target)
        if how == "dot":
            return "./" + "/./".join(parts)
        if how == "detour":
            return "/".join([parts[0], "..", *parts])
        link = project / f"link-{how}-{target.name}"
        if not link.exists():
            (link.symlink_to(target) if how == "symlink" else os.link(target, link))
        return link.name
    return spelled()


INPUT_CASES = {
    "learn: a demo": ("learn", "demos/scoop_2.csv"),
    "learn: the spec": ("learn", "specs/scoop.toml"),
    "certify: the model": ("certify", "models/scoop.model.json"),
    "certify: the model's spec": ("certify", "specs/scoop.toml"),
    "spec automaton: the spec": ("spec automaton", "specs/scoop.toml"),
}


def _argv(command: str, project: Path, out: str) -> list[str]:
    if command == "learn":
        return ["learn", "demos/scoop_1.csv", "demos/scoop_2.csv", "--spec", "specs/scoop.toml",
                "-o", out]
    if command == "certify":
        return ["certify", "models/scoop.model.json", "-o", out]
    return ["spec", "automaton", "specs/scoop.toml", "-o", out]


@pytest.mark.parametrize("case", list(INPUT_CASES))
@settings(max_examples=12)
@given(data=st.data())
def test_output_equal_to_an_input_is_refused_before_any_work(
        case: str, data: st.DataObject, tmp_path_factory: pytest.TempPathFactory,
        repo: Path) -> None:
    project = tmp_path_factory.mktemp("p")
    for sub in ("demos", "specs", "models"):
        shutil.copytree(repo / sub, project / sub)
    command, target = INPUT_CASES[case]
    out = data.draw(_spellings(project / target, project), label="output")
    before = (project / target).read_bytes()
    cwd = Path.cwd()
    os.chdir(project)
    try:
        try:
            code = main(_argv(command, project, out))
        except SystemExit as exc:
            code = int(exc.code or 0)
    finally:
        os.chdir(cwd)
    assert code == 2
    assert (project / target).read_bytes() == before
    assert not (project / "certificates").exists()  # refused before any work


# --------------------------------------------------------------------------------------------
# class 3: resource limits
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom", "fifo"])
@pytest.mark.parametrize("role", ["spec", "model", "certificate", "demo"])
def test_devices_and_streams_are_refused(role: str, device: str, tmp_path: Path) -> None:
    if device == "fifo":
        os.mkfifo(tmp_path / "fifo")
        device = str(tmp_path / "fifo")
    argv = {"spec": ["spec", "check", device],
            "model": ["certify", device, "-o", str(tmp_path / "c.json")],
            "certificate": ["check-cert", device],
            "demo": ["learn", device, "-o", str(tmp_path / "m.json")]}[role]
    proc = run_subprocess(argv, tmp_path, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: ") and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert "not a regular file" in proc.stderr or "no such certificate" in proc.stderr


def _nest(depth: int, opener: str) -> str:
    closer = {"[": "]", "{": "}"}
    out, tail = "", ""
    for i in range(depth):
        o = opener[i % len(opener)]
        out += o if o == "[" else '{"k":'
        tail = closer[o] + tail
    return out + "1" + tail


@settings(max_examples=20)
@given(depth=st.integers(MAX_NESTING + 1, 5000), opener=st.sampled_from(["[", "{", "[{", "{["]),
       where=st.sampled_from(["model", "certificate", "model-field"]))
def test_deeply_nested_json_is_bad_input(depth: int, opener: str, where: str,
                                         tmp_path_factory: pytest.TempPathFactory,
                                         repo: Path) -> None:
    d = tmp_path_factory.mktemp("deep")
    nested = _nest(depth, opener)
    if where == "model-field":
        doc = json.loads((repo / "models" / "scoop.model.json").read_text())
        text = json.dumps(doc).replace('"cuts": []', f'"cuts": [{nested}]', 1)
    else:
        text = nested
    f = d / "x.json"
    f.write_text(text)
    import io
    from contextlib import redirect_stderr, redirect_stdout

    err = io.StringIO()
    argv = (["check-cert", str(f)] if where == "certificate"
            else ["certify", str(f), "-o", str(d / "c.json")])
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        code = main(argv)
    if where == "certificate":  # a malformed certificate does not re-check: exit 1, one line
        assert code == 1, err.getvalue()
    else:
        assert code == 2, err.getvalue()
    assert "MAX_NESTING" in err.getvalue() and "internal error" not in err.getvalue()


def test_gate_blocks_on_hostile_files_instead_of_dying(project: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    (project / "certificates" / "deep.cert.json").write_text(_nest(3000, "["))
    (project / "models" / "deep.model.json").write_text(_nest(3000, "{"))
    doc = json.loads((project / "models" / "scoop.model.json").read_text())
    doc["modes"]["a"]["components"][0]["cov"] = [[1e-320, 0.0], [0.0, 1e-320]]
    (project / "models" / "tiny.model.json").write_text(json.dumps(doc))
    (project / "specs" / "deep.toml").write_text("x = " + "[" * 3000 + "]" * 3000 + "\n")
    code, out, err = run(capsys, "gate", str(project))
    assert code == 1, err
    assert "internal error" not in err
    for name in ("deep.cert.json", "deep.model.json", "tiny.model.json", "deep.toml"):
        assert any(line.startswith("BLOCK") and name in line for line in out.splitlines()), out


def test_demo_with_too_many_dimensions_is_refused_not_aborted(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]
                                                             ) -> None:
    n, rows = 200, 40
    lines = ["t," + ",".join(f"x{i}" for i in range(n)) + ",r"]
    lines += [f"{0.1 * r}," + ",".join(str(0.01 * (r + i)) for i in range(n)) + ",0"
              for r in range(rows)]
    f = tmp_path / "wide.csv"
    f.write_text("\n".join(lines) + "\n")
    code, _, err = run(capsys, "learn", str(f), "-o", str(tmp_path / "m.json"))
    assert_bad_input(code, err, "wide.csv", f"limit of {MAX_STATE_DIM}", "MAX_STATE_DIM")


# --------------------------------------------------------------------------------------------
# class 4: non-finite and huge numbers
# --------------------------------------------------------------------------------------------

HOSTILE = st.sampled_from([1e308, -1e308, 1.7976931348623157e308, 1e300, 1e200, 1e16,
                           -1e7, 1e-320, 5e-324, -1e-320, 0.0, 1e-300])


@settings(max_examples=40)
@given(value=HOSTILE, field=st.sampled_from(["attractor", "P", "mean", "cov", "A", "cut"]),
       i=st.integers(0, 1), j=st.integers(0, 1))
def test_certify_refuses_or_the_velocity_is_finite(value: float, field: str, i: int, j: int,
                                                   tmp_path_factory: pytest.TempPathFactory,
                                                   repo: Path) -> None:
    """A hostile number in a model: exit 2 naming the field, or a model whose velocity is
    finite at ordinary states (never a certified model returning NaN/inf)."""
    import numpy as np

    from tli_verify.model.serialize import load_model

    d = tmp_path_factory.mktemp("num")
    doc = json.loads((repo / "models" / "scoop.model.json").read_text())
    doc["spec"] = None
    mode = doc["modes"]["b"]
    comp = mode["components"][0]
    if field == "attractor":
        mode["attractor"][i] = value
    elif field == "P":
        mode["P"][i][j] = value
        mode["P"][j][i] = value
    elif field in ("mean", "cut"):
        if field == "cut":
            mode["cuts"] = [{"normal": [1.0, 0.0], "point": [value, value]}]
        else:
            comp["mean"][i] = value
    elif field == "cov":
        comp["cov"] = [[value, 0.0], [0.0, value]] if i == j else comp["cov"]
        comp["cov"][i][j] = value
        comp["cov"][j][i] = value
    else:
        comp["A"][i][j] = value
    f = d / "m.json"
    f.write_text(json.dumps(doc))
    import io
    from contextlib import redirect_stderr, redirect_stdout

    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        code = main(["certify", str(f), "-o", str(d / "c.json")])
    assert code in (0, 1, 2), err.getvalue()
    if code == 2:
        assert "modes.b" in err.getvalue() and len(err.getvalue().splitlines()) == 1
    if code == 0:
        model = load_model(f)
        grid = np.array([[x, y] for x in np.linspace(-20, 20, 9) for y in np.linspace(-20, 20, 9)])
        with np.errstate(all="ignore"):
            v = model.velocity(grid, "b")
        assert np.all(np.isfinite(v))


@settings(max_examples=30)
@given(value=st.one_of(st.floats(min_value=1e6, exclude_min=True, allow_infinity=False),
                       st.floats(max_value=-1e6, exclude_max=True, allow_infinity=False)),
       row=st.integers(0, 5), col=st.sampled_from(["x0", "x1", "dx0", "dx1"]))
def test_huge_demo_values_name_file_line_column(value: float, row: int, col: str,
                                                tmp_path_factory: pytest.TempPathFactory) -> None:
    d = tmp_path_factory.mktemp("demo")
    header = ["t", "x0", "x1", "dx0", "dx1", "r"]
    rows = [[str(0.1 * r), "1.0", "2.0", "-0.1", "-0.2", "0"] for r in range(6)]
    rows[row][header.index(col)] = repr(value)
    f = d / "d.csv"
    f.write_text("\n".join(",".join(x) for x in [header, *rows]) + "\n")
    import io
    from contextlib import redirect_stderr

    err = io.StringIO()
    with redirect_stderr(err):
        code = main(["learn", str(f), "-o", str(d / "m.json")])
    assert code == 2
    assert_bad_input(code, err.getvalue(), f"d.csv: line {row + 2}: column '{col}'",
                     "MAX_ABS_VALUE")


# --------------------------------------------------------------------------------------------
# class 9: tli demo from another folder
# --------------------------------------------------------------------------------------------

def test_demo_spec_stage_reads_the_bundled_specs_from_any_folder(
        tmp_path: Path, repo: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from tli_verify.commands import spec as spec_cmd

    monkeypatch.chdir(tmp_path)  # no ./specs here
    lines = spec_cmd.demo_stage(tmp_path / "out")
    n = len(list((repo / "specs").glob("*.toml")))
    assert n > 0
    assert lines[0] == f"[spec] checking {n} specs in specs/"
    assert len(list((tmp_path / "out" / "automata").glob("*.json"))) > 0


def test_bundled_files_are_found_relative_to_the_package(tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch
                                                         ) -> None:
    from tli_verify.io import bundled_dir

    monkeypatch.chdir(tmp_path)
    assert (bundled_dir("specs") / "scoop.toml").is_file()
    assert sorted(p.name for p in bundled_dir("demos").glob("scoop_*.csv")) == \
        ["scoop_1.csv", "scoop_2.csv", "scoop_3.csv"]


# --------------------------------------------------------------------------------------------
# class 10: clearer messages
# --------------------------------------------------------------------------------------------

def test_a_directory_where_a_file_is_expected(project: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["learn", str(project / "demos"), "-o", str(project / "m.json")],
                 ["certify", str(project / "models"), "-o", str(project / "c.json")],
                 ["spec", "automaton", str(project / "specs")],
                 ["check-cert", str(project / "certificates")],
                 ["check-cert", str(project / "certificates" / "scoop.cert.json"), "--model",
                  str(project / "models")],
                 ["learn", str(project / "demos" / "scoop_1.csv"), "--spec",
                  str(project / "specs"), "-o", str(project / "m.json")]):
        code, _, err = run(capsys, *argv)
        assert_bad_input(code, err, "is a directory")


def test_certify_refuses_a_model_whose_spec_is_not_toml(project: Path,
                                                        capsys: pytest.CaptureFixture[str]
                                                        ) -> None:
    (project / "specs" / "scoop.toml").write_text("this is [not toml\n")
    code, _, err = run(capsys, "certify", str(project / "models" / "scoop.model.json"), "-o",
                       str(project / "c.json"))
    assert_bad_input(code, err, "scoop.toml", "TOML")
    assert not (project / "c.json").exists()


@pytest.mark.parametrize("kind", ["csv", "toml", "json"])
def test_utf8_byte_order_mark_is_accepted(kind: str, project: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    bom = b"\xef\xbb\xbf"
    if kind == "csv":
        f = project / "demos" / "scoop_1.csv"
        f.write_bytes(bom + f.read_bytes())
        code, _, err = run(capsys, "learn", str(f), "-o", str(project / "m.json"))
    elif kind == "toml":
        f = project / "specs" / "scoop.toml"
        f.write_bytes(bom + f.read_bytes())
        code, _, err = run(capsys, "spec", "check", str(f))
    else:
        f = project / "models" / "bom.model.json"
        f.write_bytes(bom + (project / "models" / "scoop.model.json").read_bytes())
        code, _, err = run(capsys, "certify", str(f), "-o", str(project / "c.json"))
    assert code == 0, err


@settings(max_examples=8)
@given(exponent=st.one_of(st.integers(-10, 5), st.integers(6, 150)), seed=st.integers(0, 2**16))
def test_learning_at_any_unit_scale_writes_a_loadable_model_or_names_the_demo(
        exponent: int, seed: int, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Demonstrations in any units: inside the limits the learned model is written and loads
    (the model limits are coherent with the demo limits); outside, exit 2 naming the file --
    never a solver failure (exit 1), an abort or an internal error."""
    import io
    from contextlib import redirect_stderr, redirect_stdout

    import numpy as np

    from tli_verify.model.serialize import load_model

    rng = np.random.default_rng(seed)
    d = tmp_path_factory.mktemp("scale")
    scale = 10.0**exponent
    t = np.arange(60) * 0.1
    x = scale * (np.outer(np.exp(-t / 2), [1.0, -0.5]) + 0.01 * rng.normal(size=(60, 2)))
    rows = [f"{float(t[i])!r},{float(x[i, 0])!r},{float(x[i, 1])!r},{int(t[i] > 3)}"
            for i in range(60)]
    f = d / "demo.csv"
    f.write_text("t,x0,x1,r\n" + "\n".join(rows) + "\n")
    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()):
        code = main(["learn", str(f), "-o", str(d / "m.json")])
    from tli_verify.limits import MAX_ABS_VALUE

    # the demonstration's own largest value decides (exponent 6 with noise can stay under it)
    if float(np.max(np.abs(x))) <= MAX_ABS_VALUE:  # learnable in these units
        assert code == 0, err.getvalue()
        assert len(load_model(d / "m.json").modes) == 2
    else:
        assert_bad_input(code, err.getvalue(), "demo.csv", "MAX_ABS_VALUE")


@pytest.mark.parametrize(("field", "value"), [
    ("cov", 1e-320),          # subnormal covariance: Sigma^-1 overflows, gamma_k = NaN
    ("cov", 1e-300),
    ("mean", 1e308),
    ("attractor", -1e300),
])
def test_gate_blocks_a_re_hashed_model_with_hostile_numbers(field: str, value: float,
                                                            project: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    """Forgery: put a hostile number into the certified model, recompute the model hash and the
    certificate digest. The A_k and P are untouched, so the exact Lyapunov check still passes;
    only the load-time ranges catch it, and the gate must block."""
    from tli_verify.certification.certificate import certificate_digest
    from tli_verify.io import canonical_json, sha256_file

    model = project / "models" / "scoop.model.json"
    doc = json.loads(model.read_text())
    comp = doc["modes"]["b"]["components"][0]
    if field == "cov":
        comp["cov"] = [[value, 0.0], [0.0, value]]
    elif field == "mean":
        comp["mean"][0] = value
    else:
        doc["modes"]["b"]["attractor"][0] = value
    model.write_text(canonical_json(doc))
    cert_path = project / "certificates" / "scoop.cert.json"
    cert = json.loads(cert_path.read_text())
    cert["model"]["sha256"] = sha256_file(model)
    cert["digest"] = certificate_digest(cert)
    cert_path.write_text(canonical_json(cert))
    code, out, err = run(capsys, "gate", str(project))
    assert code == 1, out + err
    assert "internal error" not in err
    blocked = [line for line in out.splitlines() if line.startswith("BLOCK")]
    assert any("scoop.cert.json" in line and "modes.b" in line for line in blocked), out


def test_demo_without_a_checkout_says_what_it_needs(tmp_path: Path, repo: Path) -> None:
    """A bare copy of the package (as a wheel installs it) has no specs/ or demos/ next to it:
    ``tli demo`` says so (exit 2), instead of silently checking 0 specs."""
    shutil.copytree(repo / "tli_verify", tmp_path / "site" / "tli_verify",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(tmp_path / "site"), MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", "demo", "--out",
                           str(tmp_path / "out")], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=120, check=False)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith("error: the bundled project is missing")
    assert "reinstall" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1


def test_check_cert_on_a_fifo_and_an_empty_automaton_output(
        tmp_path: Path, repo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "cert.json"
    os.mkfifo(fifo)
    code, _, err = run(capsys, "check-cert", str(fifo))
    assert_bad_input(code, err, "cert.json", "not a regular file")
    code, _, err = run(capsys, "spec", "automaton", str(repo / "specs" / "scoop.toml"), "-o", "")
    assert_bad_input(code, err, "empty path")


def test_learn_control_dt_is_bounded_and_run_never_overwrites_its_certificate(
        tmp_path: Path, repo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "learn", str(repo / "demos" / "scoop_1.csv"), "-o",
                       str(tmp_path / "m.json"), "--control-dt", "1e200")
    assert code == 2 and "must be between 1e-06 and 1 s" in err
    for sub in ("models", "certificates", "specs"):
        shutil.copytree(repo / sub, tmp_path / sub)
    cert = tmp_path / "certificates" / "scoop.cert.json"
    before = cert.read_bytes()
    code, _, err = run(capsys, "run", "--task", "scoop", "--model",
                       str(tmp_path / "models" / "scoop.model.json"), "--certificate", str(cert),
                       "--spec", str(tmp_path / "specs" / "scoop.toml"), "--seed", "1", "-o",
                       str(tmp_path / "certificates" / "scoop.model.json"))
    assert_bad_input(code, err, "would overwrite the input file")
    assert cert.read_bytes() == before


def test_run_refuses_a_spec_other_than_the_certified_one(
        tmp_path: Path, repo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = tmp_path / "other.toml"
    other.write_text((repo / "specs" / "scoop.toml").read_text() + "\n# another spec\n")
    # a spec given alone selects the model of its project (models/<spec stem>.model.json):
    # here there is none
    code, _, err = run(capsys, "run", "--task", "scoop", "--spec", str(other), "--steps", "5")
    assert_bad_input(code, err, str(tmp_path / "models" / "other.model.json"),
                     "no such model file")
    # a model with a spec other than the one it names (and its certificate binds) is refused
    code, _, err = run(capsys, "run", "--task", "scoop", "--model",
                       str(repo / "models" / "scoop.model.json"), "--spec", str(other),
                       "--steps", "5")
    assert_bad_input(code, err, "not the spec the model names")
