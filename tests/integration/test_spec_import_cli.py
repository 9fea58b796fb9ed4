"""``tli spec import`` end to end: the TOML it writes loads and checks; refusals exit 2 with
one ``error:`` line naming the file and line; outputs are written atomically and never over
the input."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.cli import run

SPECTRA = """\
module Arbiter
env boolean r;
sys boolean g;
sys Int(0..2) k;
gar !g;
gar G (r -> next(g));
gar G (next(k) = 0 | next(k) = k + 1);
gar GF (k = 2);
asm GF (!r);
"""

UNREAL = """\
[INPUT]
a
[OUTPUT]
b
[SYS_TRANS]
a' -> ! b'
[SYS_LIVENESS]
b
"""


def test_import_then_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "arbiter.spectra"
    src.write_text(SPECTRA)
    out = tmp_path / "arbiter.toml"
    code, stdout, err = run(capsys, "spec", "import", str(src), "-o", str(out))
    assert code == 0, err
    assert "wrote" in stdout and out.exists()
    assert 'semantics = "textbook"' in out.read_text()
    code, stdout, err = run(capsys, "spec", "check", str(out))
    assert code == 0, err
    assert ": realizable" in stdout


def test_import_to_stdout_and_unrealizable_verdict(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "u.slugsin"
    src.write_text(UNREAL.replace("a' -> ! b'", "| ! a' ! b'"))
    code, stdout, _ = run(capsys, "spec", "import", str(src))
    assert code == 0 and stdout.startswith("# Imported from u.slugsin")
    src2 = tmp_path / "u.structuredslugs"
    src2.write_text(UNREAL)
    out = tmp_path / "u.toml"
    assert run(capsys, "spec", "import", str(src2), "-o", str(out), "--semantics", "tli")[0] == 0
    assert "semantics" not in out.read_text()
    code, stdout, _ = run(capsys, "spec", "check", str(out))
    assert code == 1 and "UNREALIZABLE" in stdout


def test_refused_construct_exits_2_with_one_error_line(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]
                                                       ) -> None:
    src = tmp_path / "w.spectra"
    src.write_text(SPECTRA + "weight reward: g;\n")
    out = tmp_path / "w.toml"
    code, stdout, err = run(capsys, "spec", "import", str(src), "-o", str(out))
    assert code == 2 and stdout == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert f"{src}:10:" in lines[0] and "weights" in lines[0]
    assert not out.exists()


def test_output_rules(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "a.spectra"
    src.write_text(SPECTRA)
    before = src.read_text()
    code, _, err = run(capsys, "spec", "import", str(src), "-o", str(src))
    assert code == 2 and err.startswith("error:")
    assert src.read_text() == before
    code, _, err = run(capsys, "spec", "import", str(src), "-o", str(tmp_path / "a.json"))
    assert code == 2 and ".toml" in err
    code, _, err = run(capsys, "spec", "import", str(tmp_path / "a.txt"))
    assert code == 2 and err.startswith("error:")
    (tmp_path / "b.smv").write_text("MODULE main\n")
    code, _, err = run(capsys, "spec", "import", str(tmp_path / "b.smv"))
    assert code == 2 and "unknown format" in err
