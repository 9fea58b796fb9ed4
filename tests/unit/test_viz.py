"""n-D pictures of tasks and episodes (tli_verify.viz): files, panels, shadows, cut traces."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import numpy.typing as npt
import pytest
from PIL import Image, ImageSequence

from tli_verify.boundary.cuts import Cut
from tli_verify.ds.lpvds import LPVDS
from tli_verify.errors import ModelError, TliError
from tli_verify.model.types import Model, ModeModel
from tli_verify.runtime.events import CutAdded, InvarianceFailure, Perturbation
from tli_verify.runtime.loop import EpisodeResult
from tli_verify.viz import regions as vr
from tli_verify.viz.episodes import (
    animate_episode,
    episode_title,
    mode_sequence,
    plot_episodes,
    zoom_colors,
)

matplotlib.use("Agg")

FloatArray = npt.NDArray[np.float64]
Pred = Callable[[FloatArray], npt.NDArray[np.bool_]]


# ----------------------------------------------------------------------------- fake tasks
def box(lo: Sequence[float], hi: Sequence[float]) -> Pred:
    a, b = np.asarray(lo), np.asarray(hi)
    return lambda X: np.all((X >= a) & (X <= b), axis=1)


def ball(center: Sequence[float], radius: float) -> Pred:
    c = np.asarray(center)
    return lambda X: np.linalg.norm(X - c, axis=1) <= radius


@dataclass
class FakeTask:
    """A TaskLike: region 0 is the free space, the others are tested in order."""

    name: str
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    region_names: tuple[str, ...]
    region_colors: tuple[str, ...]
    preds: list[Pred] = field(default_factory=list)
    calls: list[str] = field(default_factory=list)

    @property
    def dim(self) -> int:
        return len(self.lo)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(f"q{k + 1}" for k in range(self.dim))

    def region_index(self, X: FloatArray) -> npt.NDArray[np.int64]:
        Xa = np.asarray(X, dtype=np.float64)
        idx = np.zeros(len(Xa), dtype=np.int64)
        for k in range(len(self.preds), 0, -1):
            idx[self.preds[k - 1](Xa)] = k
        return idx

    def sample_region(self, name: str, count: int, rng: np.random.Generator) -> FloatArray:
        self.calls.append(name)
        k = self.region_names.index(name)
        got: list[FloatArray] = []
        for _ in range(20):
            X = rng.uniform(self.lo, self.hi, size=(4 * count, self.dim))
            got.append(X[self.region_index(X) == k])
            if sum(len(g) for g in got) >= count:
                return np.concatenate(got)[:count]
        raise ModelError(f"{self.name}: cannot sample region {name!r}")


def task_2d() -> FakeTask:
    return FakeTask("flat", (0.0, 0.0), (4.0, 3.0), ("free", "A", "B"),
                    ("white", "red", "blue"),
                    [box((0.5, 0.5), (1.5, 1.5)), box((2.5, 1.0), (3.5, 2.5))])


def task_3d(*, speck: bool = True) -> FakeTask:
    names, colors = ["free", "A", "B"], ["white", "red", "blue"]
    preds = [box((0.1, 0.1, 0.1), (0.45, 0.45, 0.45)), ball((0.72, 0.7, 0.65), 0.18)]
    if speck:
        names.append("speck")
        colors.append("green")
        preds.append(ball((0.9, 0.1, 0.9), 1e-4))
    return FakeTask("drawer", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0), tuple(names), tuple(colors),
                    preds)


def task_4d() -> FakeTask:
    return FakeTask("four", (0.0,) * 4, (1.0,) * 4, ("free", "A"), ("white", "red"),
                    [box((0.2,) * 4, (0.7,) * 4)])


# ----------------------------------------------------------------------------- fake episodes
def model_for(dim: int, cuts: Sequence[Cut] = ()) -> Model:
    """A real model: modes a and b, one stable linear system each (x* = 0.9 ... 0.9)."""
    n = dim
    ds = LPVDS(attractor=np.full(n, 0.9), priors=np.ones(1), means=np.full((1, n), 0.5),
               covs=np.eye(n)[None] * 0.1, A=-np.eye(n)[None], P=np.eye(n))
    return Model(state_names=tuple(f"q{k + 1}" for k in range(n)),
                 modes={"a": ModeModel("a", "a", "b", ds, cuts=tuple(cuts)),
                        "b": ModeModel("b", "b", None, ds)})


def episode(dim: int, *, cut: Cut | None = None, success: bool = True) -> EpisodeResult:
    """A straight run 0.2 -> 0.9 with a push at step 20, a failure at 30 and a cut at 31."""
    T = 60
    s = np.linspace(0.0, 1.0, T + 1)[:, None]
    S = 0.2 + 0.7 * s * np.ones((1, dim))
    S[20:, 0] = np.clip(S[20:, 0] + 0.05, 0.0, 1.0)  # the push lands between 19 and 20
    modes = tuple("a" if t < 40 else "b" for t in range(T + 1))
    events: list[Any] = [Perturbation(step=20, mode="a"),
                            InvarianceFailure(step=30, mode="a", key="a", to_mode="b",
                                              entry=S[0], last_inside=S[29], outside=S[30])]
    cuts = []
    if cut is not None:
        events.append(CutAdded(step=31, mode="a", keys=("a",), cut=cut, cuts=1,
                               fallback=False))
        cuts.append(cut)
    return EpisodeResult(success=success, steps=T, states=S, modes=modes,
                         automaton_states=tuple(0 for _ in modes), events=tuple(events),
                         cuts_added=len(cuts), model=model_for(dim, cuts))


def diagonal_cut(dim: int) -> Cut:
    w = np.zeros(dim)
    w[0] = w[1] = 1.0 / math.sqrt(2.0)
    return Cut(normal=-w, point=np.full(dim, 0.5))  # x* = 0.9.. is on the inner side


# ----------------------------------------------------------------------------- image checks
def rgb(path: Path) -> npt.NDArray[np.uint8]:
    with Image.open(path) as im:
        im.load()
        assert im.format == "PNG"
        assert im.width > 0 and im.height > 0
        return np.asarray(im.convert("RGB"))


def distinct(pixels: npt.NDArray[np.uint8]) -> int:
    flat = pixels.reshape(-1, 3).astype(np.int64)
    return len(np.unique(flat[:, 0] << 16 | flat[:, 1] << 8 | flat[:, 2]))


def count_near(pixels: npt.NDArray[np.uint8], color: Sequence[float], tol: int = 4) -> int:
    return int(np.sum(np.all(np.abs(pixels.astype(int) - np.asarray(color)) <= tol, axis=-1)))


def over_white(color: Sequence[float]) -> tuple[float, ...]:
    """A shadow of ``color`` (0..1 RGB) over white, as 0..255."""
    a = vr.SHADOW_ALPHA
    return tuple(255 * (a * c + (1 - a)) for c in color)


# ----------------------------------------------------------------------------- pure helpers
def test_pairs_for() -> None:
    assert vr.pairs_for(1) == ()
    assert vr.pairs_for(2) == ((0, 1),)
    assert vr.pairs_for(3) == ((0, 1), (0, 2), (1, 2))
    assert len(vr.pairs_for(4)) == 6
    assert vr.pairs_for(7) == ((0, 1), (0, 2), (0, 3), (0, 4), (0, 5), (0, 6))
    assert vr.pairs_for(5, [(4, 0), (1, 3)]) == ((4, 0), (1, 3))
    for bad in ([(0, 0)], [(0, 5)], [(0, 1), (0, 1)], [], [(0, 1, 2)]):
        with pytest.raises(TliError):
            vr.pairs_for(5, bad)
    with pytest.raises(TliError, match="dimension 0"):
        vr.pairs_for(0)


def test_cut_trace_normal_out_of_plane_has_no_trace() -> None:
    assert vr.cut_trace([0.0, 0.0, 1.0], [0.5, 0.5, 0.5], 0, 1, [0, 0, 0], [1, 1, 1]) is None
    seg = vr.cut_trace([0.0, 0.0, 1.0], [0.5, 0.5, 0.3], 0, 2, [0, 0, 0], [1, 1, 1])
    assert seg is not None  # the horizontal line x3 = 0.3 in the (x1, x3) plane
    np.testing.assert_allclose(sorted(seg[:, 0]), [0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(seg[:, 1], [0.3, 0.3], atol=1e-12)


def test_cut_trace_diagonal() -> None:
    w = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    seg = vr.cut_trace(w, [0.5, 0.5, 0.5], 0, 1, [0, 0, 0], [1, 1, 1])
    assert seg is not None and seg.shape == (2, 2)
    ends = sorted(map(tuple, np.round(seg, 12)))
    np.testing.assert_allclose(ends, [(0.0, 1.0), (1.0, 0.0)], atol=1e-12)
    seg = vr.cut_trace(w, [0.2, 0.3, 0.5], 1, 0, [0, 0, 0], [1, 2, 1])  # u = x2, v = x1
    assert seg is not None  # x1 + x2 = 0.5 from (x2, x1) = (0, 0.5) to (0.5, 0)
    np.testing.assert_allclose(sorted(map(tuple, seg)), [(0.0, 0.5), (0.5, 0.0)], atol=1e-12)
    vertical = vr.cut_trace(w, [0.5, 0.5, 0.5], 0, 2, [0, 0, 0], [1, 1, 1])
    assert vertical is not None
    np.testing.assert_allclose(vertical[:, 0], [0.5, 0.5], atol=1e-12)  # x1 = 0.5 in (x1, x3)
    np.testing.assert_allclose(sorted(vertical[:, 1]), [0.0, 1.0], atol=1e-12)
    assert vr.cut_trace(w, [5.0, 5.0, 0.5], 0, 1, [0, 0, 0], [1, 1, 1]) is None  # misses box


def test_shadows_and_legend_labels() -> None:
    task = task_3d()
    shadows = vr.region_shadows(task, samples=800, seed=3)
    assert [s.name for s in shadows] == list(task.region_names)
    assert not shadows[3].drawable and shadows[3].reason
    assert all(s.drawable and s.points is not None and s.points.shape == (800, 3)
               for s in shadows[:3])
    assert vr.legend_labels(shadows) == ("free", "A", "B", "speck (too small to draw)")
    again = vr.region_shadows(task, samples=800, seed=3)
    np.testing.assert_array_equal(shadows[2].points, again[2].points)  # seeded
    assert shadows[1].points is not None
    mask = vr.shadow_mask(shadows[1].points, 0, 1, task.lo, task.hi)
    frac = mask.mean()
    assert 0.08 < frac < 0.2  # the box [0.1, 0.45]^2 covers 0.1225 of the plane


def test_bad_tasks_raise_and_write_nothing(tmp_path: Path) -> None:
    out = tmp_path / "x.png"
    zero = FakeTask("zero", (), (), ("free",), ("white",))
    with pytest.raises(TliError, match="dimension 0"):
        vr.plot_task(zero, out)
    nothing = task_3d()
    nothing.sample_region = _refuse  # type: ignore[method-assign]
    with pytest.raises(TliError, match="no region can be sampled"):
        vr.plot_task(nothing, out, samples=200)
    colours = FakeTask("c", (0.0, 0.0), (1.0, 1.0), ("free", "A"), ("white",))
    with pytest.raises(TliError, match="colours"):
        vr.plot_task(colours, out)
    with pytest.raises(TliError, match="no episode"):
        plot_episodes(task_3d(), [], out)
    with pytest.raises(TliError, match="states of shape"):
        plot_episodes(task_3d(), [("2-D run", episode(2))], out, samples=200)
    assert not out.exists() and list(tmp_path.iterdir()) == []


def _refuse(name: str, count: int, rng: np.random.Generator) -> FloatArray:
    raise ModelError(f"cannot sample {name}")


def test_titles() -> None:
    assert mode_sequence(["a", "a", "b", "a", "b", "b"]) == "abab"
    assert mode_sequence(["approach", "pull", "pull", "retract"]) == "approach-pull-retract"
    r = episode(3, success=False)
    assert episode_title(r, label="LTL-DS", goal_label="the open drawer") == \
        "LTL-DS: ab (does not reach the open drawer in 60 steps, 0 cuts)"
    assert episode_title(episode(3, cut=diagonal_cut(3))) == "ab (reaches the goal, 1 cut)"
    assert list(zoom_colors(["b", "a", "b"])) == ["b", "a"]
    assert zoom_colors(["b", "a"], {"a": "tab:red"})["a"] == ("tab:red", "tab:red")


# ----------------------------------------------------------------------------- pictures
class _Demo:
    def __init__(self, x: FloatArray) -> None:
        self.x = x


def test_plot_task_2d(tmp_path: Path) -> None:
    task = task_2d()
    demo = _Demo(np.column_stack([np.linspace(0.2, 3.8, 50), np.linspace(0.2, 2.8, 50)]))
    pic = vr.plot_task(task, tmp_path / "flat.png", demos=[demo], resolution=120)
    assert pic.panels == 1 and pic.pairs == ((0, 1),) and pic.legend == ("free", "A", "B")
    px = rgb(pic.path)
    assert distinct(px) > 8
    assert count_near(px, (255, 0, 0), tol=2) > 500  # region A, opaque in 2-D
    assert count_near(px, (0, 0, 255), tol=2) > 500
    assert task.calls == []  # 2-D draws the exact partition, no sampling


def test_plot_task_1d(tmp_path: Path) -> None:
    task = FakeTask("line", (0.0,), (2.0,), ("free", "A"), ("white", "red"),
                    [box((0.5,), (1.2,))])
    demo = _Demo(np.linspace(0.0, 2.0, 30)[:, None])
    pic = vr.plot_task(task, tmp_path / "line.png", demos=[demo], resolution=100)
    assert pic.panels == 1 and pic.pairs == ()
    px = rgb(pic.path)
    assert distinct(px) > 8 and count_near(px, (255, 0, 0), tol=2) > 500


def test_plot_task_3d(tmp_path: Path) -> None:
    task = task_3d()
    demo = _Demo(np.linspace([0.2, 0.2, 0.2], [0.8, 0.7, 0.6], 40))
    pic = vr.plot_task(task, tmp_path / "drawer.png", demos=[demo], samples=1500)
    assert pic.panels == 3 and pic.pairs == vr.pairs_for(3)
    assert "speck (too small to draw)" in pic.legend
    px = rgb(pic.path)
    assert distinct(px) > 20
    assert count_near(px, over_white((1.0, 0.0, 0.0))) > 300  # the box's shadows
    assert count_near(px, over_white((0.0, 0.0, 1.0))) > 300  # the ball's


def test_plot_task_4d_panels(tmp_path: Path) -> None:
    pic = vr.plot_task(task_4d(), tmp_path / "four.png", samples=800)
    assert pic.panels == 6
    assert count_near(rgb(pic.path), over_white((1.0, 0.0, 0.0))) > 300
    pic = vr.plot_task(task_4d(), tmp_path / "two.png", samples=800, pairs=[(0, 3), (2, 1)])
    assert pic.panels == 2 and pic.pairs == ((0, 3), (2, 1))


def test_plot_episodes_2d(tmp_path: Path) -> None:
    task = task_2d()
    cut = diagonal_cut(2)
    pic = plot_episodes(task, [("no modulation", episode(2, success=False)),
                               ("LTL-DS", episode(2, cut=cut))], tmp_path / "ep2.png",
                        nominal=episode(2), zoom_first=True, title="two runs")
    assert pic.panels == 3 and pic.pairs == ((0, 1),)
    px = rgb(pic.path)
    assert distinct(px) > 20 and count_near(px, (255, 0, 0), tol=2) > 300


def test_plot_episodes_3d(tmp_path: Path) -> None:
    task = task_3d()
    pic = plot_episodes(task, [("no modulation", episode(3, success=False)),
                               ("LTL-DS", episode(3, cut=diagonal_cut(3)))],
                        tmp_path / "ep3.png", nominal=episode(3), zoom_first=True,
                        goal_label="the open drawer", samples=1000)
    # per episode 3 pairs and a mode strip, and the zoom panel
    assert pic.panels == 2 * (3 + 1) + 1 and pic.pairs == vr.pairs_for(3)
    assert "speck (too small to draw)" in pic.legend
    px = rgb(pic.path)
    assert distinct(px) > 20
    assert count_near(px, over_white((1.0, 0.0, 0.0))) > 300


def test_plot_episodes_1d(tmp_path: Path) -> None:
    task = FakeTask("line", (0.0,), (1.0,), ("free", "A"), ("white", "red"),
                    [box((0.5,), (0.7,))])
    pic = plot_episodes(task, [("run", episode(1))], tmp_path / "ep1.png", zoom_first=True)
    assert pic.panels == 2
    assert count_near(rgb(pic.path), (255, 0, 0), tol=2) > 300


@pytest.mark.parametrize("dim", [2, 3])
def test_animate_episode(tmp_path: Path, dim: int) -> None:
    task = task_2d() if dim == 2 else task_3d(speck=False)
    res = episode(dim, cut=diagonal_cut(dim))
    out = tmp_path / f"ep{dim}.gif"
    n = animate_episode(task, res, out, frames=6, fps=10, title="LTL-DS", samples=800)
    assert n == 6
    with Image.open(out) as im:
        assert im.format == "GIF"
        decoded = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]
    assert len(decoded) == 6
    last = decoded[-1]
    assert last.shape[0] > 0 and distinct(last) > 8
    want = (255, 0, 0) if dim == 2 else over_white((1.0, 0.0, 0.0))
    assert count_near(last, want, tol=8) > 100
