"""`tli learn | certify | check-cert | gate` end to end: outputs, exit codes, error lines."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.cli import run
from tests.support.evidence import attach_evidence


@pytest.fixture
def project(tmp_path: Path, repo: Path) -> Path:
    (tmp_path / "demos").mkdir()
    (tmp_path / "specs").mkdir()
    for demo in sorted((repo / "demos").glob("scoop_*.csv")):
        shutil.copy(demo, tmp_path / "demos" / demo.name)
    shutil.copy(repo / "specs" / "scoop.toml", tmp_path / "specs" / "scoop.toml")
    return tmp_path


def assert_one_error_line(err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: ")
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_learn_certify_check_gate(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    demos = sorted(str(p) for p in (project / "demos").glob("*.csv"))
    model = project / "models" / "scoop.model.json"
    cert = project / "certificates" / "scoop.cert.json"
    code, out, _ = run(capsys, "learn", *demos, "--spec", str(project / "specs" / "scoop.toml"),
                       "-o", str(model), "--seed", "0")
    assert code == 0
    assert out.splitlines()[0].startswith("a: K=")
    assert f"wrote {model} (4 DS)" in out
    assert json.loads(model.read_text())["spec"] == "../specs/scoop.toml"

    code, out, _ = run(capsys, "certify", str(model), "-o", str(cert))
    assert code == 0
    assert out.count("exact: yes") == 4

    code, out, _ = run(capsys, "check-cert", str(cert))
    assert code == 0
    assert out.strip().endswith(f"valid (re-checked exactly against {model})")

    # certified but never property-tested: the campaign-evidence check alone blocks
    code, out, err = run(capsys, "gate", str(project))
    assert code == 1
    assert [line.split(": ")[1] for line in out.splitlines() if line.startswith("BLOCK")] == [
        "campaign"]
    assert_one_error_line(err, "gate blocked: 1 problem(s)", "no campaign evidence")
    attach_evidence(project)
    code, out, _ = run(capsys, "gate", str(project))
    assert code == 0
    assert out.strip().splitlines()[-1] == ("gate: pass (1 certificate(s), 1 model(s), "
                                            "1 spec(s))")

    # same seed, same model file
    again = project / "again.model.json"
    assert run(capsys, "learn", *demos, "--spec", str(project / "specs" / "scoop.toml"),
               "-o", str(again))[0] == 0
    first, second = json.loads(model.read_text()), json.loads(again.read_text())
    assert first["modes"] == second["modes"]

    # an edit of the model: check-cert and gate say no, and what differs
    text = model.read_text()
    model.write_text(text.replace('"eps": 0.001', '"eps": 0.002', 1))
    code, out, err = run(capsys, "check-cert", str(cert))
    assert code == 1
    assert "FAIL" in out and "the model changed after certification" in out
    assert_one_error_line(err, "certificate does not re-check")
    code, out, err = run(capsys, "gate", str(project))
    assert code == 1
    assert "BLOCK certificate" in out and "BLOCK model" in out
    assert_one_error_line(err, "gate blocked: 3 problem(s)")  # certificate, model, campaign


def test_json_output_and_label_free_modes(project: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    demos = sorted(str(p) for p in (project / "demos").glob("*.csv"))
    model = project / "m.json"
    code, out, _ = run(capsys, "learn", *demos, "-o", str(model), "--json")
    assert code == 0
    records = [json.loads(line) for line in out.splitlines()]
    assert [r["key"] for r in records] == ["!r & !s & !t", "r & !s & !t", "!r & s & !t",
                                          "!r & !s & t"]
    assert records[0]["next_mode"] == "r & !s & !t"
    code, out, _ = run(capsys, "certify", str(model), "-o", str(project / "c.json"), "--json")
    assert code == 0
    assert all(json.loads(line)["exact"] for line in out.splitlines())
    code, out, _ = run(capsys, "check-cert", str(project / "c.json"), "--json")
    assert code == 0
    assert json.loads(out.splitlines()[-1])["valid"] is True
    code, out, _ = run(capsys, "gate", str(project), "--json")
    assert code == 1  # nothing under models/ here: the gate fails closed
    records = [json.loads(line) for line in out.splitlines()]
    assert records[-1] == {"gate": "blocked", "root": str(project), "blockers": 1}
    assert [r["check"] for r in records if not r.get("ok", True)] == ["contents"]


def test_baseline_learning(project: Path, capsys: pytest.CaptureFixture[str]) -> None:
    demos = sorted(str(p) for p in (project / "demos").glob("*.csv"))
    model = project / "b.json"
    assert run(capsys, "learn", *demos, "-o", str(model), "--baseline")[0] == 0
    fits = [m["fit"] for m in json.loads(model.read_text())["modes"].values()]
    assert {(f["clustering"], f["lyapunov"]) for f in fits} == {("em-bic", "identity")}


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("t,x0,x1\n0,0,0\n1,nan,1\n2,2,2\n", ("bad.csv: line 3: column 'x0'", "not finite")),
        ("t,x0,x1\n0,0,0\n1,1,1\n", ("at least 3",)),
        ("t,x0,x1,r\n0,0,0,0\n1,1,1,3\n2,2,2,1\n", ("line 3: sensor 'r': value '3'",)),
        ("t,x0,x1\n0,0,0\n0,1,1\n2,2,2\n", ("line 3: t = 0.0 does not increase",)),
    ],
)
def test_bad_demo_is_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                            fragments: tuple[str, ...]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    code, _, err = run(capsys, "learn", str(bad), "-o", str(tmp_path / "m.json"))
    assert code == 2
    assert_one_error_line(err, *fragments)
    assert not (tmp_path / "m.json").exists()


def test_spec_mode_without_demonstration(project: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    demo = project / "demos" / "scoop_1.csv"
    lines = demo.read_text().splitlines()
    header = lines[1].split(",")
    t_col = header.index("t")
    kept = [line for line in lines[2:] if line.split(",")[t_col] == "0"]  # never reaches d
    short = project / "short.csv"
    short.write_text("\n".join([lines[1], *kept]) + "\n")
    code, _, err = run(capsys, "learn", str(short), "--spec",
                       str(project / "specs" / "scoop.toml"), "-o", str(project / "m.json"))
    assert code == 2
    assert_one_error_line(err, "mode 'd'", "visited by no demonstration", "Asm. 3")


def test_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, "learn", "x.csv")
    assert code == 2
    assert_one_error_line(err, "-o/--output")
    code, _, err = run(capsys, "learn", "x.csv", "-o", "m.json", "--eps", "-1")
    assert code == 2
    assert_one_error_line(err, "must be ")
    code, _, err = run(capsys, "learn", str(tmp_path / "missing.csv"), "-o", "m.json")
    assert code == 2
    assert_one_error_line(err, "missing.csv: cannot read demonstration file")
    code, _, err = run(capsys, "check-cert", str(tmp_path / "none.json"))
    assert code == 2
    assert_one_error_line(err, "no such certificate file")
    code, _, err = run(capsys, "gate", str(tmp_path / "nodir"))
    assert code == 2
    assert_one_error_line(err, "not a directory")


def test_certify_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps({"schema_version": 1, "state_names": ["x0", "x1"], "modes": {
        "reach": {"attractor": [0.0, 0.0], "P": [[1.0, 0.0], [0.0, 1.0]], "cuts": [],
                  "components": [
                      {"prior": 0.5, "mean": [0.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]],
                       "A": [[-1.0, 0.0], [0.0, -1.0]]},
                      {"prior": 0.5, "mean": [1.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]],
                       "A": [[0.2, 0.0], [0.0, -1.0]]}]}}}))
    code, _, err = run(capsys, "certify", str(bad), "-o", str(tmp_path / "c.json"))
    assert code == 1
    assert_one_error_line(err, "mode 'reach'", "component 1", "the model's P does not certify",
                          "--repair")
    assert not (tmp_path / "c.json").exists()
    data = json.loads(bad.read_text())
    data["modes"]["reach"]["components"][1]["cov"] = [[1.0, 3.0], [3.0, 1.0]]
    bad.write_text(json.dumps(data))
    code, _, err = run(capsys, "certify", str(bad))
    assert code == 2
    assert_one_error_line(err, "modes.reach.components[1].cov: not symmetric positive definite")


def test_motion_commands_import_nothing_heavy() -> None:
    code = ("import sys, argparse; from tli_verify.commands import motion; "
            "p = argparse.ArgumentParser(); motion.register(p.add_subparsers()); "
            "print(sorted(m for m in ('cvxpy', 'sklearn', 'sympy', 'matplotlib', 'scipy') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
