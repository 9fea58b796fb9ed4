"""The Franka-feasible sensors (tli_verify.sim.franka_sensors) and the wrist F/T sensor."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("mujoco")

import mujoco

from tli_verify.errors import InputError, TliError
from tli_verify.sim.franka_sensors import (
    BEAD_WEIGHT,
    CONTROL_PERIOD,
    SENSOR_KINDS,
    FrankaSensors,
    SensorSettings,
    make_sensors,
)
from tli_verify.sim.scene import (
    BEAD_MASS,
    BEAD_RADIUS,
    LADLE_MASS,
    SOUP_CENTER,
    TARGET_CENTER,
    build_mocap_scene,
    ladle_quat,
    scene_ids,
)
from tli_verify.sim.sensors import ScoopSensors

G = 9.81
QUIET = SensorSettings(force_noise=0.0, force_bias=0.0, accel_noise=0.0, pose_noise=0.0,
                       calibration=0.0)
"""Noise-free settings: the sensors' logic alone."""
ABOVE_TARGET = (float(TARGET_CENTER[0]), float(TARGET_CENTER[1]), 0.12)
BETWEEN = (0.5, 0.0, 0.2)
IN_SOUP = (float(SOUP_CENTER[0]), float(SOUP_CENTER[1]) + 0.05, 0.05)


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return build_mocap_scene()


def _place(model: mujoco.MjModel, data: mujoco.MjData, pos: tuple[float, float, float],
           pitch: float = 0.0) -> None:
    """The free carrier (and the ladle under it) at ``pos``, at rest; forward dynamics."""
    jnt = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "ladle_free"))
    a, d = int(model.jnt_qposadr[jnt]), int(model.jnt_dofadr[jnt])
    data.qpos[a:a + 3] = pos
    data.qpos[a + 3:a + 7] = ladle_quat(pitch)
    data.qvel[d:d + 6] = 0.0
    mujoco.mj_forward(model, data)


def _press(model: mujoco.MjModel, data: mujoco.MjData, load: float) -> None:
    """A downward force ``load`` (N) on the ladle: what beads on the tray would weigh."""
    data.xfrc_applied[scene_ids(model).ladle_body] = [0.0, 0.0, -load, 0.0, 0.0, 0.0]
    mujoco.mj_forward(model, data)


def test_ft_reads_the_empty_ladles_weight_at_rest(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, ABOVE_TARGET, pitch=0.4)
    force, torque = FrankaSensors(model, settings=QUIET).wrench(data)
    mass = LADLE_MASS + 6 * 1e-3  # the tray, rim and handle, and the front lip's 6 segments
    np.testing.assert_allclose(force, [0.0, 0.0, mass * G], atol=1e-6)
    # the torque about the mount: the weight acting at the ladle's centre of mass
    ids = scene_ids(model)
    site = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "ladle_ft"))
    arm = data.xipos[ids.ladle_body] - data.site_xpos[site]
    np.testing.assert_allclose(torque, np.cross(arm, [0.0, 0.0, -mass * G]) * -1, atol=1e-6)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_ft_grows_by_each_bead_on_the_tray(n: int) -> None:
    from tli_verify.sim.demos import MocapRig
    from tli_verify.sim.scene import PhysicsOptions

    # the awake scene: the beads are placed by hand (qpos written), which does not wake a bead
    # that fell asleep in the soup bowl -- in a trial the ladle's contact wakes it
    rig = MocapRig(0, start=(*ABOVE_TARGET, 0.0, 0.0, 0.0),
                   physics=PhysicsOptions(sleep=False))
    sensors = FrankaSensors(rig.model, rig.ids, QUIET)
    empty = sensors.wrench(rig.data)[0][2]
    first = sensors.read(rig.data)  # tares
    assert not first.s
    tray = rig.data.site_xpos[rig.ids.tray_site].copy()
    for i in range(n):  # on the tray floor, a ring of beads
        a, d = int(rig.ids.bead_qpos[i]), int(rig.ids.bead_dof[i])
        ang = 2 * math.pi * i / n
        rad = 0.0 if n == 1 else 0.018
        rig.data.qpos[a:a + 3] = tray + np.array([rad * math.cos(ang), rad * math.sin(ang),
                                                  BEAD_RADIUS + 5e-4])
        rig.data.qpos[a + 3:a + 7] = (1.0, 0.0, 0.0, 0.0)
        rig.data.qvel[d:d + 6] = 0.0
    mujoco.mj_forward(rig.model, rig.data)
    rig.step(300)  # 0.6 s: the beads settle, the hand holds
    fz, load = [], []
    for _ in range(10):
        rig.step(10)
        fz.append(sensors.wrench(rig.data)[0][2])
        sensors.read(rig.data)
        assert sensors.last is not None
        load.append(sensors.last.load)
    assert int(sensors.truth.on_ladle(rig.data).sum()) == n
    expected = n * BEAD_MASS * G
    assert float(np.mean(fz)) - empty == pytest.approx(expected, rel=0.05)
    assert float(np.mean(load)) == pytest.approx(expected, rel=0.05)  # tared, compensated
    assert sensors.read(rig.data).s


def test_the_ladles_own_inertial_force_is_compensated(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN, pitch=0.3)
    sensors = FrankaSensors(model, settings=QUIET)
    sensors.read(data)  # tared at rest
    carrier = int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "ladle_carrier"))
    for wrench in ([0.0, 8.0, 25.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 3.0, 0.0, 1.0]):
        data.xfrc_applied[carrier] = wrench  # the hand accelerates, and turns
        mujoco.mj_forward(model, data)
        force = sensors.wrench(data)[0]
        reading = sensors.read(data)
        assert sensors.last is not None
        assert np.linalg.norm(force - [0.0, 0.0, sensors.ladle_mass * G]) > 0.1  # it moves
        assert abs(sensors.last.load) < 1e-6 and not reading.s  # but nothing is on it


def test_noise_statistics_match_the_settings(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN)
    cfg = replace(QUIET, force_noise=0.08, force_rate=500.0, pose_noise=0.002)
    per_reading = 0.08 / math.sqrt(500.0 * CONTROL_PERIOD)
    truth = FrankaSensors(model, settings=QUIET).wrench(data)[0]
    sensors = FrankaSensors(model, settings=cfg, seed=5)
    samples = [sensors.measure(data) for _ in range(4000)]
    force = np.array([m.force for m in samples])
    tray = np.array([m.tray for m in samples])
    np.testing.assert_allclose(force.std(axis=0), per_reading, rtol=0.05)
    np.testing.assert_allclose(force.mean(axis=0), truth, atol=5 * per_reading / 60)
    np.testing.assert_allclose(tray.std(axis=0), 0.002, rtol=0.05)
    np.testing.assert_allclose(tray.mean(axis=0), data.site_xpos[scene_ids(model).tray_site],
                               atol=5 * 0.002 / 60)


def test_noise_is_seeded(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN)

    def trace(seed: int) -> np.ndarray:
        sensors = make_sensors("franka", model, seed=seed)
        return np.array([[*m.force, *m.tray, m.load] for m in
                         (sensors.measure(data) for _ in range(20))])

    np.testing.assert_array_equal(trace(3), trace(3))
    assert not np.allclose(trace(3), trace(4))


def test_bias_is_tared_away(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN)
    cfg = replace(QUIET, force_bias=2.0, force_noise=0.05, tare_samples=10_000)
    sensors = FrankaSensors(model, settings=cfg, seed=1)
    loads = [sensors.measure(data).load for _ in range(2000)]
    assert abs(float(np.mean(loads))) < 5 * 0.05 / math.sqrt(10_000) + 5 * 0.05 / math.sqrt(
        20 * 2000)
    biased = [sensors.measure(data).force[2] for _ in range(200)]
    assert abs(float(np.mean(biased)) - FrankaSensors(model, settings=QUIET).wrench(data)[0][2]
               ) > 0.05  # the raw force keeps its bias (2 N std: off by more than 0.05 N)


def _switch(trace: list[bool]) -> int:
    """Index of the first reading that differs from the first one."""
    return next(i for i, v in enumerate(trace) if v != trace[0])


@pytest.mark.parametrize("latency", [0, 1, 4])
def test_latency_delays_each_switch_by_its_periods(model: mujoco.MjModel, latency: int) -> None:
    data = mujoco.MjData(model)
    fast = FrankaSensors(model, settings=replace(QUIET, load_tau=0.0, latency_s=0))
    slow = FrankaSensors(model, settings=replace(QUIET, load_tau=0.0, latency_s=latency,
                                                 latency_t=latency, latency_r=latency))
    got: dict[str, list[list[bool]]] = {"fast": [], "slow": []}
    for k in range(20):
        _place(model, data, BETWEEN if k < 8 else ABOVE_TARGET)
        _press(model, data, 0.0 if k < 12 else 5 * BEAD_WEIGHT)
        for name, sensors in (("fast", fast), ("slow", slow)):
            reading = sensors.read(data)
            got[name].append([reading.r, reading.s, reading.t])
    for i in (1, 2):  # s, t
        f = _switch([v[i] for v in got["fast"]])
        s = _switch([v[i] for v in got["slow"]])
        assert f == (12 if i == 1 else 8)
        assert s - f == latency


def test_latency_delays_r_entering_the_soup_bowl(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    sensors = FrankaSensors(model, settings=replace(QUIET, latency_r=3))
    trace = []
    for k in range(10):
        _place(model, data, BETWEEN if k < 2 else IN_SOUP)
        trace.append(sensors.read(data).r)
    assert trace == [False] * 5 + [True] * 5


def test_hysteresis_keeps_s_from_chattering_on_a_noisy_constant_load(
        model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN)
    noisy = replace(QUIET, force_noise=0.05, load_tau=0.1, s_on=0.03, s_off=0.01)
    band = FrankaSensors(model, settings=noisy, seed=2)
    none = FrankaSensors(model, settings=replace(noisy, s_off=noisy.s_on), seed=2)
    band.read(data)
    none.read(data)  # tared empty
    # constant, 1 mN above s_on: the filtered noise (3.5 mN) crosses s_on all the time, but
    # not s_off, 5.7 of its stds below
    _press(model, data, noisy.s_on + 0.001)
    with_band = [band.read(data).s for _ in range(500)]
    without = [none.read(data).s for _ in range(500)]
    flips = [int(np.sum(np.diff(np.array(t, dtype=int)) != 0)) for t in (with_band, without)]
    assert with_band[-1] and flips[0] == 1  # on once, and stays on
    assert flips[1] > 10  # the same noise without a band chatters (the test can fail)


def test_s_holds_while_a_contact_hides_the_load(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, BETWEEN)
    cfg = replace(QUIET, load_tau=0.0, latency_s=0)
    sensors = FrankaSensors(model, settings=cfg)
    ladle = scene_ids(model).ladle_body
    sensors.read(data)
    _press(model, data, 3 * BEAD_WEIGHT)
    assert sensors.read(data).s
    for push in ([0.0, 0.0, 5.0], [2.0, 0.0, 0.0]):  # the floor pushing up; the pile, sideways
        data.xfrc_applied[ladle, :3] = push
        mujoco.mj_forward(model, data)
        assert sensors.read(data).s  # held: the load is hidden
        assert sensors.last is not None and sensors.last.contact > cfg.contact_hold
    _press(model, data, 0.0)
    assert not sensors.read(data).s  # free again: empty
    data.xfrc_applied[ladle, :3] = [0.0, 0.0, 5.0]
    mujoco.mj_forward(model, data)
    assert not sensors.read(data).s  # held off
    unheld = FrankaSensors(model, settings=replace(cfg, contact_hold=100.0))
    unheld.read(data)
    _press(model, data, 3 * BEAD_WEIGHT)
    unheld.read(data)
    data.xfrc_applied[ladle, :3] = [0.0, 0.0, 5.0]
    mujoco.mj_forward(model, data)
    assert not unheld.read(data).s  # without the hold the push reads as no soup


def test_t_is_pose_only_over_the_target_with_an_empty_ladle(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, ABOVE_TARGET)
    got = FrankaSensors(model).read(data)
    ideal = ScoopSensors(model).read(data)
    assert got.t and not got.s and not got.r
    assert not ideal.t  # the ideal t wants soup to deliver; the pose-only one does not
    assert not got.on_ladle.any() and not got.in_target.any()  # the truth, for the records
    _place(model, data, BETWEEN)
    assert not FrankaSensors(model).read(data).t


def test_r_is_the_tray_in_the_soup_bowls_region(model: mujoco.MjModel) -> None:
    data = mujoco.MjData(model)
    _place(model, data, IN_SOUP)
    got = FrankaSensors(model).read(data)
    assert got.r and not got.s and not got.t
    assert ScoopSensors(model).read(data).r


@pytest.mark.parametrize(("field", "value"), [
    ("force_noise", -0.1), ("force_rate", 0.0), ("load_tau", float("nan")),
    ("latency_s", 1.5), ("latency_t", -1), ("tare_samples", 0), ("pose_noise", "1mm"),
    ("period", 0.0), ("region_hysteresis", -1.0), ("seed", True),
])
def test_invalid_settings_name_the_field(field: str, value: object) -> None:
    with pytest.raises(InputError, match=rf"SensorSettings\.{field}"):
        SensorSettings(**{field: value})  # type: ignore[arg-type]


def test_s_off_above_s_on_is_refused() -> None:
    with pytest.raises(InputError, match=r"SensorSettings\.s_off.*s_on"):
        SensorSettings(s_on=0.01, s_off=0.02)


def test_factory_kinds(model: mujoco.MjModel) -> None:
    assert SENSOR_KINDS == ("franka", "ideal")
    assert isinstance(make_sensors("ideal", model), ScoopSensors)
    franka = make_sensors("franka", model, seed=7, settings=QUIET)
    assert isinstance(franka, FrankaSensors) and franka.settings.seed == 7
    with pytest.raises(InputError, match="franka, ideal"):
        make_sensors("camera", model)
    with pytest.raises(InputError, match="settings"):
        make_sensors("ideal", model, settings=QUIET)


def test_a_model_without_the_ft_sensor_is_refused() -> None:
    spec = mujoco.MjSpec()
    from tli_verify.sim.scene import add_scene

    add_scene(spec)
    body = spec.worldbody.add_body(name="ladle")
    body.add_site(name="ladle_tray")
    body.add_geom(name="ladle_floor", size=[0.01, 0, 0])
    with pytest.raises(TliError, match="ladle_ft"):
        FrankaSensors(spec.compile())


def test_the_period_is_the_loops() -> None:
    from tli_verify.sim.demos import CONTROL_DT

    assert CONTROL_PERIOD == CONTROL_DT


@pytest.mark.slow
def test_a_nominal_panda_trial_succeeds_with_franka_sensors() -> None:
    """No push, the robot's own sensors (the loop's default), the measured law: the trial
    delivers and its mode trace is one the automaton allows (a scoop that loads nothing is
    re-entered from a by the stall rule: a b a b ... c d)."""
    from tli_verify.sim.franka_project import load_policy
    from tli_verify.sim.loop import run_trial
    from tli_verify.sim.trial_oracle import check_trial

    policy = load_policy("LTL-DS")
    result = run_trial(policy, 0, perturbations=[], robot="panda", sensors="franka")
    assert result.success and result.controller == "measured" and result.sensors == "franka"
    runs = result.mode_sequence().split()
    assert runs[0] == "a" and runs[-1] == "d" and runs[-2] == "c"
    verdict = check_trial(result, policy.automaton, policy.goal_modes)
    assert verdict.ok, verdict.messages
