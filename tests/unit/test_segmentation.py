"""Sensor-based segmentation and attractors (paper appendix C) and per-transition DS."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tli_verify.demos import Demonstration, load_demos
from tli_verify.errors import DemoError, SpecError
from tli_verify.segmentation import (
    DEFAULT_MODE,
    segment_demos,
    spec_labeler,
    transition_key,
)


def demo(x: list[list[float]], sensors: list[list[int]], names: tuple[str, ...] = ("r",),
         path: str = "d.csv") -> Demonstration:
    X = np.array(x, dtype=float)
    t = np.arange(len(X), dtype=float)
    return Demonstration(path=path, t=t, x=X, dx=np.gradient(X, t, axis=0),
                         sensor_names=names,
                         sensors=np.array(sensors, dtype=bool).reshape(len(X), len(names)))


def test_each_sensor_state_is_a_mode_and_attractor_is_the_entry_into_the_next_mode() -> None:
    d1 = demo([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]], [[0], [0], [1], [1], [0]])
    d2 = demo([[0, 1], [1, 1], [2, 1], [3, 1]], [[0], [0], [0], [1]])
    seg = segment_demos([d1, d2])
    assert seg.modes == ("!r", "r")
    assert [(s.demo, s.start, s.stop, s.modes, s.next_modes) for s in seg.segments] == [
        (0, 0, 2, ("!r",), ("r",)), (0, 2, 4, ("r",), ("!r",)), (0, 4, 5, ("!r",), None),
        (1, 0, 3, ("!r",), ("r",)), (1, 3, 4, ("r",), None),
    ]
    # Lemma 2: the mean of the first (up to 3) states of the next segment, over the segments
    # that hand over; the one-sample segment ending demo 1 in "!r" (and demo 2's in "r") is
    # too short for a DS that stays: only the hand-over keys are learned
    assert sorted(seg.data) == ["!r->r", "r->!r"]
    np.testing.assert_allclose(seg.data["!r->r"].attractor, np.mean([[2.5, 0.0], [3.0, 1.0]], 0))
    np.testing.assert_allclose(seg.data["r->!r"].attractor, [4, 0])  # only d1 hands over
    one = segment_demos([d1, d2], entry_samples=1)
    np.testing.assert_allclose(one.data["!r->r"].attractor, np.mean([[2, 0], [3, 1]], 0))
    assert seg.data["!r->r"].next_mode == "r"
    assert seg.data["r->!r"].next_mode == "!r"
    # without the ending segments: one observed successor, plain key
    plain = segment_demos([demo([[0, 0], [1, 0], [2, 0], [3, 0]], [[0], [0], [1], [1]])])
    assert sorted(plain.data) == ["!r", "r"] and plain.data["!r"].next_mode == "r"


def test_a_mode_that_only_ends_demonstrations_keeps_the_mean_end_point() -> None:
    d1 = demo([[0, 0], [1, 0], [2, 0], [3, 0]], [[0], [0], [1], [1]])
    d2 = demo([[0, 1], [1, 1], [2, 1], [3, 3]], [[0], [0], [1], [1]])
    np.testing.assert_allclose(segment_demos([d1, d2]).data["r"].attractor, [3, 1.5])


def test_attractor_is_strictly_inside_the_next_region_appendix_d_is_not() -> None:
    # delta_r = {x0 >= 2}: three demonstrations cross it at different heights and speeds
    rows = []
    for height, speed in ((0.0, 0.7), (1.0, 0.45), (-0.5, 0.9)):
        X = np.column_stack([np.arange(0.0, 4.0, speed), np.full(len(np.arange(0.0, 4.0, speed)),
                                                                  height)])
        rows.append(demo(X.tolist(), (X[:, :1] >= 2).astype(int).tolist()))
    data = segment_demos(rows).data["!r"]
    assert data.attractor[0] > 2.0  # in r, strictly
    lasts = [rows[s.demo].x[s.stop - 1] for s in data.segments]
    assert np.mean(lasts, axis=0)[0] < 2.0  # appendix C's point reads !r: the DS never leaves


def test_segments_are_shifted_so_their_entry_points_meet_at_the_attractor() -> None:
    d1 = demo([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]], [[0], [0], [1], [1], [1]])
    d2 = demo([[0, 2], [1, 2], [1, 3], [1, 4]], [[0], [0], [1], [1]])
    data = segment_demos([d1, d2], entry_samples=2).data["!r"]
    entries = np.array([[2.5, 0], [1, 3.5]])
    np.testing.assert_allclose(data.attractor, entries.mean(0))
    shift = data.attractor - entries
    np.testing.assert_allclose(data.x[:2], d1.x[:2] + shift[0])
    np.testing.assert_allclose(data.x[2:], d2.x[:2] + shift[1])
    np.testing.assert_allclose(data.dx, np.concatenate([d1.dx[:2], d2.dx[:2]]))
    unshifted = segment_demos([d1, d2], shift=False).data["!r"]
    np.testing.assert_allclose(unshifted.x, np.concatenate([d1.x[:2], d2.x[:2]]))


def test_segments_ending_a_demonstration_are_shifted_onto_the_attractor() -> None:
    d1 = demo([[0, 0], [1, 0], [2, 0]], [[0], [0], [0]])
    d2 = demo([[0, 2], [1, 2], [2, 4]], [[0], [0], [0]])
    data = segment_demos([d1, d2]).data["!r"]
    np.testing.assert_allclose(data.attractor, [2, 2])
    ends = data.x[[2, 5]]
    np.testing.assert_allclose(ends, [[2, 2], [2, 2]])
    np.testing.assert_allclose(data.x[:3], [[0, 2], [1, 2], [2, 2]])
    unshifted = segment_demos([d1, d2], shift=False).data["!r"]
    np.testing.assert_allclose(unshifted.x[:3], [[0, 0], [1, 0], [2, 0]])


def test_entry_samples_must_be_positive() -> None:
    d = demo([[0, 0], [1, 0], [2, 0]], [[0], [0], [1]])
    with pytest.raises(DemoError, match="entry_samples must be >= 1, got 0"):
        segment_demos([d], entry_samples=0)


def test_no_sensor_columns_is_one_mode() -> None:
    d = Demonstration(path="d.csv", t=np.arange(3.0), x=np.zeros((3, 2)), dx=np.zeros((3, 2)),
                      sensor_names=(), sensors=np.zeros((3, 0), dtype=bool))
    seg = segment_demos([d, d])
    assert seg.modes == (DEFAULT_MODE,)
    assert list(seg.data) == [DEFAULT_MODE]
    assert seg.data[DEFAULT_MODE].x.shape == (6, 2)


def test_per_transition_ds_when_a_mode_has_several_successors() -> None:
    names = ("p", "q")
    d1 = demo([[0, 0], [1, 0], [2, 0], [3, 0]], [[0, 0], [0, 0], [1, 0], [1, 0]], names)
    d2 = demo([[0, 0], [0, 1], [0, 2], [0, 3]], [[0, 0], [0, 0], [0, 1], [0, 1]], names)
    seg = segment_demos([d1, d2])
    a, b, c = "!p & !q", "p & !q", "!p & q"
    assert sorted(seg.data) == sorted([transition_key(a, b), transition_key(a, c), b, c])
    to_b = seg.data[f"{a}->{b}"]
    assert (to_b.mode, to_b.next_mode) == (a, b)
    np.testing.assert_allclose(to_b.attractor, [2.5, 0])  # only the segments heading to b
    np.testing.assert_allclose(seg.data[f"{a}->{c}"].attractor, [0, 2.5])


def test_shared_labels_share_data_and_every_transition_pair_gets_a_key() -> None:
    def label(reading: Mapping[str, bool]) -> tuple[str, ...]:
        if reading["r"]:
            return ("y",)
        return ("g",) if reading["q"] else ("w1", "w2")

    names = ("r", "q")
    to_y = demo([[0, 0], [1, 0], [2, 0], [3, 0]], [[0, 0], [0, 0], [1, 0], [1, 0]], names)
    to_g = demo([[0, 0], [0, 1], [0, 2], [0, 3]], [[0, 0], [0, 0], [0, 1], [0, 1]], names)
    seg = segment_demos([to_y], labeler=label)
    assert seg.modes == ("w1", "w2", "y")
    np.testing.assert_array_equal(seg.data["w1"].x, seg.data["w2"].x)
    assert seg.data["w1"].next_mode == "y"
    both = segment_demos([to_y, to_g], labeler=label)
    assert sorted(both.data) == ["g", "w1->g", "w1->y", "w2->g", "w2->y", "y"]
    np.testing.assert_allclose(both.data["w2->g"].attractor, [0, 2.5])


def test_reading_without_a_mode_names_file_and_line(repo: Path) -> None:
    from tli_verify.logic.spec import load_spec

    labeler, modes, labels = spec_labeler(load_spec(repo / "specs" / "scoop.toml"))
    d = demo([[0, 0], [1, 0], [2, 0]], [[0, 0, 0], [1, 1, 0], [0, 0, 1]], ("r", "s", "t"),
             path="demos/x.csv")
    with pytest.raises(DemoError, match=r"demos/x\.csv: row 2: sensor reading r=1, s=1, t=0 "
                                        "satisfies no mode label"):
        segment_demos([d], labeler=labeler, modes=modes, labels=labels)


def test_spec_modes_on_bundled_demos(repo: Path) -> None:
    from tli_verify.logic.spec import load_spec

    spec = load_spec(repo / "specs" / "scoop.toml")
    labeler, modes, labels = spec_labeler(spec)
    demos = load_demos(sorted((repo / "demos").glob("scoop_*.csv")), sensor_names=spec.inputs)
    seg = segment_demos(demos, labeler=labeler, modes=modes, labels=labels)
    assert list(seg.data) == ["a", "b", "c", "d"]
    assert [seg.data[m].next_mode for m in "abcd"] == ["b", "c", "d", None]
    assert len(seg.segments) == 12


def test_unvisited_spec_mode_is_named(repo: Path) -> None:
    from tli_verify.logic.spec import load_spec

    labeler, modes, labels = spec_labeler(load_spec(repo / "specs" / "scoop.toml"))
    d = demo([[0, 0], [1, 0], [2, 0], [3, 0]], [[0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0]],
             ("r", "s", "t"))
    with pytest.raises(DemoError, match=r"mode 'c' \(label '!r & s & !t'\) is visited by no "
                                        r"demonstration.*Asm\. 3"):
        segment_demos([d], labeler=labeler, modes=modes, labels=labels)


def test_a_ds_needs_two_samples() -> None:
    d = demo([[0, 0], [1, 0], [2, 0]], [[0], [0], [1]])
    with pytest.raises(DemoError, match=r"DS 'r' has only 1 sample"):
        segment_demos([d])


def test_spec_without_modes_table() -> None:
    with pytest.raises(SpecError, match=r"s\.toml: no \[modes\] table"):
        spec_labeler(SimpleNamespace(modes=None, path="s.toml"))


def test_a_mode_passed_through_and_ending_gets_a_hand_over_key_and_a_plain_key() -> None:
    # cooking's pot: passed through (-> white) in one demonstration, the final mode in both.
    # The hand-over is keyed per transition; the plain key is the DS that stays (the mean end
    # point), not the hand-over's (before: one plain DS heading to white for both)
    d1 = demo([[0, 0], [1, 0], [2, 0], [3, 0], [4, 0], [5, 0], [6, 0], [7, 0], [8, 0]],
              [[0], [0], [1], [1], [1], [0], [0], [1], [1]])
    d2 = demo([[0, 2], [1, 2], [2, 2], [3, 2], [3, 3]], [[0], [0], [1], [1], [1]])
    seg = segment_demos([d1, d2])
    assert sorted(seg.data) == ["!r", "r", "r->!r"]
    hand_over, stay = seg.data["r->!r"], seg.data["r"]
    assert (hand_over.mode, hand_over.next_mode) == ("r", "!r")
    assert (stay.mode, stay.next_mode) == ("r", None)
    np.testing.assert_allclose(hand_over.attractor, [5.5, 0])  # entry into white
    np.testing.assert_allclose(stay.attractor, np.mean([[8, 0], [3, 3]], axis=0))  # the ends
    assert [(s.demo, s.start) for s in hand_over.segments] == [(0, 2)]
    assert [(s.demo, s.start) for s in stay.segments] == [(0, 7), (1, 2)]
    # with shared labels (cooking-cb's d1/d2 on the pot): both pot modes get both keys

    def label(reading: Mapping[str, bool]) -> tuple[str, ...]:
        return ("d1", "d2") if reading["r"] else ("w1", "w2")

    shared = segment_demos([d1, d2], labeler=label)
    assert {"d1", "d2", "d1->w1", "d1->w2", "d2->w1", "d2->w2"} <= set(shared.data)
    np.testing.assert_allclose(shared.data["d2"].attractor, stay.attractor)
