"""`tli learn-orientation | certify | check-cert` on pose demonstrations the test writes:
outputs, exit codes, one error line for bad input, a forged orientation matrix refused."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from tests.support.cli import run
from tli_verify.defaults import DEFAULT_DT
from tli_verify.ds.quaternion import quat_exp

Q_STAR = np.array([math.cos(0.7), math.sin(0.7), 0.0, 0.0])  # 80 degrees about x
A_TRUE = np.array([[-0.8, 0.5, 0.0], [-0.5, -0.8, 0.0], [0.0, 0.0, -1.2]])


def _write_demos(root: Path, n: int = 4) -> list[str]:
    rng = np.random.default_rng(3)
    paths = []
    t = np.linspace(0.0, 9.0, 180)
    for i in range(n):
        xi0 = rng.normal(size=3)
        xi0 *= rng.uniform(0.6, 2.0) / np.linalg.norm(xi0)
        q = quat_exp(np.array([expm(A_TRUE * s) @ xi0 for s in t]), Q_STAR)
        q[::7] *= -1.0  # hemisphere flips, as some trackers write them
        x = np.outer(np.exp(-t), [0.1, 0.2, -0.1])
        rows = [",".join(repr(float(v)) for v in (ti, *xi, *qi[[1, 2, 3, 0]]))
                for ti, xi, qi in zip(t, x, q, strict=True)]
        path = root / f"pose_{i}.csv"
        path.write_text("# quaternion: scalar-last\ntime,x0,x1,x2,q0,q1,q2,q3\n"
                        + "\n".join(rows) + "\n", encoding="utf-8")
        paths.append(str(path))
    return paths


def _one_error(err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_learn_certify_check_and_forgery(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    demos = _write_demos(tmp_path)
    model = tmp_path / "orientation.json"
    code, out, err = run(capsys, "learn-orientation", *demos, "-o", str(model))
    assert code == 0, err
    assert "hemisphere flip(s) fixed" in out and f"wrote {model}" in out
    cert = tmp_path / "orientation.cert.json"
    code, out, err = run(capsys, "certify", str(model), "-o", str(cert))
    assert code == 0, err
    assert "exact: yes" in out and f"decrease per step at dt = {DEFAULT_DT}" in out
    code, out, err = run(capsys, "check-cert", str(cert))
    assert code == 0, err
    assert "valid (orientation DS re-checked exactly)" in out
    doc = json.loads(cert.read_text(encoding="utf-8"))
    assert doc["kind"] == "tli-verify/orientation-certificate"
    # forge one orientation matrix entry
    doc["A"][0][1][2] += 0.25
    cert.write_text(json.dumps(doc), encoding="utf-8")
    code, out, err = run(capsys, "check-cert", str(cert))
    assert code == 1
    _one_error(err, "orientation certificate does not re-check")
    assert "digest does not match" in out and "A is not the model's" in out


def test_a_nan_quaternion_is_one_error_line(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    demo = Path(_write_demos(tmp_path, n=1)[0])
    lines = demo.read_text(encoding="utf-8").splitlines()
    fields = lines[10].split(",")
    fields[5] = "NaN"
    lines[10] = ",".join(fields)
    demo.write_text("\n".join(lines) + "\n", encoding="utf-8")
    code, _, err = run(capsys, "learn-orientation", str(demo), "-o", str(tmp_path / "o.json"))
    assert code == 2
    _one_error(err, str(demo), "line 11", "'q1'", "not finite")
    assert not (tmp_path / "o.json").exists()


def test_output_over_an_input_is_refused_before_work(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    demos = _write_demos(tmp_path, n=1)
    before = Path(demos[0]).read_bytes()
    code, _, err = run(capsys, "learn-orientation", demos[0], "-o", demos[0])
    assert code == 2
    _one_error(err)
    assert Path(demos[0]).read_bytes() == before


def test_the_gate_re_checks_orientation_certificates(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    from tli_verify.deploy.gate import run_gate

    demos = _write_demos(tmp_path)
    (tmp_path / "orientation").mkdir()
    (tmp_path / "certificates").mkdir()
    model = tmp_path / "orientation" / "tool.json"
    cert = tmp_path / "certificates" / "tool.orientation.cert.json"
    assert run(capsys, "learn-orientation", *demos, "-o", str(model))[0] == 0
    assert run(capsys, "certify", str(model), "-o", str(cert))[0] == 0
    report = run_gate(tmp_path, rerun=0)
    item = next(i for i in report.items if i.kind == "certificate")
    assert item.ok and "orientation DS re-checked exactly" in item.message
    assert not report.ok  # no deployable (position) model: the gate still fails closed
    doc = json.loads(cert.read_text(encoding="utf-8"))
    doc["P"][0][0] *= 2.0
    cert.write_text(json.dumps(doc), encoding="utf-8")
    item = next(i for i in run_gate(tmp_path, rerun=0).items if i.kind == "certificate")
    assert not item.ok and "P is not the model's" in item.message
