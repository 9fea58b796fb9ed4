"""``tli sim franka``: the closed loop behind the certificate."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("mujoco")

from tests.support.cli import json_records, run
from tests.support.sim import copy_franka_project
from tli_verify.cli import main

pytestmark = pytest.mark.sim


def _project(tmp: Path) -> Path:
    """A copy of the Franka scoop spec, model and certificate; its certificates dir."""
    copy_franka_project(tmp)
    return tmp / "certificates"


def test_one_nominal_trial_scoops_and_delivers(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["sim", "franka", "--trials", "1", "--seed", "1", "--no-perturb", "--json",
                 "--duration", "14"])
    out = capsys.readouterr().out
    trial, summary = json_records(out)
    assert code == (0 if trial["success"] else 1)
    assert trial["success"] is True and int(trial["delivered"]) >= 1  # type: ignore[call-overload]
    seq = str(trial["mode_sequence"]).split()
    assert seq[:2] == ["a", "b"] and seq[-1] == "d" and "c" in seq
    assert summary["successes"] == 1 and summary["trials"] == 1


def test_tampered_certificate_is_refused_naming_it(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    certs = _project(tmp_path)
    data = json.loads((certs / "franka-scoop.cert.json").read_text())
    data["dt"] = "1/10"  # claim a longer control period than was proven
    (certs / "franka-scoop.cert.json").write_text(json.dumps(data))
    code = main(["sim", "franka", "--certificates", str(certs)])
    err = capsys.readouterr().err
    assert code == 1
    assert err.startswith("error: ") and err.count("\n") == 1
    assert str(certs / "franka-scoop.cert.json") in err


def test_missing_certificate_is_refused(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    certs = _project(tmp_path)
    (certs / "franka-scoop.cert.json").unlink()
    code = main(["sim", "franka", "--certificates", str(certs)])
    err = capsys.readouterr().err
    assert code == 1 and "franka-scoop.cert.json" in err and err.count("\n") == 1


def test_a_retrained_model_is_refused(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The model changed after certification (one number): the certificate no longer covers
    it."""
    certs = _project(tmp_path)
    model = tmp_path / "models" / "franka-scoop.model.json"
    data = json.loads(model.read_text())
    mode = next(iter(data["modes"].values()))
    mode["attractor"][0] += 1e-3
    model.write_text(json.dumps(data))
    code = main(["sim", "franka", "--certificates", str(certs)])
    err = capsys.readouterr().err
    assert code == 1 and str(certs / "franka-scoop.cert.json") in err


def test_the_untampered_copy_is_accepted(tmp_path: Path) -> None:
    """The control for the tamper test: a byte-identical copy passes the check."""
    from tli_verify.sim.franka_project import load_policy

    certs = _project(tmp_path)
    policy = load_policy("LTL-DS", certificates=certs)
    assert policy.mode == "" and abs(policy.dt - 0.02) < 1e-12


@pytest.mark.parametrize("argv", [
    ["sim", "franka", "--trials", "0"],
    ["sim", "franka", "--trials", "x"],
    ["sim", "franka", "--seed", "-1"],
    ["sim", "franka", "--no-modulation", "--no-replan"],
    ["sim", "franka", "--duration", "0"],
    ["sim", "franka", "--certificates", "/nonexistent/dir"],
    ["sim"],
    ["sim", "cartpole"],
    ["sim", "franka", "--robot", "ur5"],
    ["sim", "franka", "--robot", "hand"],
    ["sim", "franka", "--controller", "impedance"],
    ["sim", "franka", "--robot", "free-tool", "--controller", "passive"],
    ["sim", "franka", "--sensors", "camera"],
])
def test_bad_arguments_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1


def test_fig9_plot_is_written(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fig9.png"
    code = main(["sim", "franka", "--no-perturb", "--duration", "0.5", "--fig9", str(out)])
    assert code == 1  # half a second delivers nothing: the trial fails, the plot is written
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "0/1 trials" in capsys.readouterr().out


@pytest.mark.parametrize(("flag", "sub", "name"), [
    ("--fig9", "models", "franka-scoop.model.json"),
    ("--video", "certificates", "franka-scoop.cert.json"),
    ("--fig9", "specs", "franka-scoop.toml"),
])
def test_outputs_never_overwrite_the_project(flag: str, sub: str, name: str, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    certs = _project(tmp_path)
    victim = tmp_path / sub / name
    before = victim.read_bytes()
    code = main(["sim", "franka", "--certificates", str(certs), flag, str(victim)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    assert "would overwrite the input file" in err
    assert victim.read_bytes() == before

