"""The pictures of a closed-loop run on a user's own 4-D task show the mode (issue 32, part 6).

The test writes a 4-D task and its spec, makes demonstrations, learns, certifies and runs
``tli run --animate`` as a user does, then reads the pictures it wrote -- their structure, not
their pixels: ``run.png`` has one panel per coordinate pair (6 for n = 4) in a grid of 3
columns, panels at least 250 px a side, and a mode strip under them; the path in the panels is
drawn in the modes' colours (not black), and the strip shows the modes of ``run.json``'s mode
trace in their order. ``run.gif``'s frames show three planes and the strip.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from matplotlib.colors import to_rgb
from PIL import Image, ImageSequence

from tests.support.drawer4d import write_project
from tli_verify.viz.episodes import mode_colors

Pixels = npt.NDArray[np.uint8]


def _tli(*argv: str, cwd: Path) -> str:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, f"tli {' '.join(argv)}: exit {proc.returncode}\n{proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """A certified 4-D project and one pushed run of it (``out/run.png``, ``out/run.gif``)."""
    root = write_project(tmp_path_factory.mktemp("drawer4"))
    _tli("demos", "tasks/drawer4.toml", cwd=root)
    demos = sorted(str(p.relative_to(root)) for p in (root / "demos").glob("*.csv"))
    _tli("learn", *demos, "--spec", "specs/drawer4.toml", "-o", "models/drawer4.model.json",
         "--no-handoff", cwd=root)
    _tli("certify", "models/drawer4.model.json", cwd=root)
    _tli("run", "--task", "drawer4", "--perturb", "random:3", "--seed", "6", "--animate", "8",
         "--out", "out", cwd=root)
    return root / "out", json.loads((root / "out" / "run.json").read_text())


def _frames(px: Pixels, min_len: int = 150) -> list[tuple[int, int, int]]:
    """The axes' horizontal spines: ``(row, first column, end column)`` of every run of dark
    pixels at least ``min_len`` long (a spine a few rows thick counted once)."""
    dark = np.all(px[..., :3] < 60, axis=-1)
    out: list[tuple[int, int, int]] = []
    for y in range(dark.shape[0]):
        d = np.diff(np.concatenate([[0], dark[y].astype(int), [0]]))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True):
            if b - a >= min_len and not any(abs(y - y2) <= 2 and abs(a - a2) <= 3
                                            for y2, a2, _ in out):
                out.append((y, int(a), int(b)))
    return out


def _boxes(px: Pixels) -> list[tuple[int, int, int, int]]:
    """Axes boxes ``(top, bottom, left, right)``: spines paired by their column span."""
    spines = _frames(px)  # in row order
    boxes = []
    bottoms: set[int] = set()
    for k, (y, a, b) in enumerate(spines):
        if k in bottoms:
            continue
        below = [q for q in range(k + 1, len(spines)) if abs(spines[q][1] - a) <= 3
                 and abs(spines[q][2] - b) <= 3]
        if below:
            bottoms.add(below[0])
            boxes.append((y, spines[below[0]][0], a, b))
    return boxes


def _rgb(name: str) -> npt.NDArray[np.float64]:
    return np.array(to_rgb(name)) * 255.0


def _near(px: Pixels, color: str, tol: float = 12.0) -> npt.NDArray[np.bool_]:
    return np.all(np.abs(px[..., :3].astype(np.float64) - _rgb(color)) <= tol, axis=-1)


def _strip_sequence(px: Pixels, box: tuple[int, int, int, int], colors: dict[str, str]
                    ) -> list[str]:
    """The modes along the strip's bars, left to right (runs of 3 px or more)."""
    top, bottom, left, right = box
    row = px[top + round(0.3 * (bottom - top)), left + 2:right - 2]
    seq: list[str] = []
    width = 0
    for k in range(row.shape[0]):
        hit = [m for m, c in colors.items() if _near(row[k:k + 1], c)[0]]
        if hit and seq and seq[-1] == hit[0]:
            width += 1
        elif hit:
            if seq and width < 3:
                seq.pop()
            if seq and seq[-1] == hit[0]:  # a bar too narrow to count between two of one mode
                width = 3
                continue
            seq.append(hit[0])
            width = 1
    if seq and width < 3:
        seq.pop()
    return seq


def _subsequence(short: list[str], long: list[str]) -> bool:
    it = iter(long)
    return all(m in it for m in short)


def _strip_shows_the_trace(seen: list[str], rec: dict[str, Any]) -> None:
    """The strip's bars are runs of the mode trace, in order, and every run lasting 2 % of the
    steps or more has its bar."""
    assert _subsequence(seen, _trace_runs(rec, 0.0)), seen
    assert _subsequence(_trace_runs(rec, 0.02), seen), seen
    assert len(set(seen)) >= 3


def _trace_runs(rec: dict[str, Any], at_least: float) -> list[str]:
    """The modes of the mode trace whose runs last at least ``at_least`` of the steps."""
    trace = [(m, t) for m, t in rec["mode_trace"]] + [("", rec["steps"] + 1)]
    runs = [m for (m, t), (_, t2) in itertools.pairwise(trace)
            if t2 - t >= at_least * rec["steps"]]
    return [m for k, m in enumerate(runs) if k == 0 or runs[k - 1] != m]


def test_run_png_is_a_grid_of_planes_coloured_by_mode_over_a_mode_strip(run) -> None:
    out, rec = run
    modes = [m for m, _ in rec["mode_trace"]]
    assert len(set(modes)) >= 3 and len(modes) >= 5  # pushed back: replans
    px = np.asarray(Image.open(out / "run.png").convert("RGB"))
    boxes = _boxes(px)
    panels = [b for b in boxes if abs((b[1] - b[0]) - (b[3] - b[2])) <= 0.1 * (b[3] - b[2])]
    strips = [b for b in boxes if (b[3] - b[2]) > 3 * (b[1] - b[0])]
    assert len(boxes) == 7 and len(panels) == 6 and len(strips) == 1, boxes
    assert min(b[3] - b[2] for b in panels) >= 250  # larger panels (169 px before)
    assert len({b[0] for b in panels}) == 2 and len({b[2] for b in panels}) == 3  # 2 x 3 grid
    strip = strips[0]
    assert strip[0] > max(b[1] for b in panels)  # under the panels, as wide as the grid
    assert strip[3] - strip[2] >= 0.9 * (max(b[3] for b in panels) - min(b[2] for b in panels))
    colors = mode_colors(modes)
    inside = np.zeros(px.shape[:2], dtype=bool)
    for top, bottom, left, right in panels:
        inside[top + 6:bottom - 6, left + 6:right - 6] = True
    steps = {m: 0 for m in colors}
    for (m, t), (_, t2) in zip(rec["mode_trace"], [*rec["mode_trace"][1:],
                                                   ("", rec["steps"])], strict=True):
        steps[m] += t2 - t
    drawn = {m: int(np.sum(_near(px, c) & inside)) for m, c in colors.items()}
    long_ones = [m for m in colors if steps[m] >= 0.1 * rec["steps"]]
    assert len(long_ones) >= 2
    for m in long_ones:  # every mode that ran a while is drawn in its colour
        assert drawn[m] >= 50, (m, drawn)
    black = np.all(px[..., :3] < 40, axis=-1) & inside
    assert int(black.sum()) < 400  # the path is not drawn in black (1,328 px before)
    _strip_shows_the_trace(_strip_sequence(px, strip, colors), rec)


def test_run_gif_frames_show_three_planes_and_the_strip(run) -> None:
    out, rec = run
    colors = mode_colors([m for m, _ in rec["mode_trace"]])
    with Image.open(out / "run.gif") as im:
        frames = [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]
    assert len(frames) == 8
    last = frames[-1]
    boxes = _boxes(last)
    panels = [b for b in boxes if abs((b[1] - b[0]) - (b[3] - b[2])) <= 0.1 * (b[3] - b[2])]
    strips = [b for b in boxes if (b[3] - b[2]) > 3 * (b[1] - b[0])]
    assert len(panels) == 3 and len(strips) == 1, boxes
    _strip_shows_the_trace(_strip_sequence(last, strips[0], colors), rec)
    first = frames[0]  # the path grows: the first frame has (almost) none of it
    inside = np.zeros(first.shape[:2], dtype=bool)
    for top, bottom, left, right in panels:
        inside[top + 6:bottom - 6, left + 6:right - 6] = True
    drawn = [int(np.sum(_near(f, colors[rec["mode_trace"][0][0]]) & inside)) for f in frames]
    assert drawn[0] < drawn[-1] and drawn[-1] >= 100
