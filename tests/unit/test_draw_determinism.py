"""A campaign seed draws the same cases whatever modules the process has imported since.

Hypothesis mixes "local constants" harvested from imported non-library modules into its draws;
a campaign importing a module lazily made the first campaign of a process differ from the next.
``import_independent_draws`` pins that pool (empty) while the campaign draws.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

from tli_verify.tasks.registry import find_task
from tli_verify.verify.draws import draw_cases
from tli_verify.verify.strategies import LEVELS, cases


def test_draws_ignore_constants_of_modules_imported_in_between(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    task = find_task("scoop")
    assert task.starts.nominal[0] == (-5.0, 4.5)

    def draw() -> list:
        st = cases(task, start=task.starts.nominal[0], max_pushes=3, window=700, levels=LEVELS)
        return draw_cases(st, 120, "determinism")

    before = draw()
    # a new local module full of integer constants in the strategies' ranges
    body = "\n".join(f"C{k} = {k}" for k in range(0, 700, 3))
    (tmp_path / "tli_extra_constants_mod.py").write_text(body + "\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.import_module("tli_extra_constants_mod")
    try:
        assert draw() == before
    finally:
        sys.modules.pop("tli_extra_constants_mod", None)
