"""``tli verify`` and ``tli replay``: short campaigns on the scoop world, the JSON record, exit
codes, the replay round trip, Ctrl-C (a partial report), and a worker that dies."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.support.cli import run
from tests.support.drawer3d import write_project
from tli_verify.cli import main
from tli_verify.errors import WorkerLost
from tli_verify.verify.backends import ProcessBackend, make_backend

REPO = Path(__file__).resolve().parents[2]
KINDS = {"invariance", "repeated-exit", "reachability", "automaton", "looping"}


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    return run(capsys, *argv)


@pytest.fixture(scope="module")
def found(tmp_path_factory: pytest.TempPathFactory) -> tuple[int, dict, Path]:  # type: ignore[type-arg]
    """A short campaign without modulation (serial backend): it finds a counterexample."""
    out = tmp_path_factory.mktemp("found")
    code = main(["verify", "--task", "scoop", "--examples", "25", "--seed", "0",
                 "--no-modulation", "--backend", "serial", "--json", "--out", str(out)])
    return code, json.loads((out / "campaign.json").read_text()), out


def test_campaign_json_fields(found: tuple[int, dict, Path]) -> None:  # type: ignore[type-arg]
    code, rec, out = found
    assert code == 1
    assert rec["runs"] == 25 and rec["partial"] is False and rec["modulation"] is False
    assert set(rec["violations"]) == KINDS
    assert sum(rec["violations"].values()) >= 1
    assert rec["task_satisfied"] <= rec["runs"]
    assert rec["cuts_added"] == 0  # no modulation: no cut is ever learned
    cov = rec["coverage"]
    assert 0 < cov["automaton_edges"]["exercised"] <= cov["automaton_edges"]["total"]
    assert "a->b" in cov["mode_edges"]["list"]
    assert set(cov["modes_perturbed"]["perturbed"]) <= set(cov["modes_perturbed"]["modes"])
    ce = rec["counterexample"]
    assert ce is not None and ce["shrunk"] is True
    assert ce["expected"]["violation"] in KINDS
    assert 1 <= rec["simulations_to_first_counterexample"] <= 25
    assert rec["failure_probability_bound_95"] is None
    assert ce["files"]["model"]["path"] == "models/scoop.model.json"
    for name in ("campaign.md", "campaign.png", "counterexample.json", "counterexample.png"):
        assert (out / name).stat().st_size > 100
    assert "## Counterexample" in (out / "campaign.md").read_text()


def test_fig7_looping_found_and_shrunk(found: tuple[int, dict, Path]) -> None:  # type: ignore[type-arg]
    # the shipped model loops a -> b -> a -> b without modulation (Fig. 7): the campaign files
    # its counterexample under looping (the most specific kind found, although a lone
    # invariance failure came first) and shrinks it to a single perturbation
    _, rec, _ = found
    first = rec["first_violation_by_kind"]
    assert first["looping"] is not None
    assert rec["simulations_to_first_counterexample"] == min(v for v in first.values() if v)
    ce = rec["counterexample"]
    assert ce["expected"]["violation"] == "looping"
    assert ce["index"] + 1 == first["looping"]
    assert len(ce["perturbations"]) == 1
    assert ce["expected"]["oracle_modes"].startswith("ababab")


def test_replay_round_trip(found: tuple[int, dict, Path],  # type: ignore[type-arg]
                           capsys: pytest.CaptureFixture[str]) -> None:
    _, rec, out = found
    case = out / "counterexample.json"
    code, text, _ = _run(["replay", str(case), "--json"], capsys)
    got = json.loads(text)
    assert code == 1 and got["reproduced"] is True
    assert got["expected"] == rec["counterexample"]["expected"]["violation"]
    assert got["oracle_modes"] == rec["counterexample"]["expected"]["oracle_modes"]
    # the same case under LTL-DS: the cut answers the failure, nothing is violated
    code, text, _ = _run(["replay", str(case), "--modulation", "on", "--json"], capsys)
    assert code == 0 and json.loads(text)["violations"] == []


def test_campaign_with_modulation_finds_nothing(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code, text, _ = _run(["verify", "--task", "scoop", "--examples", "25", "--seed", "0",
                          "--backend", "serial", "--json", "--out", str(tmp_path)], capsys)
    rec = json.loads(text)
    assert code == 0, rec["violations"]
    assert rec["counterexample"] is None and rec["simulations_to_first_counterexample"] is None
    assert rec["failure_probability_bound_95"] == pytest.approx(3 / rec["runs"])
    assert "None found" in (tmp_path / "campaign.md").read_text()


@pytest.mark.slow  # starts 2 worker processes that each load the setup (~5-15 s)
def test_process_backend_matches_serial(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    recs = []
    for backend, extra in (("serial", []), ("process", ["--workers", "2"])):
        code, text, _ = _run(["verify", "--task", "scoop", "--examples", "30", "--seed", "5",
                              "--no-modulation", "--no-shrink", "--batch-size", "7",
                              "--backend", backend, *extra, "--json",
                              "--out", str(tmp_path / backend)], capsys)
        recs.append((code, json.loads(text)))
    (c1, a), (c2, b) = recs
    assert c1 == c2
    for key in ("runs", "violations", "task_satisfied", "coverage", "counterexample",
                "simulations_to_first_counterexample"):
        assert a[key] == b[key], key


@pytest.mark.parametrize(("argv", "needle"), [
    (["verify", "--task", "nowhere"], "unknown task"),
    (["verify", "--task", "scoop", "--examples", "0"], "--examples"),
    (["verify", "--task", "scoop", "--scheduler", "tcp://x:1"], "--scheduler"),
    (["verify", "--task", "scoop", "--model", "/nonexistent/m.json"], "no such model"),
    (["verify", "--task", "scoop", "--backend", "threads"], "--backend"),
    (["replay", "/nonexistent/case.json"], "no such case file"),
    # checked before the campaign runs (one line: no campaign note before it)
    (["verify", "--task", "scoop", "--examples", "5", "--evidence",
      str(Path(__file__).resolve().parents[2] / "models" / "scoop.model.json")],
     "would overwrite the input file"),
    # an empty PATH is refused, not taken as the default path (the bundled evidence)
    (["verify", "--task", "scoop", "--examples", "5", "--evidence", ""], "empty path"),
])
def test_bad_arguments_exit_2_with_one_line(argv: list[str], needle: str, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    full = [*argv, *(["--out", str(tmp_path)] if argv[0] == "verify" else [])]
    code, _, err = run(capsys, *full)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and needle in lines[0], err


@pytest.mark.parametrize("content", [
    "not json {",
    json.dumps({"kind": "something-else"}),
    json.dumps({"kind": "tli-verify/bisimulation-case", "files": {}}),
])
def test_bad_case_file_exits_2(content: str, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    case = tmp_path / "case.json"
    case.write_text(content)
    code, _, err = _run(["replay", str(case)], capsys)
    assert code == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("error:") and "case" in err


def test_replay_of_an_edited_case_names_the_field(found: tuple[int, dict, Path],  # type: ignore[type-arg]
                                                  tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    doc = json.loads((found[2] / "counterexample.json").read_text())
    doc["perturbations"] = [{"step": -1, "displacement": [0.0, 0.0]}]
    case = tmp_path / "edited.json"
    case.write_text(json.dumps(doc))
    code, _, err = _run(["replay", str(case)], capsys)
    assert code == 2 and "perturbations[0].step" in err


@pytest.mark.parametrize(("edit", "needle"), [
    ({"start": [1e308, 0.0]}, "outside the workspace of task"),
    ({"window": 10**12}, "MAX_CAMPAIGN_STEPS"),
    ({"lag": 10**9}, "MAX_CAMPAIGN_STEPS"),
    ({"perturbations": [{"step": 10**18, "displacement": [1.0, 0.0]}]}, "MAX_CAMPAIGN_STEPS"),
    ({"perturbations": [{"step": k + 1, "displacement": [0.0, 0.0]} for k in range(101)]},
     "MAX_PUSHES"),
])
def test_replay_refuses_hostile_numbers(edit: dict, needle: str,  # type: ignore[type-arg]
                                        found: tuple[int, dict, Path],  # type: ignore[type-arg]
                                        tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """Numbers that would stall a replay (a step budget from a huge window or step) or run it
    from outside the world: exit 2 with one line, before simulating."""
    doc = {**json.loads((found[2] / "counterexample.json").read_text()), **edit}
    case = tmp_path / "hostile.json"
    case.write_text(json.dumps(doc))
    code, _, err = _run(["replay", str(case)], capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("error:") and needle in err


@pytest.mark.slow  # a subprocess that draws 600 cases before it is interrupted (~5-10 s)
def test_ctrl_c_writes_a_partial_report(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO), "MPLBACKEND": "Agg"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "tli_verify.cli", "verify", "--task", "scoop", "--examples",
         "600", "--no-shrink", "--workers", "1", "--batch-size", "10", "--out",
         str(tmp_path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        # SIGINT as an interactive shell leaves it, even when this run inherited it ignored
        # (make test &, nohup): else the child would ignore the Ctrl-C this test sends
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stderr is not None
    seen = []
    for line in proc.stderr:  # wait until the simulation started
        seen.append(line)
        if "simulating" in line:
            break
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    err = "".join(seen) + err
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1].startswith("error: interrupted")
    # a partial result never replaces a complete one: the report goes to OUT/partial/
    assert not (tmp_path / "campaign.json").exists()
    rec = json.loads((tmp_path / "partial" / "campaign.json").read_text())
    assert rec["partial"] is True and rec["runs"] < 600
    assert "PARTIAL" in (tmp_path / "partial" / "campaign.md").read_text()


def _die_once(item: tuple[str, int]) -> int:
    """A batch function whose worker dies (os._exit) the first time it sees item 2."""
    marker, value = item
    if value == 2 and not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(3)
    return value * value


def _always_die(item: int) -> int:
    os._exit(3)


def test_dead_worker_is_reported_and_its_batch_rerun(tmp_path: Path) -> None:
    events: list[str] = []
    backend = ProcessBackend(workers=2, on_event=events.append)
    marker = str(tmp_path / "marker")
    try:
        got = dict(backend.map_unordered(_die_once, [(marker, v) for v in range(6)]))
    finally:
        backend.close()
    assert got == {i: i * i for i in range(6)}
    assert any("worker lost" in e for e in events)
    assert Path(marker).exists()


def test_worker_dying_every_time_raises_worker_lost() -> None:
    backend = make_backend("process", workers=1)
    try:
        with pytest.raises(WorkerLost, match="died"):
            list(backend.map_unordered(_always_die, [1]))
    finally:
        backend.close()


@pytest.fixture(scope="module")
def broken(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The shipped model with mode b's attractor moved into white (above the soup): b's DS
    leaves yellow, a's DS brings the spoon back, forever (a deliberately broken model; its
    certificate is re-issued, stability does not depend on x*)."""
    from tli_verify.certification.certificate import issue_certificate, write_certificate
    from tli_verify.io import bundled_dir

    d = tmp_path_factory.mktemp("broken")
    doc = json.loads((bundled_dir("models") / "scoop.model.json").read_text())
    doc["modes"]["b"]["attractor"] = [-2.5, -2.0]
    doc["spec"] = str((bundled_dir("specs") / "scoop.toml").resolve())
    doc["source"] = {}
    model, cert = d / "broken.model.json", d / "broken.cert.json"
    model.write_text(json.dumps(doc))
    write_certificate(issue_certificate(model, cert_path=cert, dt="1/100"), cert)
    return model, cert


def test_looping_model_is_found_and_shrunk_to_no_perturbation(
        broken: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    model, cert = broken
    code, text, _ = _run(["verify", "--task", "scoop", "--model", str(model),
                          "--certificate", str(cert), "--examples", "12", "--no-modulation",
                          "--backend", "serial", "--json", "--out", str(tmp_path)], capsys)
    rec = json.loads(text)
    assert code == 1
    assert rec["violations"]["looping"] >= 1
    ce = rec["counterexample"]
    assert ce["expected"]["violation"] == "looping"
    assert ce["perturbations"] == []  # the nominal run already loops: the minimal sequence
    assert ce["expected"]["oracle_modes"].startswith("ababab")
    assert rec["simulations_to_first_counterexample"] == 1
    code, text, _ = _run(["replay", str(tmp_path / "counterexample.json"), "--json"], capsys)
    assert code == 1 and json.loads(text)["reproduced"] is True


def test_replay_notes_changed_files(found: tuple[int, dict, Path],  # type: ignore[type-arg]
                                    tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    doc = json.loads((found[2] / "counterexample.json").read_text())
    doc["files"]["model"]["sha256"] = "0" * 64
    case = tmp_path / "stale.json"
    case.write_text(json.dumps(doc))
    code, text, err = _run(["replay", str(case), "--json"], capsys)
    assert code == 1 and json.loads(text)["reproduced"] is True
    assert err.startswith("note: model:") and "changed since the case was saved" in err


# --------------------------------------------------------------------------------------------
# a 3-D task of the test's own (tests/support/drawer3d.py)
# --------------------------------------------------------------------------------------------


@pytest.mark.slow  # a 3-D learn and a shrinking campaign: a minute on 2 cores
def test_verify_on_a_3d_task_reports_3d_pushes(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """``tli verify`` on a 3-D task written as files (task, spec, ``tli demos``, ``tli learn``,
    ``tli certify``): the counterexample's start and pushes carry 3 coordinates in the JSON
    record, counterexample.json and campaign.md, and the printed summary shows all 3 (a push
    (0, 0, -3) was once printed as "(0, 0)"). Without modulation, seed 1 finds an unprovoked
    exit b -> a after one push within 30 examples (the drawer is robust: most seeds find
    nothing in 30)."""
    import re

    project = write_project(tmp_path / "drawer")
    spec = project / "specs" / "drawer.toml"
    model = project / "models" / "drawer.model.json"
    code, out, err = _run(["demos", str(project / "tasks" / "drawer.toml")], capsys)
    assert code == 0, err
    demos = sorted((project / "demos").glob("drawer_*.csv"))
    assert [p.name for p in demos] == ["drawer_1.csv", "drawer_2.csv", "drawer_3.csv"]
    code, out, err = _run(["learn", *map(str, demos), "--spec", str(spec), "-o", str(model)],
                          capsys)
    assert code == 0, err
    code, out, err = _run(["certify", str(model)], capsys)
    assert code == 0 and "dt = 1/100" in out, err  # the task's control period, by default
    assert (project / "certificates" / "drawer.cert.json").is_file()

    args = ["verify", "--spec", str(spec), "--examples", "30", "--seed", "1", "--no-modulation",
            "--backend", "serial"]
    code, text, err = _run([*args, "--json", "--out", str(tmp_path / "json")], capsys)
    rec = json.loads(text)
    assert code == 1, (rec["violations"], err)
    assert rec["task"]["name"] == "drawer" and rec["runs"] == 30
    ce = rec["counterexample"]
    assert ce is not None and ce["shrunk"] is True
    assert len(ce["start"]) == 3
    pushes = ce["perturbations"]
    assert pushes, "the counterexample needs a push (the nominal run satisfies the task)"
    assert all(len(p["displacement"]) == 3 for p in pushes), pushes
    saved = json.loads((tmp_path / "json" / "counterexample.json").read_text())
    assert saved["perturbations"] == pushes and len(saved["start"]) == 3
    # the report lists every push with its 3 coordinates
    md = (tmp_path / "json" / "campaign.md").read_text()
    listed = re.findall(r"^- step (\d+): \w+ displacement \[([^\]]*)\]", md, flags=re.M)
    assert [(int(s), [float(v) for v in d.split(",")]) for s, d in listed] == [
        (p["step"], p["displacement"]) for p in pushes], md
    # the printed summary shows all 3 coordinates of every push (not shrunk, to save time: the
    # counterexample as drawn, saved in that run's counterexample.json)
    code, text, err = _run([*args, "--no-shrink", "--out", str(tmp_path / "text")], capsys)
    assert code == 1, err
    drawn = json.loads((tmp_path / "text" / "counterexample.json").read_text())["perturbations"]
    assert drawn and all(len(p["displacement"]) == 3 for p in drawn), drawn
    line = next(ln for ln in text.splitlines() if ln.startswith("first counterexample"))
    printed = re.findall(r"step (\d+): \w+ \(([^)]*)\)", line)
    assert [(int(s), d.split(", ")) for s, d in printed] == [
        (p["step"], [f"{v:.3g}" for v in p["displacement"]]) for p in drawn], line
