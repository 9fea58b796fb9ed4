"""``tli spec infer`` end to end: the written spec, exit codes, one-line errors."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tli_verify.cli import main
from tli_verify.logic.check import check_spec, synthesize
from tli_verify.logic.spec import load_spec


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        code = main(args)
    except SystemExit as exc:  # usage errors (argparse)
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def _one_error(err: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


@pytest.fixture
def scoop_demos(repo: Path, tmp_path: Path) -> list[str]:
    """Copies of the bundled demonstrations (another process may regenerate the originals)."""
    out = []
    for p in sorted((repo / "demos").glob("scoop_*.csv")):
        shutil.copy(p, tmp_path / p.name)
        out.append(str(tmp_path / p.name))
    return out


def test_infer_scoop_writes_a_loadable_sound_spec(scoop_demos: list[str], specs_dir: Path,
                                                  tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sub" / "scoop-inferred.toml"
    code, stdout, err = run(["spec", "infer", *scoop_demos, "--modes",
                             str(specs_dir / "scoop.toml"), "-o", str(out)], capsys)
    assert code == 0, err
    assert f"wrote {out}: realizable, well-separated" in stdout
    assert "mode changes a->b b->c c->d" in stdout
    spec = load_spec(out)
    assert spec.name == "scoop-inferred"
    assert spec.modes == load_spec(specs_dir / "scoop.toml").modes
    result = check_spec(spec)
    assert result.realizable and result.well_separated
    pairs = [p for p in synthesize(spec).mode_transitions() if p[0] != p[1]]
    assert pairs == [["a", "b"], ["b", "c"], ["c", "d"]]
    # `tli spec check` agrees on the written file.
    code, stdout, _ = run(["spec", "check", "--strict", str(out)], capsys)
    assert code == 0 and ": realizable" in stdout


def test_infer_with_a_labels_only_file(scoop_demos: list[str], tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    labels = tmp_path / "labels.toml"
    labels.write_text('[modes]\nreach = "!r & !s & !t"\nscoop = "r & !s & !t"\n'
                      'carry = "!r & s & !t"\ndone = "!r & !s & t"\n')
    out = tmp_path / "x.toml"
    code, _, err = run(["spec", "infer", *scoop_demos, "--modes", str(labels), "-o",
                             str(out), "--name", "renamed"], capsys)
    assert code == 0, err
    spec = load_spec(out)
    assert spec.name == "renamed"
    assert spec.mode_names == ("reach", "scoop", "carry", "done")
    assert [f.text for f in spec.guarantee.liveness] == ["GF(done | p)"]


@pytest.mark.parametrize("case", ["missing-labels", "unknown-sensor", "no-modes-table",
                                  "bad-toml", "missing-demo", "unvisited-mode", "no-demos",
                                  "output-is-input"])
def test_bad_inputs_exit_2_with_one_error_line(case: str, scoop_demos: list[str],
                                               specs_dir: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    labels = tmp_path / "labels.toml"
    out = tmp_path / "out.toml"
    demos = scoop_demos
    expect = ""
    if case == "missing-labels":
        expect = "missing.toml"
        labels = tmp_path / "missing.toml"
    elif case == "unknown-sensor":
        labels.write_text('[modes]\na = "!r & !s & !t"\nb = "r & !q"\n')
        expect = "labels.toml:3: modes.b: label uses 'q', which is not a sensor column"
    elif case == "no-modes-table":
        labels.write_text('name = "x"\n')
        expect = "no [modes] table"
    elif case == "bad-toml":
        labels.write_text("[modes\n")
        expect = "invalid TOML"
    elif case == "missing-demo":
        labels = specs_dir / "scoop.toml"
        demos = [*scoop_demos, str(tmp_path / "nope.csv")]
        expect = "nope.csv"
    elif case == "unvisited-mode":
        labels.write_text('[modes]\na = "!r & !s & !t"\nb = "r & !s & !t"\nc = "!r & s & !t"\n'
                          'd = "!r & !s & t"\ne = "r & s & t"\n')
        expect = "'e'"
    elif case == "no-demos":
        labels = specs_dir / "scoop.toml"
        demos = []
        expect = "DEMO.csv"
    elif case == "output-is-input":
        labels = specs_dir / "scoop.toml"
        out = Path(scoop_demos[0])
        expect = "overwrite"
    before = out.read_bytes() if out.exists() else None
    code, _, err = run(["spec", "infer", *demos, "--modes", str(labels), "-o", str(out)],
                       capsys)
    assert code == 2
    assert expect in _one_error(err)
    assert (out.read_bytes() if out.exists() else None) == before  # nothing written


def test_help_documents_the_scoop_growth(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["spec", "infer", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "Fig. 3(a)" in out and "b->a, c->a, c->b" in out
