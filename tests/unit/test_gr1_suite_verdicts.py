"""The suite-verdict benchmark's bookkeeping: labels, copies, and time-outs never counted as
verdicts (benchmarks/gr1_suite_verdicts.py, benchmarks/bench_gr1_peers.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from benchmarks.bench_gr1_peers import _t
from benchmarks.gr1_suite_verdicts import label_of, spec_key, verdict_report


def test_labels_come_from_folders_then_from_names(tmp_path: Path) -> None:
    for d in ("S17/all_realizable", "S17/group1/unrealizable", "S15/unrealizable", "S20/ALL"):
        (tmp_path / d).mkdir(parents=True)
    assert label_of(Path("S17/all_realizable/a.spectra"), tmp_path) == ("R", "folder")
    assert label_of(Path("S17/group1/unrealizable/a.spectra"), tmp_path) == ("U", "folder")
    assert label_of(Path("S20/ALL/Elevator_realizable_v1.spectra"), tmp_path) == ("R", "name")
    assert label_of(Path("S20/ALL/x_unrealizable.spectra"), tmp_path) == ("U", "name")
    # next to an unrealizable/ folder the suite sorts by folder: a name is no label
    assert label_of(Path("S15/PCar_Unrealizable_fixed.spectra"), tmp_path) == (None, "")
    assert label_of(Path("S20/ALL/v5unrealliveness.spectra"), tmp_path) == (None, "")


def test_copies_of_a_spec_have_one_key_and_other_formulas_another() -> None:
    a = ('# from a.spectra:3\nname = "A"\ndescription = "a"\ninputs = ["x"]\n'
         'outputs = ["y"]\n[guarantee]\nsafety = [\n  # a.spectra:9\n  "G(y)",\n]\n')
    copy = a.replace("a.spectra", "b_as_a.spectra").replace('"A"', '"B"')
    other = a.replace('"G(y)"', '"G(!y)"')
    assert spec_key(a) == spec_key(copy)
    assert spec_key(a) != spec_key(other)


def _rec(name: str, label: str | None, tb: dict[str, Any], tli: dict[str, Any]) -> dict[str, Any]:
    return {"key": name, "name": name, "n_vars": 3, "files": [name], "limit": 10.0,
            "labels": {name: (label, "folder")} if label else {}, "textbook": tb, "tli": tli}


R: dict[str, Any] = {"timeout": False, "verdict": True, "total": 0.5}
U: dict[str, Any] = {"timeout": False, "verdict": False, "total": 0.5}
T: dict[str, Any] = {"timeout": True, "limit": 10.0}


def _row(md: str, start: str) -> list[str]:
    line = next(ln for ln in md.splitlines() if ln.startswith(start))
    return [c.strip() for c in line.strip("|").split("|")]


def test_time_outs_are_never_verdicts_and_disagreements_are_named() -> None:
    recs = [
        _rec("s1", "R", {"ours": R, "omega": R, "slugs": R}, {"ours": U, "omega": U}),
        _rec("s2", "R", {"ours": U, "omega": U, "slugs": U}, {"ours": U, "omega": U}),
        _rec("s3", None, {"ours": R, "omega": T, "slugs": U}, {"ours": R, "omega": T}),
    ]
    md = verdict_report(recs, None, timeout=10.0, notes=[], command="x")
    # realizable, unrealizable, time-out, error, not run
    assert _row(md, "| textbook | ours |") == ["textbook", "ours", "2", "1", "0", "0", "0"]
    assert _row(md, "| textbook | omega |") == ["textbook", "omega", "1", "1", "1", "0", "0"]
    # agree, disagree, not both decided
    assert _row(md, "| textbook | ours vs omega |") == ["textbook", "ours vs omega", "2", "0", "1"]
    assert _row(md, "| textbook | ours vs slugs |") == ["textbook", "ours vs slugs", "2", "1", "0"]
    assert _row(md, "| tli | ours vs omega |") == ["tli", "ours vs omega", "2", "0", "1"]
    assert _row(md, "| textbook | ours vs Spectra") == [
        "textbook", "ours vs Spectra's label (2 labelled)", "1", "1", "0"]
    assert "textbook, ours vs slugs: s3" in md
    assert "Spectra's label R (folder): s2" in md
    assert "different verdicts (ours) on 1 of the 3 specs decided in both: s1" in md


def test_a_time_out_counts_as_its_own_limit_in_a_ratio() -> None:
    assert _t({"timeout": True, "limit": 60.0}, 10.0) == 60.0
    assert _t({"timeout": True}, 10.0) == 10.0
    assert abs(_t(R, 10.0) - 0.5) < 1e-12
