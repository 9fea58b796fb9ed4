"""``tli run``: one closed-loop episode on the scoop world (shipped model and certificate)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.support.cli import run
from tli_verify.io import bundled_dir


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    return run(capsys, *argv)


def test_json_fields_and_success(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(["run", "--task", "scoop", "--seed", "2", "--random-start",
                           "--perturb", "random:3",
                           "--out", str(tmp_path), "--json"], capsys)
    rec = json.loads(out)
    assert code == 0 and rec["success"] is True, err
    for k in ("mode_trace", "automaton_states", "events", "cuts_added", "success", "sim_time",
              "seconds", "perturbations"):
        assert k in rec
    assert rec["mode_sequence"].startswith("a") and rec["mode_sequence"].endswith("d")
    assert rec["mode_trace"][0] == ["a", 0] and rec["mode_trace"][-1][0] == "d"
    assert len(rec["perturbations"]) == 3
    fired = [p for p in rec["perturbations"] if p["step"] <= rec["steps"]]
    assert fired and sum(e["event"] == "Perturbation" for e in rec["events"]) == len(fired)
    assert rec["cuts_added"] == sum(e["event"] == "CutAdded" for e in rec["events"])
    assert json.loads((tmp_path / "run.json").read_text()) == rec
    assert (tmp_path / "run.png").stat().st_size > 1000


def test_animation_on_request(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``--animate N``: run.gif with N frames, the last one after the cut was learned."""
    from PIL import Image

    code, out, _ = _run(["run", "--task", "scoop", "--start=-5.0,4.0", "--perturb",
                         "957:6.09,6.01", "--animate", "6", "--out", str(tmp_path), "--json"],
                        capsys)
    rec = json.loads(out)
    assert code == 0 and rec["cuts_added"] == 1
    assert rec["animation"] == str(tmp_path / "run.gif")
    with Image.open(tmp_path / "run.gif") as gif:
        assert gif.format == "GIF" and gif.n_frames == 6
        first = np.asarray(gif.convert("RGB"))
        gif.seek(5)
        assert not np.array_equal(first, np.asarray(gif.convert("RGB")))  # the path moved
    assert not (tmp_path / "run.gif").with_name("run.gif.tmp").exists()


def test_no_modulation_differs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # seed 19: the perturbations leave the spoon where the unmodulated system loops a -> b
    # -> a ... (Fig. 7); LTL-DS cuts the b -> a failure once and reaches d
    code1, out1, _ = _run(["run", "--task", "scoop", "--seed", "19", "--random-start",
                           "--perturb", "random:3",
                           "--out", str(tmp_path / "a"), "--json"], capsys)
    code2, out2, _ = _run(["run", "--task", "scoop", "--seed", "19", "--random-start",
                           "--perturb", "random:3",
                           "--no-modulation", "--out", str(tmp_path / "b"), "--json"], capsys)
    a, b = json.loads(out1), json.loads(out2)
    assert a["perturbations"] == b["perturbations"]
    assert a["cuts_added"] >= 1 and b["cuts_added"] == 0
    assert a["mode_trace"] != b["mode_trace"]
    assert (code1, a["success"]) == (0, True) and (code2, b["success"]) == (1, False)
    assert b["mode_sequence"].startswith("ababab") and b["steps"] == 3000


def test_explicit_perturbation_is_applied(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(["run", "--task", "scoop", "--start=-5,4", "--perturb", "50:0,-9",
                         "--out", str(tmp_path), "--json"], capsys)
    rec = json.loads(out)
    assert rec["start"] == [-5.0, 4.0]
    assert rec["perturbations"] == [{"step": 50, "displacement": [0.0, -9.0]}]
    # pushed from white straight into the soup (yellow): mode b right after step 50
    trace = dict((m, t) for m, t in rec["mode_trace"])
    assert trace["b"] == 50 and code == 0


@pytest.mark.parametrize("args", [
    ["--task", "nope"],
    ["--task", "cooking", "--spec", "specs/scoop.toml"],  # not the model's spec
    ["--task", "scoop", "--perturb", "3:x"],
    ["--task", "scoop", "--perturb", "0:1,1"],
    ["--task", "scoop", "--perturb", "random:-1"],
    ["--task", "scoop", "--perturb", "5:1,1", "--perturb", "5:2,2"],
    ["--task", "scoop", "--perturb", "5:1,nan"],
    ["--task", "scoop", "--start", "20,0"],
    ["--task", "scoop", "--animate", "1"],
    ["--task", "scoop", "--animate", "nan"],
])
def test_bad_arguments_exit_2_with_one_error_line(args: list[str], tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(["run", *args, "--out", str(tmp_path)], capsys)
    assert code == 2
    assert err.startswith("error:") and err.count("\n") == 1 and "Traceback" not in err
    assert out == ""


def test_tampered_model_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = bundled_dir("models").parent
    for d in ("models", "certificates", "specs"):
        (tmp_path / d).mkdir()
    shutil.copy(root / "specs" / "scoop.toml", tmp_path / "specs")
    shutil.copy(root / "certificates" / "scoop.cert.json", tmp_path / "certificates")
    doc = json.loads((root / "models" / "scoop.model.json").read_text())
    doc["modes"]["b"]["attractor"][0] += 0.5  # a forged DS the certificate does not cover
    (tmp_path / "models" / "scoop.model.json").write_text(json.dumps(doc))
    code, out, err = _run(["run", "--task", "scoop",
                           "--model", str(tmp_path / "models" / "scoop.model.json"),
                           "--certificate", str(tmp_path / "certificates" / "scoop.cert.json"),
                           "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and err.startswith("error:") and "refused" in err
    assert err.count("\n") == 1 and out == ""
    assert not (tmp_path / "o" / "run.json").exists()


def test_uncertified_pair_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    root = bundled_dir("models").parent
    (tmp_path / "models").mkdir()
    shutil.copytree(root / "specs", tmp_path / "specs")  # the spec the model names
    shutil.copy(root / "models" / "scoop.model.json", tmp_path / "models" / "m.model.json")
    # the bundled certificate (covers models/scoop.model.json, not the copy); a --model alone
    # now takes the certificate of its project layout (certificates/m.cert.json), so pass it
    code, _, err = _run(["run", "--task", "scoop", "--model",
                         str(tmp_path / "models" / "m.model.json"),
                         "--certificate", str(root / "certificates" / "scoop.cert.json"),
                         "--out", str(tmp_path / "o")], capsys)
    assert code == 1 and "refused" in err and err.count("\n") == 1


def test_learned_cuts_saved_certified_and_reused(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """-o saves the model with the episode's cut and a re-issued certificate; the pair runs
    (the executive accepts it) and the failure the cut was learned from is not repeated."""
    from tli_verify.certification.certificate import check_certificate
    from tli_verify.model.serialize import load_model

    saved = tmp_path / "m" / "learned.model.json"
    args = ["run", "--task", "scoop", "--seed", "19", "--random-start",
            "--perturb", "random:3", "--json"]
    code, out, err = _run([*args, "--out", str(tmp_path / "a"), "-o", str(saved)], capsys)
    first = json.loads(out)
    assert code == 0 and first["cuts_added"] == 1, err
    cert = tmp_path / "m" / "learned.cert.json"
    assert first["saved"] == {"model": str(saved), "certificate": str(cert)}
    assert check_certificate(cert).ok
    assert sum(len(mm.cuts) for mm in load_model(saved).modes.values()) >= 1
    code, out, err = _run([*args, "--out", str(tmp_path / "b"), "--model", str(saved),
                           "--certificate", str(cert)], capsys)
    second = json.loads(out)
    assert code == 0, err
    assert second["cuts_added"] == 0
    fails = [e for e in second["events"] if e["event"] == "InvarianceFailure"]
    assert len(fails) < sum(e["event"] == "InvarianceFailure" for e in first["events"])


def test_world_is_the_former_name_of_task(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """One word for a task: ``--world`` is not in ``--help`` any more, still accepted with a
    note, and the same run as ``--task``."""
    code, shown, _ = _run(["run", "--help"], capsys)
    assert code == 0 and "--task" in shown and "--world" not in shown
    args = ["--start=-5.0,4.0", "--json"]
    code_old, out_old, err_old = _run(["run", "--world", "scoop", *args,
                                       "--out", str(tmp_path / "old")], capsys)
    code_new, out_new, err_new = _run(["run", "--task", "scoop", *args,
                                       "--out", str(tmp_path / "new")], capsys)
    assert (code_old, code_new) == (0, 0), err_old
    assert "note: --world is the former name of --task" in err_old
    assert "--world" not in err_new
    old, new = json.loads(out_old), json.loads(out_new)
    assert old["mode_trace"] == new["mode_trace"] and old["steps"] == new["steps"]
