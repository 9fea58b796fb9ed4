"""Orientation DS (issue 35, part B): quaternion maps, pose demonstrations, learning, and the
exact orientation certificate with its forgery tests. The tests write their own pose data."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from tli_verify.certification.orientation import (
    PI_LOWER,
    check_orientation_certificate,
    issue_orientation_certificate,
    write_orientation_certificate,
)
from tli_verify.defaults import DEFAULT_DT
from tli_verify.demos import load_pose_demo
from tli_verify.ds.quaternion import (
    QuaternionDS,
    canonical_hemisphere,
    learn_quaternion_ds,
    load_orientation_model,
    quat_exp,
    quat_log,
    quat_multiply,
    rotation_angle,
    write_orientation_model,
)
from tli_verify.errors import CertificateError, DemoError

Q_STAR = np.array([math.cos(0.4), 0.0, math.sin(0.4) * 0.6, math.sin(0.4) * 0.8])
A_TRUE = np.array([[-1.0, 0.6, 0.0], [-0.6, -1.0, 0.2], [0.0, -0.2, -1.5]])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


# ------------------------------------------------------------------ maps


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4),
       st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
def test_exp_inverts_log_and_the_sign_of_q_does_not_matter(ref: list[float],
                                                           xi: list[float]) -> None:
    q_star = np.array(ref) + np.array([2.0, 0.0, 0.0, 0.0])  # away from 0
    q_star = _unit(q_star)
    x = np.array(xi)
    if np.linalg.norm(x) >= math.pi - 1e-3:
        x *= (math.pi - 1e-2) / np.linalg.norm(x)
    q = quat_exp(x, q_star)
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    np.testing.assert_allclose(quat_log(q, q_star), x, atol=1e-9)
    np.testing.assert_allclose(quat_log(-q, q_star), x, atol=1e-9)  # double cover
    assert rotation_angle(q, q_star) == pytest.approx(np.linalg.norm(x), abs=1e-9)


def test_log_is_the_rotation_vector_of_the_relative_rotation() -> None:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    for _ in range(20):
        q = _unit(rng.normal(size=4))
        rel = quat_multiply(Q_STAR * [1, -1, -1, -1], q)  # q*^{-1} q
        rotvec = Rotation.from_quat(np.r_[rel[1:], rel[0]]).as_rotvec()  # scipy: scalar-last
        np.testing.assert_allclose(quat_log(q, Q_STAR), rotvec, atol=1e-10)
    assert np.all(canonical_hemisphere(-Q_STAR[None], Q_STAR) == Q_STAR)


# ------------------------------------------------------------------ pose demonstrations


def _trajectory(xi0: np.ndarray, T: int = 200, duration: float = 8.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.linspace(0.0, duration, T)
    xi = np.array([expm(A_TRUE * s) @ xi0 for s in t])
    q = quat_exp(xi, Q_STAR)
    x = np.outer(np.exp(-t), xi0) * 0.1 + np.array([0.4, 0.0, 0.3])
    return t, x, q


def _write_pose_csv(path: Path, t: np.ndarray, x: np.ndarray, q: np.ndarray, *,
                    convention: str = "scalar-first") -> None:
    cols = q if convention == "scalar-first" else q[:, [1, 2, 3, 0]]
    lines = [f"# quaternion: {convention}", "time,x0,x1,x2,q0,q1,q2,q3"]
    lines += [",".join(repr(float(v)) for v in (ti, *xi, *qi))
              for ti, xi, qi in zip(t, x, cols, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_conventions_flips_and_norms_are_cleaned_with_notes(tmp_path: Path) -> None:
    t, x, q = _trajectory(np.array([1.0, -0.5, 0.8]))
    _write_pose_csv(tmp_path / "first.csv", t, x, q)
    dirty = q.copy()
    dirty[40:] *= -1.0  # a hemisphere flip half way
    dirty[10] *= 1.3  # a non-unit sample
    _write_pose_csv(tmp_path / "last.csv", t, x, dirty, convention="scalar-last")
    a = load_pose_demo(tmp_path / "first.csv")
    b = load_pose_demo(tmp_path / "last.csv")
    assert a.notes == () and a.convention == "scalar-first"
    assert b.convention == "scalar-last"
    np.testing.assert_allclose(b.q, a.q, atol=1e-12)  # same rotations, same signs
    assert any("normalised" in n and "line 13" in n for n in b.notes)
    assert any("1 hemisphere flip" in n and "line 43" in n for n in b.notes)


@pytest.mark.parametrize(("edit", "message"), [
    (lambda lines: lines.__setitem__(7, lines[7].rsplit(",", 1)[0] + ",nan"),
     r"line 8: column 'q3': 'nan' is not finite"),
    (lambda lines: lines.pop(0), "no quaternion convention declared"),
    (lambda lines: lines.__setitem__(0, "# quaternion: zyxw"), "unknown quaternion convention"),
    (lambda lines: lines.__setitem__(5, ",".join(lines[5].split(",")[:4] + ["0"] * 4)),
     r"line 6: quaternion norm 0"),
])
def test_bad_pose_files_are_refused_naming_file_and_line(tmp_path: Path, edit: object,
                                                         message: str) -> None:
    t, x, q = _trajectory(np.array([0.5, 0.5, 0.5]), T=10)
    path = tmp_path / "bad.csv"
    _write_pose_csv(path, t, x, q)
    lines = path.read_text(encoding="utf-8").splitlines()
    edit(lines)  # type: ignore[operator]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(DemoError, match=message) as info:
        load_pose_demo(path)
    assert str(path) in str(info.value)


# ------------------------------------------------------------------ learning + certificate


@pytest.fixture(scope="module")
def learned(tmp_path_factory: pytest.TempPathFactory) -> tuple[QuaternionDS, Path]:
    root = tmp_path_factory.mktemp("pose")
    rng = np.random.default_rng(7)
    demos = []
    for i in range(5):
        xi0 = rng.normal(size=3)
        xi0 *= rng.uniform(0.8, 2.2) / np.linalg.norm(xi0)
        t, x, q = _trajectory(xi0)
        q = canonical_hemisphere(q, -Q_STAR if i % 2 else Q_STAR)  # either sign in the files
        path = root / f"demo_{i}.csv"
        _write_pose_csv(path, t, x, q, convention="scalar-last" if i % 2 else "scalar-first")
        demos.append(load_pose_demo(path))
    ds, info = learn_quaternion_ds([d.t for d in demos], [d.q for d in demos], seed=0)
    assert info.status in ("optimal", "optimal_inaccurate") and info.rate > 0
    model = root / "orientation.json"
    write_orientation_model(ds, model, fit=info)
    return ds, model


def test_the_learned_ds_reproduces_and_converges(learned: tuple[QuaternionDS, Path]) -> None:
    ds, model = learned
    assert rotation_angle(ds.attractor, Q_STAR) < 2e-3  # attractor from the demos' ends
    again = load_orientation_model(model)
    assert np.array_equal(again.A, ds.A) and np.array_equal(again.P, ds.P)
    # velocity field close to the true one on the demonstrated region
    rng = np.random.default_rng(1)
    xi = rng.normal(size=(200, 3)) * 0.5
    true = xi @ A_TRUE.T
    err = np.linalg.norm(ds.tangent.velocity(xi) - true, axis=1).mean()
    assert err < 0.25 * np.linalg.norm(true, axis=1).mean()
    # the 1 ms controller from a start 150 degrees away ends at q*, V decreasing every step
    q0 = quat_exp(np.array([0.0, 2.6, 0.3]), ds.attractor)
    run = ds.rollout(q0, dt=1e-3, steps=12000)
    V = ds.lyapunov(run)
    assert np.all(np.diff(V) < 0.0)
    assert rotation_angle(run[-1], ds.attractor) < 1e-3


def test_the_certificate_checks_exactly(learned: tuple[QuaternionDS, Path]) -> None:
    ds, model = learned
    cert = model.parent / "orientation.cert.json"
    doc = issue_orientation_certificate(model, cert)
    write_orientation_certificate(doc, cert)
    ex = doc["exact"]
    assert ex["P_positive"] and all(ex["continuous"]) and all(ex["sampled"])
    assert doc["dt"] == str(DEFAULT_DT)
    # the recorded region: V < m pi_low^2 with m <= lambda_min(P), inside |xi| < pi
    from fractions import Fraction

    m = Fraction(ex["lambda_min_P_lower"])
    assert 0 < m <= np.linalg.eigvalsh(ds.P)[0]
    assert Fraction(ex["region_V_below"]) == m * PI_LOWER**2
    assert check_orientation_certificate(cert).ok


def _forge(cert: Path, change: object, *, redigest: bool) -> None:
    from tli_verify.certification.orientation import _digest

    doc = json.loads(cert.read_text(encoding="utf-8"))
    change(doc)  # type: ignore[operator]
    if redigest:
        doc["digest"] = _digest(doc)
    cert.write_text(json.dumps(doc), encoding="utf-8")


@pytest.mark.parametrize(("redigest", "expected"), [
    (False, "digest does not match"),
    (True, "A is not the model's"),
])
def test_a_forged_orientation_matrix_is_refused(learned: tuple[QuaternionDS, Path],
                                                 tmp_path: Path, redigest: bool,
                                                 expected: str) -> None:
    _, model = learned
    cert = model.parent / f"forged_{redigest}.cert.json"
    write_orientation_certificate(issue_orientation_certificate(model, cert), cert)

    def change(doc: dict) -> None:
        doc["A"][0][0][0] *= 1.0 + 1e-12  # still stable: only the binding catches it

    _forge(cert, change, redigest=redigest)
    check = check_orientation_certificate(cert)
    assert not check.ok
    assert any(expected in f for f in check.failures)


def test_a_forged_model_and_certificate_pair_fails_the_exact_check(
        learned: tuple[QuaternionDS, Path], tmp_path: Path) -> None:
    """Forge both files consistently with an unstable A: only the exact re-check can say no."""
    ds, _ = learned
    bad_A = ds.A.copy()
    bad_A[0] = -bad_A[0]  # unstable component
    forged = QuaternionDS.from_dict({**ds.to_dict(), "A": bad_A.tolist()})
    model = tmp_path / "forged.json"
    write_orientation_model(forged, model)
    cert = tmp_path / "forged.cert.json"
    with pytest.raises(CertificateError, match="does not certify"):
        issue_orientation_certificate(model, cert)
    # a certificate made for the good model, then pointed at the forged pair
    good_model = tmp_path / "good.json"
    write_orientation_model(ds, good_model)
    write_orientation_certificate(issue_orientation_certificate(good_model, cert), cert)
    model.replace(good_model)  # the model file now holds the unstable A

    def change(doc: dict) -> None:
        from tli_verify.io import sha256_file

        doc["A"] = bad_A.tolist()
        doc["model"]["sha256"] = sha256_file(good_model)

    _forge(cert, change, redigest=True)
    check = check_orientation_certificate(cert)
    assert not check.ok
    assert any("component 0: A_k^T P + P A_k is not negative definite" in f
               for f in check.failures)
