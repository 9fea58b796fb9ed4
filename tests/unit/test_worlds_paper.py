"""The paper's task worlds (tli_verify.worlds): regions, sensor models, demonstrators, specs.

Scoop (paper Fig. 2, appendix E), cooking (appendix "Generalization"), color tracing and the
inspection line: the regions partition the workspace as documented; every demonstration
sample reads a label of the spec's modes and the demonstrated mode sequence is a path of the
spec's task automaton; the bundled demos are the generators' output; learning works on them.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.demos import Demonstration, load_demo
from tli_verify.errors import DemoError, ModelError
from tli_verify.logic.automaton import AssumptionViolation, TaskAutomaton
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.segmentation import spec_labeler
from tli_verify.worlds import (
    WORLDS,
    ColorTracingWorld,
    CookingWorld,
    InspectionWorld,
    ScoopWorld,
    World,
    WorldBase,
)
from tli_verify.worlds.base import write_demos

SPECS = Path(__file__).resolve().parents[2] / "specs"


@functools.cache
def _automaton(name: str) -> TaskAutomaton:
    return synthesize(load_spec(SPECS / name))


def walk(spec_name: str, names: Sequence[str], readings: np.ndarray) -> list[str]:
    """Run the spec's automaton on a reading sequence; the mode sequence (deduplicated).

    Also checks every reading satisfies the label of the mode the automaton runs on it.
    Raises AssumptionViolation on a reading change the assumptions rule out.
    """
    spec = load_spec(SPECS / spec_name)
    automaton = _automaton(spec_name)
    labeler, _, _ = spec_labeler(spec)

    def reading(i: int) -> dict[str, bool]:
        return {n: bool(v) for n, v in zip(names, readings[i], strict=True)}

    true0 = {n for n, v in reading(0).items() if v}
    starts = [s for s in automaton.initial if set(automaton.states[s].inputs) == true0]
    assert starts, f"{spec_name}: no initial state for the reading {sorted(true0)}"
    state = starts[0]
    modes = [automaton.states[state].mode]
    assert modes[0] in labeler(reading(0))
    for i in range(1, len(readings)):
        state, mode = automaton.next_mode(state, reading(i))
        assert mode in labeler(reading(i)), (spec_name, i, mode, reading(i))
        if mode != modes[-1]:
            modes.append(mode)
    return modes


# ------------------------------------------------------------------ regions


PROBES = {
    "scoop": [((0.0, -5.0), "yellow"), ((4.0, -5.0), "pink"), ((2.0, -8.0), "pink"),
              ((4.0, 6.0), "pink"), ((4.0, 6.01), "green"), ((6.0, 8.0), "green"),
              ((0.0, 0.0), "white"), ((7.0, -6.0), "yellow"), ((7.0, 7.0), "white"),
              ((1.99, -4.0), "yellow"), ((1.99, -3.99), "white")],
    "cooking": [((5.0, 8.0), "dark"), ((1.0, 6.0), "yellow"), ((9.0, 6.0), "green"),
                ((5.0, 6.0), "white"), ((1.0, 4.0), "white"), ((3.0, 8.0), "dark"),
                ((2.99, 8.0), "yellow"), ((7.01, 8.0), "green")],
    "color-tracing": [((1.0, 3.0), "Y"), ((3.0, 3.0), "B"), ((5.0, 3.0), "G"),
                      ((7.0, 3.0), "O"), ((9.0, 0.5), "P"), ((11.0, 5.5), "R"),
                      ((5.0, 1.0), "dark"), ((7.9, 5.0), "dark")],
    "inspection": [((5.0, 3.0), "track"), ((8.5, 3.0), "release"), ((5.0, 4.0), "off"),
                   ((2.9, 3.0), "off"), ((9.1, 3.0), "off")],
}


@pytest.mark.parametrize("name", list(WORLDS))
def test_regions_partition_the_workspace(name: str) -> None:
    world = WORLDS[name]()
    lo, hi = np.array(world.lo), np.array(world.hi)
    X = np.random.default_rng(0).uniform(lo, hi, size=(20000, 2))
    masks = world.region_masks(X)
    assert list(masks) == list(world.region_names)
    np.testing.assert_array_equal(np.sum(list(masks.values()), axis=0), 1)
    for region, mask in masks.items():
        assert mask.any(), f"{name}: region {region} is empty"
    probes = PROBES[name]
    got = world.true_mode(np.array([p for p, _ in probes]))
    assert list(got) == [r for _, r in probes]
    assert len(world.region_colors) == len(world.region_names)
    assert isinstance(world, World)
    assert all((SPECS / s).is_file() for s in world.specs)


@pytest.mark.parametrize("name", list(WORLDS))
def test_sample_region_stays_in_the_region(name: str) -> None:
    world = WORLDS[name]()
    for region in world.region_names:
        X = world.sample_region(region, 50, np.random.default_rng(1))
        assert X.shape == (50, 2)
        assert world.in_region(region, X).all()
    with pytest.raises(ModelError, match="no region"):
        world.sample_region("nowhere", 1, np.random.default_rng(1))


def test_scoop_region_areas_are_the_papers() -> None:
    world = ScoopWorld()
    g = np.linspace(-8.0, 8.0, 801)
    X = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    frac = {k: float(v.mean()) for k, v in world.region_masks(X).items()}
    # yellow: x2 <= -4 outside 2 <= x1 <= 6 (12 x 4); pink 4 x 14; green 4 x 2 of 16 x 16
    np.testing.assert_allclose(frac["yellow"], 48 / 256, atol=0.01)
    np.testing.assert_allclose(frac["pink"], 56 / 256, atol=0.01)
    np.testing.assert_allclose(frac["green"], 8 / 256, atol=0.01)


def _touching(world: WorldBase, step: float = 0.02) -> set[frozenset[str]]:
    """Region pairs that share a boundary (neighbouring points of a fine grid)."""
    lo, hi = np.array(world.lo), np.array(world.hi)
    gx = np.arange(lo[0], hi[0] + step / 2, step)
    gy = np.arange(lo[1], hi[1] + step / 2, step)
    X = np.stack(np.meshgrid(gx, gy), axis=-1)
    idx = world.region_index(X.reshape(-1, 2)).reshape(X.shape[:2])
    names = world.region_names
    pairs = set()
    for a, b in ((idx[:, :-1], idx[:, 1:]), (idx[:-1, :], idx[1:, :])):
        diff = a != b
        pairs |= {frozenset((names[i], names[j])) for i, j in zip(a[diff], b[diff], strict=True)}
    return pairs


def test_cooking_and_color_tracing_adjacency_is_what_the_assumptions_allow() -> None:
    cooking = {frozenset(p) for p in (("white", "yellow"), ("white", "green"),
                                      ("white", "dark"), ("yellow", "dark"), ("green", "dark"))}
    assert _touching(CookingWorld()) == cooking  # no yellow-green
    tiles = ["Y", "B", "G", "O", "P", "R"]
    color = {frozenset(p) for p in itertools.pairwise(tiles)}
    color |= {frozenset(("dark", t)) for t in tiles[:-1]}  # not dark-R
    assert _touching(ColorTracingWorld()) == color


# ------------------------------------------------------------------ sensor models


def _scoop_reading(world: ScoopWorld, path: list[tuple[float, float]]) -> list[str]:
    codes = world.sensors(np.array(path)).astype(int) @ np.array([1, 2, 4])
    return ["abcXdXXX"[int(c)] for c in codes]


def test_scoop_soup_is_latent() -> None:
    w = ScoopWorld()
    # white -> pink without scooping: an empty spoon reads a; green without soup too
    assert _scoop_reading(w, [(0, 0), (3, 0), (3, 5), (3, 7)]) == ["a", "a", "a", "a"]
    # yellow -> pink: soup; pink -> green: delivered, and t latches
    assert _scoop_reading(w, [(0, 0), (0, -5), (3, -5), (3, 5), (3, 7), (0, 0)]) == \
        ["a", "b", "c", "c", "d", "d"]
    # a spill: pink -> white loses the soup (c -> a); back to pink from white: still empty
    assert _scoop_reading(w, [(0, -5), (3, -5), (0, 0), (3, 0), (3, 7)]) == \
        ["b", "c", "a", "a", "a"]
    # knocked back into the soup: c -> b, and scooping again works
    assert _scoop_reading(w, [(0, -5), (3, -5), (1, -5), (3, -6), (3, 7)]) == \
        ["b", "c", "b", "c", "d"]
    # soup stays in pink (no contact while x2 <= -4 in pink: pink overrides yellow)
    assert _scoop_reading(w, [(0, -5), (3, -5), (3, -7), (5, -7)]) == ["b", "c", "c", "c"]


def test_sensor_lag_reads_the_past_and_batches_match() -> None:
    rng = np.random.default_rng(3)
    X = np.cumsum(rng.normal(scale=0.6, size=(4, 120, 2)), axis=1).clip(-8, 8)
    base = ScoopWorld().sensors(X)
    lagged = ScoopWorld(lag=19).sensors(X)
    k = np.arange(120)
    np.testing.assert_array_equal(lagged, base[:, np.maximum(k - 19, 0)])
    assert not np.array_equal(lagged, base)
    for b in range(4):  # the batch scan is the per-episode scan
        np.testing.assert_array_equal(base[b], ScoopWorld().sensors(X[b]))
    with pytest.raises(ModelError, match="lag"):
        ScoopWorld(lag=-1)


def test_inspection_release_is_one_reading_and_the_cube_is_gone_after() -> None:
    w = InspectionWorld()
    path = [(1, 1), (4, 3), (6, 3), (8.5, 3), (8.6, 3), (5, 3), (5, 5), (4, 3), (8.5, 3)]
    R = w.sensors(np.array(path)).astype(int)
    assert R.tolist() == [[0, 0], [1, 0], [1, 0], [1, 1], [0, 0], [0, 0], [0, 0], [1, 0],
                          [1, 1]]
    # the release station reached from off the line is not a release (!line -> X !rel)
    assert w.sensors(np.array([(8.5, 4.0), (8.5, 3.0), (8.6, 3.0)])).astype(int).tolist() == \
        [[0, 0], [1, 0], [1, 1]]


def test_cooking_empty_spoon_over_the_pot_reads_white() -> None:
    w = CookingWorld()
    R = w.sensors(np.array([(5, 5), (5, 8), (1, 8), (5, 8), (5, 5)])).astype(int)
    assert R.tolist() == [[0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 0, 1], [0, 0, 0]]


jumps = st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8)), min_size=2, max_size=40)


@settings(max_examples=60)
@given(jumps)
def test_scoop_sensor_changes_are_allowed_even_under_jumps(path: list[tuple[float, float]]
                                                           ) -> None:
    # any state sequence (perturbations of any size) gives readings the assumptions allow
    w = ScoopWorld()
    walk("scoop.toml", w.sensor_names, w.sensors(np.array([(0.0, 0.0), *path])))


@settings(max_examples=60)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(0, 6)), min_size=2, max_size=40))
def test_inspection_sensor_changes_are_allowed_even_under_jumps(
        path: list[tuple[float, float]]) -> None:
    w = InspectionWorld()
    walk("inspection.toml", w.sensor_names, w.sensors(np.array([(1.0, 1.0), *path])))


@settings(max_examples=60)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10)), min_size=2, max_size=40))
def test_cooking_never_reads_white_then_pot(path: list[tuple[float, float]]) -> None:
    R = CookingWorld().sensors(np.array(path))
    white = np.asarray(~R.any(axis=1))
    assert not np.any(white[:-1] & R[1:, 2])


# ------------------------------------------------------------------ demonstrations vs specs


def _bundled(repo: Path, name: str, spec: str | None = None) -> list[Demonstration]:
    inputs = load_spec(SPECS / spec).inputs if spec else None
    paths = sorted((repo / "demos").glob(f"{name}_*.csv"))
    assert paths, name
    return [load_demo(p, sensor_names=inputs) for p in paths]


@pytest.mark.parametrize(("name", "spec", "expected"), [
    ("scoop", "scoop.toml", [["a", "b", "c", "d"]] * 3),
    ("cooking", "cooking-cb.toml", [["w1", "y", "d1", "w2", "g", "d2"], None, None]),
    ("cooking", "cooking-bc.toml", [None, ["w1", "g", "d1", "w2", "y", "d2"], None]),
    ("cooking", "cooking-c.toml", [None, None, ["w", "g", "w", "y", "d"]]),  # the detour
    # demonstrations 2-7: recoveries, starting in the dark (entered only by perturbations)
    ("color-tracing", "color-tracing-a.toml", [["y", "b", "g", "o", "pk", "rd"]] + ["dark"] * 6),
    ("color-tracing", "color-tracing-b.toml", [["y", "b", "g", "o", "pk", "rd"]] + ["dark"] * 6),
    ("color-tracing", "color-tracing-c.toml", [["y", "b", "g", "o", "pk", "rd"]] + ["dark"] * 6),
    ("inspection", "inspection.toml", [["a", "b", "a"]] * 2),
])
def test_demonstrations_are_paths_of_the_automaton(repo: Path, name: str, spec: str,
                                                   expected: list[list[str] | str | None]
                                                   ) -> None:
    demos = _bundled(repo, name, spec)
    assert len(demos) == len(expected)
    for demo, modes in zip(demos, expected, strict=True):
        if modes == "dark":  # a recovery: starts in the dark, ends on red
            assert not demo.sensors[0].any() and demo.sensors[-1, -1]
        elif modes is None:  # the other order: its sensor change is ruled out by this spec
            with pytest.raises(AssumptionViolation):
                walk(spec, demo.sensor_names, demo.sensors)
        else:
            assert walk(spec, demo.sensor_names, demo.sensors) == modes


def test_cooking_c_and_cc_allow_the_chicken_prefix_only(repo: Path) -> None:
    chicken_first = _bundled(repo, "cooking", "cooking-c.toml")[0]
    pot = np.flatnonzero(chicken_first.sensors[:, 2])
    first_stop = int(pot[np.flatnonzero(np.diff(pot) > 1)[0]]) + 1  # end of the first visit
    prefix = chicken_first.sensors[:first_stop]
    assert walk("cooking-c.toml", chicken_first.sensor_names, prefix) == ["w", "y", "d"]
    assert walk("cooking-cc.toml", chicken_first.sensor_names, prefix) == ["w", "y", "d"]
    with pytest.raises(AssumptionViolation):  # cooking-c: the done pot is never left
        walk("cooking-c.toml", chicken_first.sensor_names, chicken_first.sensors)
    with pytest.raises(AssumptionViolation):  # cooking-cc: from w only chicken comes next
        walk("cooking-cc.toml", chicken_first.sensor_names, chicken_first.sensors)


@pytest.mark.parametrize("name", list(WORLDS))
def test_bundled_demos_are_the_generator_output(repo: Path, name: str) -> None:
    world = WORLDS[name]()
    generated = world.demonstrate(0)
    loaded = _bundled(repo, name)
    assert len(loaded) == len(generated)
    for got, want in zip(loaded, generated, strict=True):
        assert got.sensor_names == world.sensor_names
        np.testing.assert_allclose(got.t, want.t, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.x, want.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.dx, want.dx, rtol=1e-9, atol=1e-9)
        # sensor bits, away from region boundaries (where rounding may flip them)
        near = np.zeros(want.n_samples, dtype=bool)
        base = world.region_index(want.x)
        for shift in ((1e-7, 0), (-1e-7, 0), (0, 1e-7), (0, -1e-7)):
            near |= world.region_index(want.x + np.array(shift)) != base
        near[1:] |= near[:-1].copy()  # a reading also depends on the previous state
        assert near.mean() < 0.01
        np.testing.assert_array_equal(got.sensors[~near], want.sensors[~near])
        np.testing.assert_array_equal(want.sensors, world.sensors(want.x))
        np.testing.assert_allclose(want.dx[[0, -1]], 0.0, atol=1e-9)  # at rest at both ends


@pytest.mark.parametrize("name", list(WORLDS))
def test_demonstrator_is_seeded(tmp_path: Path, name: str) -> None:
    world = WORLDS[name]()
    a = write_demos(world, tmp_path / "a", seed=5)
    b = write_demos(world, tmp_path / "b", seed=5)
    c = write_demos(world, tmp_path / "c", seed=6)
    assert [p.read_bytes() for p in a] == [p.read_bytes() for p in b]
    assert [p.read_bytes() for p in a] != [p.read_bytes() for p in c]
    assert all(world.in_workspace(d.x).all() for d in world.demonstrate(6))


# ------------------------------------------------------------------ learning


@pytest.mark.slow  # about 2 s per world on an idle core (the scoop learner also runs in
# tests/integration/test_lemma2.py outside the slow set)
@pytest.mark.parametrize(("name", "spec", "keys"), [
    ("scoop", "scoop.toml", {"a", "b", "c", "d"}),
    ("cooking", "cooking-cb.toml",
     {"w1->y", "w2->y", "w1->g", "w2->g", "y", "g->d1", "g->d2", "g->w1", "g->w2",
      "d1", "d2", "d1->w1", "d1->w2", "d2->w1", "d2->w2"}),
    ("inspection", "inspection.toml", {"a->b", "a", "b"}),
    ("color-tracing", None, {"cy & !cb & !cg & !co & !cp & !cr",
                             "!cy & cb & !cg & !co & !cp & !cr",
                             "!cy & !cb & cg & !co & !cp & !cr",
                             "!cy & !cb & !cg & co & !cp & !cr",
                             "!cy & !cb & !cg & !co & cp & !cr",
                             "!cy & !cb & !cg & !co & !cp & cr",
                             *(f"!cy & !cb & !cg & !co & !cp & !cr->{tile}" for tile in (
                                 "cy & !cb & !cg & !co & !cp & !cr",
                                 "!cy & cb & !cg & !co & !cp & !cr",
                                 "!cy & !cb & !cg & !co & cp & !cr"))}),
])
def test_tli_learn_finds_every_mode(repo: Path, tmp_path: Path, name: str, spec: str | None,
                                    keys: set[str]) -> None:
    from tli_verify.cli import main

    out = tmp_path / "m.json"
    demos = [str(p) for p in sorted((repo / "demos").glob(f"{name}_*.csv"))]
    argv = ["learn", *demos, "-o", str(out), "--seed", "0", "--control-dt", "0.01"]
    if spec:
        argv += ["--spec", str(SPECS / spec)]
    assert main(argv) == 0
    from tli_verify.model import load_model

    assert set(load_model(out).modes) == keys


def test_color_tracing_dark_modes_have_no_demonstration(repo: Path, tmp_path: Path) -> None:
    from tli_verify.model import learn_model

    # the paper's demonstration alone (the recoveries 2-7 are ours)
    demos = [repo / "demos" / "color-tracing_1.csv"]
    with pytest.raises(DemoError, match=r"mode 'd1'.*visited by no demonstration"):
        learn_model(demos, out_path=tmp_path / "m.json",
                    spec_path=SPECS / "color-tracing-a.toml")


def _literals(label: str) -> frozenset[str]:
    return frozenset(part.strip() for part in label.split("&"))


def test_cooking_ds_learned_once_serve_all_four_automata(repo: Path, tmp_path: Path) -> None:
    """Paper appendix "Generalization": per-transition DS learned from both orders' demos
    (without a spec: one DS per sensor transition), reused by cooking-cb/bc/c/cc through
    their mode labels, without relearning.

    For every automaton transition the strategy *plans* (target state without ``p``) between
    modes of different labels, the model must have a DS from the source label heading to the
    target label; every mode that ends the task must have a DS that stays (no next mode).
    No gaps: the pot's hand-over (-> white) and its final visit get separate DS (segmentation
    keys hand-overs per transition), and the detour demonstration gives cooking-c's planned
    broccoli -> white.
    """
    from tli_verify.model import learn_model

    demos = sorted((repo / "demos").glob("cooking_*.csv"))
    model = learn_model(demos, out_path=tmp_path / "cooking.model.json", seed=0,
                        control_dt=0.01)
    have = {(_literals(mm.mode), None if mm.next_mode is None else _literals(mm.next_mode))
            for mm in model.modes.values()}
    gaps: set[tuple[str, str, str | None]] = set()
    for spec_name in ("cooking-cb.toml", "cooking-bc.toml", "cooking-c.toml",
                      "cooking-cc.toml"):
        spec = load_spec(SPECS / spec_name)
        labels = {m: _literals(lab) for m, lab in dict(spec.modes or {}).items()}
        automaton = synthesize(spec)
        planned: dict[str, set[str]] = {}
        for t in automaton.transitions:
            src, dst = automaton.states[t.source], automaton.states[t.target]
            if "p" in dst.outputs or labels[src.mode] == labels[dst.mode]:
                continue
            planned.setdefault(src.mode, set()).add(dst.mode)
        for s in automaton.states:
            for dst_mode in planned.get(s.mode, set()):
                if (labels[s.mode], labels[dst_mode]) not in have:
                    gaps.add((spec_name, s.mode, dst_mode))
            if s.mode not in planned and (labels[s.mode], None) not in have:
                gaps.add((spec_name, s.mode, None))
    assert gaps == set()


@pytest.mark.parametrize("name", list(WORLDS))
def test_worlds_are_values_that_pickle(name: str) -> None:
    import pickle

    world = WORLDS[name](lag=3)
    again = pickle.loads(pickle.dumps(world))
    assert again == world and again.lag == 3
    assert again != WORLDS[name]()
