"""``tli spec ...`` end to end: exit codes, one-line errors, JSON records, output files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tli_verify.cli import main


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_check_all_shipped(specs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    files = [str(p) for p in sorted(specs_dir.glob("*.toml")) if "unrealizable" not in p.name]
    code, out, err = run(["spec", "check", *files], capsys)
    assert code == 0, err
    assert out.count(": realizable") == len(files)


def test_check_unrealizable_exit_1_with_diagnosis(specs_dir: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["spec", "check", str(specs_dir / "scoop-unrealizable.toml")], capsys)
    assert code == 1
    assert "UNREALIZABLE" in out and "witness play" in out and "hint:" in out


def test_check_json_records(specs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["spec", "check", "--json", str(specs_dir / "scoop.toml"),
                        str(specs_dir / "scoop-unrealizable.toml")], capsys)
    assert code == 1
    records = [json.loads(line) for line in out.splitlines()]
    assert [r["realizable"] for r in records] == [True, False]
    for r in records:
        assert {"file", "realizable", "diagnosis", "seconds"} <= set(r)
    assert records[0]["diagnosis"] is None
    assert records[1]["diagnosis"]["kind"] == "safety"


def test_explain_lists_added_constraints(specs_dir: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(["spec", "check", "--explain", str(specs_dir / "scoop.toml")], capsys)
    assert code == 0
    assert "[added from [modes]]" in out
    assert "G(X(a -> (!r & !s & !t)))" in out


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (b"", "empty spec file"),
        (b"name = [", "invalid TOML"),
        (b'inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = ["G(a -> X q)"]', "unknown AP"),
        (b'inputs = ["a"]\noutputs = ["a"]', "both an input and an output"),
        (b'inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nliveness = ["F G a"]', "not GF(p)"),
        (b'inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = ["G(X X a)"]', "nested X"),
        (bytes(range(256)), "not a text file"),
    ],
)
def test_bad_input_exit_2_one_line(tmp_path: Path, content: bytes, needle: str,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    code, _out, err = run(["spec", "check", str(path)], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0]
    assert str(path) in lines[0]
    assert "Traceback" not in err


def test_huge_file_and_missing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    huge = tmp_path / "huge.toml"
    huge.write_bytes(b"#" * (5 * 1024 * 1024))
    code, _, err = run(["spec", "check", str(huge), str(tmp_path / "nope.toml")], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 2
    assert all(line.startswith("error: ") for line in err.strip().splitlines())


def test_bad_and_good_files_together(specs_dir: Path, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("")
    code, out, _ = run(["spec", "check", str(specs_dir / "scoop.toml"), str(bad)], capsys)
    assert code == 2
    assert "realizable" in out


def test_automaton_outputs(specs_dir: Path, tmp_path: Path,
                           capsys: pytest.CaptureFixture[str]) -> None:
    out_json = tmp_path / "a.json"
    out_dot = tmp_path / "a.dot"
    assert run(["spec", "automaton", str(specs_dir / "scoop.toml"), "-o", str(out_json)],
               capsys)[0] == 0
    assert run(["spec", "automaton", str(specs_dir / "scoop.toml"), "-o", str(out_dot)],
               capsys)[0] == 0
    data = json.loads(out_json.read_text())
    assert ["c", "a"] in data["mode_transitions"]
    assert out_dot.read_text().startswith("digraph")
    code, out, _ = run(["spec", "automaton", "--json", str(specs_dir / "inspection.toml")],
                       capsys)
    assert code == 0 and json.loads(out)["name"] == "inspection"
    code, _, err = run(["spec", "automaton", str(specs_dir / "scoop.toml"), "-o",
                        str(tmp_path / "a.txt")], capsys)
    assert code == 2 and err.startswith("error:")


def test_automaton_of_unrealizable_exit_1(specs_dir: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["spec", "automaton", str(specs_dir / "scoop-unrealizable.toml")], capsys)
    assert code == 1 and err.startswith("error:") and "unrealizable" in err


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["spec", "check"])
    assert info.value.code == 2
    assert capsys.readouterr().err.startswith("error:")
    with pytest.raises(SystemExit) as info:
        main(["no-such-command"])
    assert info.value.code == 2


def test_console_script_runs(specs_dir: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", "spec", "check",
                           str(specs_dir / "scoop.toml")], capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert "realizable" in proc.stdout
