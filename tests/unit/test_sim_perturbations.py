"""The Franka trials' perturbations: the uniform sampler, the records, the person's hand.

:func:`draw` must be deterministic in the seed in any process and *uniform* within the bounds
(Kolmogorov-Smirnov over 400 seeds; no pile-up at the bounds, which hypothesis's provider
showed); a :class:`PersonHand` must drag a free body to its commanded pose along the
minimum-jerk path without exceeding its force and torque limits. No MuJoCo needed.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from tli_verify.errors import TliError
from tli_verify.sim.perturbations import (
    HAND_MAX_FORCE,
    HAND_MAX_TORQUE,
    MAX_ELEVATION,
    MIN_JERK_PEAK,
    PUSH_DISTANCE,
    PUSH_DURATION,
    PUSH_PEAK_SPEED,
    PUSH_WINDOW,
    TILT_ANGLE,
    TILT_DELAY,
    TILT_DURATION,
    TILT_PEAK_SPEED,
    PersonHand,
    Perturbation,
    draw,
    min_jerk,
    min_push_duration,
    pushes,
    tilts,
    trial_perturbations,
)

REPO = Path(__file__).resolve().parents[2]
N_SEEDS = 400
P_MIN = 0.001
Z_MAX = math.sin(math.radians(MAX_ELEVATION))
TOL = 1e-9


@pytest.fixture(scope="module")
def sample() -> list[list[Perturbation]]:
    return [draw(s) for s in range(N_SEEDS)]


def _pushes(sample: list[list[Perturbation]]) -> list[Perturbation]:
    return [p for ps in sample for p in ps if p.kind == "push"]


def _tilts(sample: list[list[Perturbation]]) -> list[Perturbation]:
    return [p for ps in sample for p in ps if p.kind == "tilt"]


def _unit(p: Perturbation) -> np.ndarray:
    v = np.array(p.motion)
    return v / np.linalg.norm(v)


def _azimuth(p: Perturbation) -> float:
    u = _unit(p)
    return math.atan2(u[1], u[0]) % (2 * math.pi)


def _push_fraction(p: Perturbation) -> float:
    """The duration's position in its range given the distance, in [0, 1]."""
    lo = min_push_duration(p.magnitude)
    return (p.duration - lo) / (PUSH_DURATION[1] - lo)


def _tilt_fraction(p: Perturbation) -> float:
    """A tilt's duration's position in its range given the angle, in [0, 1]."""
    lo = max(TILT_DURATION[0], math.ceil(1.875 * p.magnitude / TILT_PEAK_SPEED * 1000 - 1e-9)
             / 1000)
    return (p.duration - lo) / (TILT_DURATION[1] - lo)


# (name, value of a perturbation, kind, bounds)
QUANTITIES = [
    ("push start", lambda p: p.start, "push", PUSH_WINDOW),
    ("push distance", lambda p: p.magnitude, "push", PUSH_DISTANCE),
    ("push duration given the distance", _push_fraction, "push", (0.0, 1.0)),
    ("push direction z", lambda p: float(_unit(p)[2]), "push", (-Z_MAX, Z_MAX)),
    ("push azimuth", _azimuth, "push", (0.0, 2 * math.pi)),
    ("tilt delay", lambda p: p.start, "tilt", TILT_DELAY),
    ("tilt duration given the angle", _tilt_fraction, "tilt", (0.0, 1.0)),
    ("tilt angle", lambda p: p.magnitude, "tilt", TILT_ANGLE),
    ("tilt axis z", lambda p: float(_unit(p)[2]), "tilt", (-Z_MAX, Z_MAX)),
    ("tilt azimuth", _azimuth, "tilt", (0.0, 2 * math.pi)),
]


@pytest.mark.parametrize(("name", "value", "kind", "bounds"), QUANTITIES,
                         ids=[q[0] for q in QUANTITIES])
def test_draws_are_uniform_in_the_bounds(sample: list[list[Perturbation]], name: str,
                                         value: object, kind: str,
                                         bounds: tuple[float, float]) -> None:
    ps = _pushes(sample) if kind == "push" else _tilts(sample)
    assert len(ps) == N_SEEDS
    xs = np.array([value(p) for p in ps])  # type: ignore[operator]
    lo, hi = bounds
    assert np.all(xs >= lo - TOL) and np.all(xs <= hi + TOL), name
    result = stats.kstest(xs, stats.uniform(loc=lo, scale=hi - lo).cdf)
    assert result.pvalue > P_MIN, (name, result)
    # no pile-up at the bounds: uniform puts 2 % within 1 % of the range of either end
    span = hi - lo
    near = np.mean((xs - lo < 0.01 * span) | (hi - xs < 0.01 * span))
    assert near < 0.06, (name, near)


def test_the_ks_check_rejects_a_sample_piled_at_the_bounds() -> None:
    """The uniformity test above can fail: hypothesis-style draws (a quarter at the window's
    end) are rejected."""
    rng = np.random.default_rng(0)
    xs = rng.uniform(*PUSH_WINDOW, size=N_SEEDS)
    xs[: N_SEEDS // 4] = PUSH_WINDOW[1]
    lo, hi = PUSH_WINDOW
    assert stats.kstest(xs, stats.uniform(loc=lo, scale=hi - lo).cdf).pvalue < P_MIN


def test_draws_respect_the_bounds(sample: list[list[Perturbation]]) -> None:
    for ps in sample:
        assert [p.kind for p in ps] == ["push", "tilt"]
        for p in ps:
            assert round(p.start * 1000) == pytest.approx(p.start * 1000, abs=1e-6)
            assert round(p.duration * 1000) == pytest.approx(p.duration * 1000, abs=1e-6)
            assert abs(_unit(p)[2]) <= Z_MAX + TOL
        push, tilt = ps
        assert push.rotation == (0.0, 0.0, 0.0) and tilt.displacement == (0.0, 0.0, 0.0)
        assert PUSH_WINDOW[0] <= push.start <= PUSH_WINDOW[1]
        assert PUSH_DISTANCE[0] - TOL <= push.magnitude <= PUSH_DISTANCE[1] + TOL
        assert min_push_duration(push.magnitude) <= push.duration <= PUSH_DURATION[1]
        assert push.peak_speed <= PUSH_PEAK_SPEED + 1e-9
        assert TILT_DELAY[0] <= tilt.start <= TILT_DELAY[1]
        assert TILT_DURATION[0] <= tilt.duration <= TILT_DURATION[1]
        assert tilt.peak_speed <= TILT_PEAK_SPEED + 1e-9
        assert TILT_ANGLE[0] - TOL <= tilt.magnitude <= TILT_ANGLE[1] + TOL


def test_min_push_duration_keeps_the_peak_speed() -> None:
    # a distance short enough for the floor to win
    short = 0.9 * PUSH_DURATION[0] * PUSH_PEAK_SPEED / MIN_JERK_PEAK
    assert min_push_duration(short) == PUSH_DURATION[0]
    # otherwise 1.875 d / peak, rounded up to the millisecond
    expect = math.ceil(MIN_JERK_PEAK * 0.30 / PUSH_PEAK_SPEED * 1000 - 1e-9) / 1000
    assert min_push_duration(0.30) == pytest.approx(max(PUSH_DURATION[0], expect))
    d = 0.2345
    t = min_push_duration(d)
    assert MIN_JERK_PEAK * d / t <= PUSH_PEAK_SPEED + 1e-12
    assert t - 0.001 < max(PUSH_DURATION[0], MIN_JERK_PEAK * d / PUSH_PEAK_SPEED)


def test_draw_is_deterministic_and_seeds_differ() -> None:
    assert draw(7) == draw(7)
    assert draw(7, pushes=2, tilts=2) == draw(7, pushes=2, tilts=2)
    assert len({draw(s)[0] for s in range(10)}) == 10
    assert draw(3, pushes=0, tilts=0) == []


def test_counts_order_and_distinct_starts() -> None:
    ps = draw(11, pushes=3, tilts=2)
    assert [p.kind for p in ps] == ["push"] * 3 + ["tilt"] * 2
    for kind in ("push", "tilt"):
        starts = [p.start for p in ps if p.kind == kind]
        assert starts == sorted(set(starts))
    # the tilts come from their own stream: the same whatever the number of pushes
    assert draw(11, pushes=0, tilts=2) == ps[3:]
    with pytest.raises(TliError, match="pushes and tilts"):
        draw(1, pushes=-1)
    with pytest.raises(TliError, match="seed"):
        draw(-1)


def test_draw_is_the_same_in_a_fresh_process() -> None:
    """Another interpreter, with other modules imported first, draws the same."""
    code = ("import json\n"
            "import tli_verify.verify.oracle, tli_verify.logic.gr1, hypothesis.strategies\n"
            "from tli_verify.sim.perturbations import draw\n"
            "print(json.dumps([[p.to_dict() for p in draw(s, pushes=2)] for s in range(6)]))\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, cwd=REPO, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin"},
                         timeout=120).stdout
    here = [[p.to_dict() for p in draw(s, pushes=2)] for s in range(6)]
    assert json.loads(out) == here


def test_records_round_trip_exactly(sample: list[list[Perturbation]]) -> None:
    for ps in sample[:100]:
        for p in ps:
            text = json.dumps(p.to_dict())
            assert Perturbation.from_dict(json.loads(text)) == p
    # a trial's record carries applied_at too
    p = sample[0][0]
    assert Perturbation.from_dict(dict(p.to_dict(), applied_at=1.0)) == p


@pytest.mark.parametrize(("record", "field"), [
    ({"kind": "shove", "start": 1.0, "duration": 1.0, "displacement": [0.1, 0, 0]}, "kind"),
    ({"kind": "push", "duration": 1.0, "displacement": [0.1, 0, 0]}, "start"),
    ({"kind": "push", "start": 1.0, "duration": 1.0}, "displacement"),
    ({"kind": "push", "start": 1.0, "duration": 1.0, "rotation": [0.1, 0, 0]}, "rotation"),
    ({"kind": "tilt", "start": 1.0, "duration": 1.0, "rotation": [0.1, 0]}, "rotation"),
    ({"kind": "tilt", "start": 1.0, "duration": 0.0, "rotation": [0.1, 0, 0]}, "duration"),
    ({"kind": "tilt", "start": -1.0, "duration": 1.0, "rotation": [0.1, 0, 0]}, "start"),
    ({"kind": "push", "start": 1.0, "duration": 1.0, "displacement": [math.nan, 0, 0]},
     "displacement"),
])
def test_bad_records_name_the_field(record: dict[str, object], field: str) -> None:
    with pytest.raises(TliError, match=field):
        Perturbation.from_dict(record)


def test_a_push_has_no_rotation_and_a_tilt_no_displacement() -> None:
    with pytest.raises(TliError, match="rotation"):
        Perturbation("push", 1.0, 1.0, displacement=(0.1, 0, 0), rotation=(0.1, 0, 0))
    with pytest.raises(TliError, match="displacement"):
        Perturbation("tilt", 1.0, 1.0, displacement=(0.1, 0, 0), rotation=(0.1, 0, 0))


def test_min_jerk_profile() -> None:
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0 and min_jerk(0.5) == 0.5
    assert min_jerk(-1.0) == 0.0 and min_jerk(2.0) == 1.0
    taus = np.linspace(0.0, 1.0, 2001)
    s = np.array([min_jerk(x) for x in taus])
    speed = np.diff(s) / np.diff(taus)
    assert np.all(speed >= 0)
    assert speed.max() == pytest.approx(MIN_JERK_PEAK, rel=1e-3)
    assert speed[0] < 1e-5 and speed[-1] < 1e-5  # at rest at both ends


# --- the person's hand on free bodies (numpy integration) -------------------------------------

def _drag_point(hand: PersonHand, mass: float = 1.0, dt: float = 1e-3
                ) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """A free point mass (no gravity) dragged by ``hand`` from its start to its end; the final
    position, the grab position and the force norms."""
    p0 = np.array([0.4, -0.1, 0.3])
    p, v = p0.copy(), np.zeros(3)
    forces: list[float] = []
    t = hand.start
    while t < hand.end:
        w = hand.wrench(t, p, np.eye(3), v, np.zeros(3))
        forces.append(float(np.linalg.norm(w[:3])))
        assert np.all(w[3:] == 0.0) or np.linalg.norm(w[3:]) < 1e-9  # a push does not turn
        v = v + dt * w[:3] / mass  # semi-implicit Euler
        p = p + dt * v
        t += dt
    return p, p0, forces


@pytest.mark.parametrize("seed", range(12))
def test_a_push_drags_a_free_point_mass_to_the_displacement(seed: int) -> None:
    push = draw(seed, tilts=0)[0]
    hand = PersonHand(push)
    p, p0, forces = _drag_point(hand)
    d = np.array(push.displacement)
    assert np.linalg.norm(p - (p0 + d)) < 0.02, (push, p - p0)
    assert max(forces) <= HAND_MAX_FORCE + 1e-9
    assert hand.max_force == pytest.approx(max(forces))
    assert hand.achieved is not None
    assert np.linalg.norm(hand.achieved - d) < 0.02
    assert np.array_equal(hand.commanded, d)


def test_the_force_limit_binds() -> None:
    """A weak hand (5 N) on a heavy body is clipped at 5 N, and falls short."""
    push = Perturbation("push", 1.0, 0.5, displacement=(0.3, 0.0, 0.0))
    hand = PersonHand(push, max_force=5.0)
    p, p0, forces = _drag_point(hand, mass=10.0)
    assert max(forces) == pytest.approx(5.0) and max(forces) <= 5.0 + 1e-9
    assert np.linalg.norm(p - (p0 + np.array(push.displacement))) > 0.1


def _rot(w: np.ndarray) -> np.ndarray:
    theta = float(np.linalg.norm(w))
    if theta == 0.0:
        return np.eye(3)
    k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / theta
    return np.eye(3) + math.sin(theta) * k + (1 - math.cos(theta)) * k @ k


@pytest.mark.parametrize("seed", range(6))
def test_a_tilt_turns_a_free_body_by_the_rotation(seed: int) -> None:
    tilt = draw(seed, pushes=0)[0]
    hand = PersonHand(tilt, start=2.0)
    inertia, dt = 0.013, 1e-3  # about the free hand's carrier with the ladle, kg m^2
    r0 = _rot(np.array([0.0, 0.0, 0.7]))
    r, omega = r0.copy(), np.zeros(3)
    torques = []
    t = hand.start
    while t < hand.end:
        w = hand.wrench(t, np.zeros(3), r, np.zeros(3), omega)
        torques.append(float(np.linalg.norm(w[3:])))
        omega = omega + dt * w[3:] / inertia
        r = _rot(dt * omega) @ r
        t += dt
    target = _rot(np.array(tilt.rotation)) @ r0
    err = np.arccos(np.clip((np.trace(target @ r.T) - 1) / 2, -1, 1))
    assert err < 0.05, (tilt, err)
    assert max(torques) <= HAND_MAX_TORQUE + 1e-9
    assert hand.achieved is not None
    assert np.linalg.norm(hand.achieved - np.array(tilt.rotation)) < 0.05


def test_the_hand_acts_only_while_active_and_reads_quaternions() -> None:
    tilt = Perturbation("tilt", 0.5, 1.0, rotation=(0.0, 0.9, 0.0))
    hand = PersonHand(tilt, start=3.0)
    assert not hand.active(2.999) and hand.active(3.0) and not hand.active(4.0)
    assert np.all(hand.wrench(2.0, np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3)) == 0)
    assert not hand.grabbed
    with pytest.raises(TliError, match="grabbed"):
        hand.target(3.5)
    q = np.array([math.cos(0.2), 0.0, 0.0, math.sin(0.2)])  # 0.4 rad about z
    a = hand.wrench(3.4, np.zeros(3), q, np.zeros(3), np.zeros(3))
    other = PersonHand(tilt, start=3.0)
    b = other.wrench(3.4, np.zeros(3), _rot(np.array([0.0, 0.0, 0.4])), np.zeros(3),
                     np.zeros(3))
    assert np.allclose(a, b) and np.linalg.norm(a[3:]) > 0
    assert np.all(hand.wrench(4.0, np.zeros(3), q, np.zeros(3), np.zeros(3)) == 0)  # let go
    with pytest.raises(TliError, match="stiffness"):
        PersonHand(tilt, stiffness=-1.0)


# --- the strategies' validation --------------------------------------------------------------

@pytest.mark.parametrize(("make", "field"), [
    (lambda: pushes(distance=(0.3, 0.1)), "push distance"),
    (lambda: pushes(distance=(0.0, 0.1)), "push distance"),
    (lambda: pushes(duration=(0.5, 0.6)), "push duration"),  # 0.3 m needs 0.9375 s
    (lambda: pushes(window=(-1.0, 2.0)), "push window"),
    (lambda: pushes(peak_speed=0.0), "push peak_speed"),
    (lambda: pushes(elevation=91.0), "push elevation"),
    (lambda: tilts(angle=(0.0, 1.0)), "tilt angle"),
    (lambda: tilts(duration=(1.0, math.inf)), "tilt duration"),
    (lambda: tilts(delay=(2.0, 1.0)), "tilt delay"),
    (lambda: tilts(elevation=-1.0), "tilt elevation"),
    (lambda: trial_perturbations(levels=("free",)), "levels"),
    (lambda: trial_perturbations(min_pushes=2, max_pushes=1), "min <= max"),
])
def test_strategy_bounds_are_validated(make: object, field: str) -> None:
    with pytest.raises(TliError, match=field):
        make()  # type: ignore[operator]
