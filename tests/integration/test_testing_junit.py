"""``tli verify --junit FILE``: a campaign as JUnit XML for CI, written atomically, with the
file in the command's output checks (refused, before any work, when it is an input, another
output or not writable)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tests.support.cli import run

REPO = Path(__file__).resolve().parents[2]


def test_a_campaign_as_junit_xml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The no-modulation ablation of the scoop (it fails, paper Fig. 7): one testcase per run,
    the failures are the violating runs, the counterexample's run names its ``tli replay``
    command; undecided runs without a violation are skipped."""
    out, junit = tmp_path / "out", tmp_path / "ci" / "campaign.xml"
    code, text, err = run(capsys, "verify", "--task", "scoop", "--examples", "25", "--seed",
                          "0", "--no-modulation", "--no-shrink", "--backend", "serial",
                          "--out", str(out), "--junit", str(junit))
    assert code == 1, err
    assert f"wrote JUnit report {junit}" in text
    rec = json.loads((out / "campaign.json").read_text())
    assert rec["junit"] == str(junit)
    assert [p.name for p in junit.parent.iterdir()] == ["campaign.xml"]  # no temporary left
    root = ET.parse(junit).getroot()
    (suite,) = root.findall("testsuite")
    runs = suite.findall("testcase")
    failures = [c for c in runs if c.find("failure") is not None]
    skipped = [c for c in runs if c.find("skipped") is not None]
    assert len(runs) == rec["runs"] == int(suite.get("tests", "-1")) == 25
    assert len(failures) == rec["violating_runs"] == int(suite.get("failures", "-1")) >= 1
    assert len(skipped) == int(suite.get("skipped", "-1")) <= rec["inconclusive"]
    props = {p.get("name"): p.get("value") for p in suite.iter("property")}
    assert props["seed"] == "0" and props["modulation"] == "false"
    assert props["model.sha256"] == rec["files"]["model"]["sha256"]
    ce = rec["counterexample"]
    (theirs,) = [c for c in runs if c.get("name", "").endswith(f" {ce['index'] + 1:02d}")]
    failure = theirs.find("failure")
    assert failure is not None and failure.get("type") == ce["expected"]["violation"]
    assert f"tli replay {out / 'counterexample.json'}" in (failure.text or "")


@pytest.mark.parametrize(("junit", "needle"), [
    ("{out}/campaign.json", "the JUnit report and the campaign record would be the same file"),
    ("{model}", "would overwrite the input file"),
    ("{tmp}", "is a directory"),
    ("", "empty path"),
])
def test_a_junit_file_that_cannot_be_written_is_refused_before_work(
        junit: str, needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model = REPO / "models" / "scoop.model.json"
    path = junit.format(out=tmp_path / "out", model=model, tmp=tmp_path)
    before = model.read_bytes()
    code, text, err = run(capsys, "verify", "--task", "scoop", "--examples", "5",
                          "--backend", "serial", "--out", str(tmp_path / "out"),
                          "--junit", path)
    assert code == 2 and text == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], err
    assert not (tmp_path / "out").exists() and model.read_bytes() == before
