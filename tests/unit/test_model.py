"""The model file: schema, semantic validation with field paths, round trip, velocity API."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tli_verify
from tli_verify.boundary.cuts import Cut
from tli_verify.boundary.modulation import modulate
from tli_verify.commands import exit_code
from tli_verify.errors import ModelError
from tli_verify.model.serialize import load_model, model_from_dict, model_to_dict, save_model


def doc() -> dict[str, Any]:
    return {
        "schema_version": 1,
        "state_names": ["x0", "x1"],
        "spec": None,
        "modes": {
            "a": {
                "attractor": [1.0, 1.0],
                "P": [[1.0, 0.0], [0.0, 2.0]],
                "components": [
                    {"prior": 0.25, "mean": [0.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]],
                     "A": [[-1.0, 0.0], [0.0, -1.0]]},
                    {"prior": 0.75, "mean": [3.0, 0.0], "cov": [[2.0, 0.1], [0.1, 1.0]],
                     "A": [[-2.0, 1.0], [-0.5, -1.0]]},
                ],
                "cuts": [],
            },
            "b->c": {
                "mode": "b", "next_mode": "c",
                "attractor": [0.0, 0.0],
                "P": [[1.0, 0.0], [0.0, 1.0]],
                "components": [{"prior": 1.0, "mean": [0.0, 0.0],
                                "cov": [[1.0, 0.0], [0.0, 1.0]],
                                "A": [[-1.0, 0.0], [0.0, -1.0]]}],
                "cuts": [{"normal": [1.0, 0.0], "point": [2.0, 0.0]}],
            },
        },
    }


def write(tmp_path: Path, data: Any, name: str = "m.json") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


def test_round_trip_is_bit_exact(tmp_path: Path) -> None:
    model = load_model(write(tmp_path, doc()))
    out = tmp_path / "again.json"
    save_model(model, out)
    again = load_model(out)
    for key in model.modes:
        for name in ("attractor", "P", "A", "covs", "means", "priors"):
            assert np.array_equal(getattr(model.modes[key].ds, name),
                                  getattr(again.modes[key].ds, name))
    assert model_to_dict(again)["modes"]["b->c"]["cuts"] == doc()["modes"]["b->c"]["cuts"]
    assert out.read_text().endswith("\n")


def test_public_api_and_velocity(tmp_path: Path) -> None:
    path = write(tmp_path, doc())
    model = tli_verify.load_model(path)
    X = np.random.default_rng(0).normal(size=(7, 2))
    V = model.velocity(X, mode="a")
    assert V.shape == (7, 2)
    np.testing.assert_array_equal(V, model.modes["a"].ds.velocity(X))
    assert model.velocity(X[0], mode="a").shape == (2,)
    with pytest.raises(ValueError, match="read-only"):
        model.modes["a"].ds.A[0, 0, 0] = 1.0


def test_velocity_applies_the_cuts(tmp_path: Path) -> None:
    model = load_model(write(tmp_path, doc()))
    X = np.array([[1.5, 0.2], [1.9, -0.3], [-1.0, 1.0], [1.0, 5.0]])
    mm = model.modes["b->c"]
    F = mm.ds.velocity(X)
    expected = modulate(X, F, mm.cuts, mm.ds.attractor, lyapunov=mm.ds.P)
    got = model.velocity(X, mode="b", next_mode="c")
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(model.nominal_velocity(X, mode="b->c"), F)
    # an outward flow inside the cut is changed by the modulation (paper eq. 7)
    outward = np.array([[1.5, 1.0]])
    flipped = model_from_dict({**doc(), "modes": {"b->c": {
        **doc()["modes"]["b->c"],
        "components": [{"prior": 1.0, "mean": [0.0, 0.0], "cov": [[1.0, 0.0], [0.0, 1.0]],
                        "A": [[-1.0, 3.0], [-3.0, -1.0]]}]}}})
    nominal = flipped.nominal_velocity(outward, mode="b->c")
    assert nominal[0, 0] > 0  # points out through the cut x0 = 2
    modulated = flipped.velocity(outward, mode="b->c")
    assert modulated[0, 0] < nominal[0, 0]


def test_key_resolution(tmp_path: Path) -> None:
    model = load_model(write(tmp_path, doc()))
    assert model.key("a") == "a"
    assert model.key("a", "zzz") == "a"
    assert model.key("b", "c") == "b->c"
    with pytest.raises(ModelError, match=r"no DS for 'b'; per-transition DS of this mode: "
                                         r"b->c \(pass next_mode\)"):
        model.key("b")
    with pytest.raises(ModelError, match="no DS for 'q'; known keys: a, b->c"):
        model.velocity(np.zeros((1, 2)), mode="q")


def test_with_cuts_returns_a_new_model(tmp_path: Path) -> None:
    model = load_model(write(tmp_path, doc()))
    cut = Cut(normal=np.array([0.0, 1.0]), point=np.array([1.0, 3.0]))
    cut_model = model.with_cuts("a", [cut])
    assert model.modes["a"].cuts == ()
    assert cut_model.modes["a"].cuts == (cut,)


def test_velocity_with_cuts_and_control_period(tmp_path: Path) -> None:
    """A mode with cuts returns the guarded modulation, and ``dt`` is honoured: a step of the
    continuous-time field would cross a cut the flow runs into, the ``dt`` one does not."""
    from tli_verify.boundary.modulation import modulate

    model = load_model(write(tmp_path, doc()))
    ds = model.modes["a"].ds
    x0 = ds.attractor + np.array([2.0, -1.0])
    f0 = ds.velocity(x0)
    w = f0 / np.linalg.norm(f0) + (x0 - ds.attractor) / np.linalg.norm(x0 - ds.attractor)
    w /= np.linalg.norm(w)  # the flow at x0 runs out through this plane, x* stays inside
    cut = Cut(normal=w, point=x0 + 1e-3 * w)
    cut_model = model.with_cuts("a", [cut])
    X = x0[None, :]
    dt = 10.0 * float(w @ (cut.point - ds.attractor)) / float(w @ f0)
    np.testing.assert_array_equal(
        cut_model.velocity(X, mode="a", dt=dt),
        modulate(X, ds.velocity(X), [cut], ds.attractor, lyapunov=ds.P, dt=dt))
    crossing = X + dt * cut_model.velocity(X, mode="a")
    assert (crossing[0] - cut.point) @ w > 0  # the continuous-time field, held for dt, leaves
    step = X + dt * cut_model.velocity(X, mode="a", dt=dt)
    assert (step[0] - cut.point) @ w <= 1e-12
    assert cut_model.velocity(x0, mode="a", dt=dt).shape == (2,)
    for bad in (-1.0, 0.0, "x"):  # validated with and without cuts
        for m in (model, cut_model):
            with pytest.raises(ModelError, match="dt"):
                m.velocity(X, mode="a", dt=bad)  # type: ignore[arg-type]


def mutate(path: list[str | int], value: Any) -> dict[str, Any]:
    data = copy.deepcopy(doc())
    node: Any = data
    for part in path[:-1]:
        node = node[part]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


BAD = [
    (["modes", "a", "components", 1, "cov"], [[1.0, 2.0], [2.0, 1.0]],
     r"m\.json: modes\.a\.components\[1\]\.cov: not symmetric positive definite"),
    (["modes", "a", "components", 0, "cov"], [[1.0, 0.5], [0.0, 1.0]],
     r"modes\.a\.components\[0\]\.cov: not symmetric \(entry \[0\]\[1\] != \[1\]\[0\]\)"),
    (["modes", "a", "P"], [[1.0, 0.5], [0.4, 1.0]], r"modes\.a\.P: not symmetric"),
    (["modes", "a", "P"], [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
     r"modes\.a\.P: expected shape 2x2, got 2x3"),
    (["modes", "a", "attractor"], [1.0], r"modes\.a\.attractor: expected shape 2, got 1"),
    (["modes", "a", "components", 0, "prior"], -0.2,
     r"modes\.a\.components\[0\]\.prior: -0\.2 is less than or equal to the minimum of 0"),
    (["modes", "a", "components", 0, "prior"], 0.5,
     r"modes\.a\.components: priors sum to 1\.25, not 1"),
    (["modes", "a", "components", 0, "A"], KeyError,
     r"modes\.a\.components\[0\]: 'A' is a required property"),
    (["modes", "a", "cuts"], KeyError, r"modes\.a: 'cuts' is a required property"),
    (["modes", "a", "P"], "eye", r"modes\.a\.P: 'eye' is not of type 'array'"),
    (["modes", "a", "extra"], 1, r"modes\.a: Additional properties are not allowed"),
    (["schema_version"], 2, r"schema_version: 1 was expected"),
    (["modes", "b->c", "mode"], "x",
     r"modes\[\"b->c\"\]: a per-transition key '<mode>-><next>' needs \"mode\": 'b'"),
    (["modes", "b->c", "cuts", 0, "normal"], [2.0, 0.0],
     r"modes\[\"b->c\"\]\.cuts\[0\]: cut normal must be a unit vector"),
    (["modes", "b->c", "cuts", 0, "point"], [2.0, 0.0, 1.0],
     r"modes\[\"b->c\"\]\.cuts\[0\]: cut normal has shape \(2,\) but point has \(3,\)"),
    (["modes", "b->c", "cuts", 0, "point"], [-1.0, 0.0],
     r"modes\[\"b->c\"\]\.cuts: cuts\[0\] leaves the attractor outside"),
    (["modes"], {}, r"modes: \{\} should be non-empty"),
]


@pytest.mark.parametrize(("path", "value", "message"), BAD)
def test_validation_names_file_and_field(tmp_path: Path, path: list[str | int], value: Any,
                                         message: str) -> None:
    with pytest.raises(ModelError, match=message) as info:
        load_model(write(tmp_path, mutate(path, value)))
    assert exit_code(info.value) == 2
    assert str(info.value).startswith(str(tmp_path / "m.json"))


def test_json_syntax_errors(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{\n  "schema_version": 1,\n  "modes": [\n}', encoding="utf-8")
    with pytest.raises(ModelError, match=r"bad\.json: line 4, column 1: invalid JSON"):
        load_model(bad)
    nan = tmp_path / "nan.json"
    nan.write_text(json.dumps(doc()).replace("0.25", "NaN"), encoding="utf-8")
    with pytest.raises(ModelError, match="NaN is not allowed"):
        load_model(nan)
    with pytest.raises(ModelError, match="cannot read model file"):
        load_model(tmp_path / "missing.json")


def test_bundled_model_loads(repo: Path) -> None:
    model = load_model(repo / "models" / "scoop.model.json")
    assert sorted(model.modes) == ["a", "b", "c", "d"]
    assert model.spec_path == (repo / "specs" / "scoop.toml").resolve()  # as the OS opens it
    assert model.dim == 2
    for key, mm in model.modes.items():
        assert mm.fit is not None
        assert mm.fit["status"] == "optimal"
        np.testing.assert_array_equal(model.velocity(mm.ds.attractor[None], mode=key), [[0, 0]])


# --------------------------------------------------------------------------------------------
# Every number within a declared range, covariances safely invertible
# --------------------------------------------------------------------------------------------

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tli_verify.limits import (  # noqa: E402
    COV_MAX_CONDITION,
    COV_MIN_EIGENVALUE,
    MAX_ABS_COVARIANCE,
    MAX_ABS_VALUE,
)
from tli_verify.model.types import numeric_limits  # noqa: E402

HOSTILE = st.one_of(
    st.floats(min_value=MAX_ABS_VALUE, exclude_min=True, allow_infinity=False),
    st.floats(max_value=-MAX_ABS_VALUE, exclude_max=True, allow_infinity=False),
    st.integers(min_value=10**7, max_value=10**400),
)
NUMERIC_FIELDS = [["attractor", 0], ["P", 0, 1], ["components", 0, "mean", 1],
                  ["components", 0, "cov", 0, 0], ["components", 0, "A", 1, 0],
                  ["components", 0, "prior"]]


@settings(max_examples=60)
@given(value=HOSTILE, field=st.sampled_from(NUMERIC_FIELDS), sign=st.sampled_from([1, -1]))
def test_out_of_range_numbers_are_refused_naming_the_field(value: float | int,
                                                           field: list[str | int],
                                                           sign: int) -> None:
    bundled = json.loads((Path(__file__).resolve().parents[2] / "models" /
                          "scoop.model.json").read_text())
    key = sorted(bundled["modes"])[0]
    node: Any = bundled["modes"][key]
    for part in field[:-1]:
        node = node[part]
    if "cov" in field:  # covariances have squared units: their bound is MAX_ABS_VALUE**2
        value = value * 10**6 if isinstance(value, int) else value * MAX_ABS_VALUE
    node[field[-1]] = sign * value
    limit = ("MAX_ABS_COVARIANCE" if "cov" in field else
             "MAX_ABS_VALUE" if field[-1] != "prior" or sign * value > 0 else "prior")
    with pytest.raises(ModelError, match=limit) as info:
        model_from_dict(bundled, where="m.json")
    shown = ".".join(str(p) for p in field if isinstance(p, str))
    assert f"modes.{key}." in str(info.value)
    assert shown.split(".")[-1] in str(info.value)


@settings(max_examples=80)
@given(lam=st.one_of(st.floats(min_value=5e-324, max_value=1e-90),
                     st.floats(min_value=1e-90, max_value=1e13)),
       ratio=st.floats(min_value=1.0, max_value=1e20))
def test_covariances_are_safely_invertible_or_refused(lam: float, ratio: float) -> None:
    """cov = diag(lam, lam * ratio): loads iff lam >= COV_MIN_EIGENVALUE and ratio <=
    COV_MAX_CONDITION (and in range); a loaded model has finite velocities at states within
    the declared range, even at its corners."""
    bundled = json.loads((Path(__file__).resolve().parents[2] / "models" /
                          "scoop.model.json").read_text())
    key = sorted(bundled["modes"])[0]
    bundled["modes"][key]["components"][0]["cov"] = [[lam, 0.0], [0.0, lam * ratio]]
    ok = (lam >= COV_MIN_EIGENVALUE and lam * ratio <= MAX_ABS_COVARIANCE
          and (lam * ratio) / lam <= COV_MAX_CONDITION)
    if not ok:
        with pytest.raises(ModelError, match=rf"modes\.{key}\.components\[0\]\.cov"):
            model_from_dict(bundled, where="m.json")
        return
    model = model_from_dict(bundled, where="m.json")
    corners = np.array([[a, b] for a in (-MAX_ABS_VALUE, 0.0, MAX_ABS_VALUE)
                        for b in (-MAX_ABS_VALUE, 0.0, MAX_ABS_VALUE)])
    v = model.velocity(corners, key)
    assert np.all(np.isfinite(v))


@pytest.mark.parametrize("n", [1, 2, 5])
def test_velocity_is_finite_at_the_extremes_of_the_declared_ranges(n: int) -> None:
    """The worst model the limits admit -- means and attractor at the range's edge, the
    thinnest allowed covariances, the largest A_k -- still has finite, well-defined velocities
    at every corner of the state box |x_i| <= MAX_ABS_VALUE."""
    from tli_verify.ds.lpvds import LPVDS

    thin = COV_MIN_EIGENVALUE * np.eye(n)
    wide = np.diag([COV_MIN_EIGENVALUE * COV_MAX_CONDITION] * n)
    ds = LPVDS(attractor=np.full(n, MAX_ABS_VALUE), priors=np.array([0.5, 0.5]),
               means=np.stack([np.full(n, MAX_ABS_VALUE), np.full(n, -MAX_ABS_VALUE)]),
               covs=np.stack([thin, wide]),
               A=np.stack([-MAX_ABS_VALUE * np.eye(n), -np.eye(n)]), P=np.eye(n))
    corners = np.array(np.meshgrid(*[[-MAX_ABS_VALUE, 0.0, MAX_ABS_VALUE]] * n)).reshape(n, -1).T
    gamma = ds._mix.posterior(corners)
    assert np.all(np.isfinite(gamma)) and np.all(gamma >= 0)
    np.testing.assert_allclose(gamma.sum(axis=1), 1.0)
    assert np.all(np.isfinite(ds.velocity(corners)))


def test_numeric_limits_are_the_enforced_ones() -> None:
    limits = numeric_limits()
    assert limits["max_abs_value"] == MAX_ABS_VALUE
    assert limits["max_abs_covariance"] == MAX_ABS_COVARIANCE
    assert limits["cov_min_eigenvalue"] == COV_MIN_EIGENVALUE
    assert limits["cov_max_condition"] == COV_MAX_CONDITION
    assert json.loads(json.dumps(limits)) == limits


def test_number_overflowing_a_double_is_refused(tmp_path: Path) -> None:
    text = (Path(__file__).resolve().parents[2] / "models" / "scoop.model.json").read_text()
    bad = tmp_path / "m.json"
    bad.write_text(text.replace('"attractor": [', '"attractor": [1e400, ', 1))
    with pytest.raises(ModelError, match="overflows"):
        load_model(bad)
