"""The project session (issue 33): files found, read and parsed once; one control-period rule.

Counted from the user's side: ``tli run`` in-process under an audit hook (``open`` events) and
with the parsers wrapped to count their calls; the control period settled by ``tli learn`` /
``tli certify`` / ``tli_verify.learn`` on a task the test writes, with and without ``dt``.
"""

from __future__ import annotations

import json
import os
import sys
from collections import Counter
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import tli_verify as tli
from tests.support.cli import run as tli_run
from tli_verify import snapshot
from tli_verify.defaults import DEFAULT_DT
from tli_verify.io import atomic_write_text, bundled_root, read_text, sha256_file
from tli_verify.logic import spec as spec_module
from tli_verify.model import serialize
from tli_verify.project import control_period, open_project

ROOT = bundled_root()

_OPENS: Counter[str] = Counter()
_WATCH: list[str] = []


def _hook(event: str, args: tuple[object, ...]) -> None:
    if event == "open" and _WATCH and isinstance(args[0], str | os.PathLike):
        p = os.path.realpath(os.fspath(args[0]))  # type: ignore[arg-type]
        if p in _WATCH:
            _OPENS[p] += 1


sys.addaudithook(_hook)  # hooks cannot be removed; this one counts only while _WATCH is set


@pytest.fixture
def counting(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    """Count the model and spec parses (the real parsers, wrapped)."""
    parses: Counter[str] = Counter()
    real_model, real_spec = serialize.model_from_dict, spec_module.parse_spec

    def model_from_dict(*a: object, **k: object) -> object:
        parses["model"] += 1
        return real_model(*a, **k)  # type: ignore[arg-type]

    def parse_spec(*a: object, **k: object) -> object:
        parses["spec"] += 1
        return real_spec(*a, **k)  # type: ignore[arg-type]

    # every binding of the real parsers (a module that imported one at its top holds its own)
    for name, module in list(sys.modules.items()):
        if not name.startswith("tli_verify"):
            continue
        for attr, real, wrapped in (("model_from_dict", real_model, model_from_dict),
                                    ("parse_spec", real_spec, parse_spec)):
            if getattr(module, attr, None) is real:
                monkeypatch.setattr(module, attr, wrapped)
    return parses


def test_tli_run_opens_and_parses_the_model_and_the_spec_once(
        capsys: pytest.CaptureFixture[str], counting: Counter[str], tmp_path: Path) -> None:
    model = ROOT / "models" / "scoop.model.json"
    spec = ROOT / "specs" / "scoop.toml"
    cert = ROOT / "certificates" / "scoop.cert.json"
    _WATCH[:] = [os.path.realpath(p) for p in (model, spec, cert)]
    _OPENS.clear()
    try:
        code, out, err = tli_run(capsys, "run", "--model", str(model), "--out", str(tmp_path))
    finally:
        watched = dict(_OPENS)
        _WATCH.clear()
    assert code == 0, err
    assert "reached the goal" in out
    assert watched == {os.path.realpath(model): 1, os.path.realpath(spec): 1,
                       os.path.realpath(cert): 1}, watched
    assert counting == {"model": 1, "spec": 1}, counting


def test_outside_a_snapshot_every_read_goes_to_the_disk(tmp_path: Path) -> None:
    """The counter-check: the same reads without a snapshot open the file each time (so the
    test above measures the snapshot, not a cache somewhere else)."""
    model = ROOT / "models" / "scoop.model.json"
    _WATCH[:] = [os.path.realpath(model)]
    _OPENS.clear()
    try:
        for _ in range(3):
            serialize.load_model(model)
        sha256_file(model)
    finally:
        watched = dict(_OPENS)
        _WATCH.clear()
    assert watched == {os.path.realpath(model): 4}


def test_the_hash_and_the_parse_see_the_same_bytes(tmp_path: Path) -> None:
    """A file swapped between the check (its hash) and the use (its parse) inside one session:
    both see the bytes first read; a write through the library is seen by the session."""
    f = tmp_path / "spec.toml"
    f.write_text("# first\n", encoding="utf-8")
    with snapshot.active() as snap:
        first = read_text(f, what="spec", error=tli.SpecError)
        digest = sha256_file(f)
        f.write_text("# swapped behind the session's back\n", encoding="utf-8")
        assert read_text(f, what="spec", error=tli.SpecError) == first
        assert sha256_file(f) == digest
        atomic_write_text(f, "# written by the library\n")
        assert read_text(f, what="spec", error=tli.SpecError) == "# written by the library\n"
        assert snap.opens == 1
    assert read_text(f, what="spec", error=tli.SpecError) == "# written by the library\n"


def _drawer(root: Path, *, dt: str | None) -> Path:
    """A 3-D reaching project of the test's own (``tli init``'s template), its ``dt`` as
    given (None: no ``dt`` line: the default)."""
    from tli_verify.tasks.scaffold import scaffold

    for rel, (_, text) in scaffold("reach", 3).items():
        if rel.startswith("tasks/"):
            lines = [ln if not ln.startswith("dt ") else
                     (f"dt = {dt}" if dt is not None else "") for ln in text.splitlines()]
            text = "\n".join(lines) + "\n"
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    return root


@pytest.mark.parametrize(("dt", "expect"), [(None, DEFAULT_DT), ("0.02", Fraction(1, 50))])
def test_one_rule_settles_the_control_period(tmp_path: Path, dt: str | None,
                                             expect: Fraction,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """The task's dt, else the one default, in the task, ``tli learn``, ``tli certify`` and
    the Python API alike; an explicit period wins."""
    root = _drawer(tmp_path / "p", dt=dt)
    spec = root / "specs" / "reach.toml"
    task = tli.load_task(root / "tasks" / "reach.toml")
    assert Fraction(repr(task.dt)) == expect
    assert control_period(None, spec) == expect
    assert control_period(Fraction(1, 7), spec) == Fraction(1, 7)
    demos = task.demonstrate(seed=0, n_demos=2)
    model = tli.learn(demos, spec=spec, handoff=False)
    fits = {m.fit["control_dt"] for m in model.modes.values() if m.fit}
    assert fits == {float(expect)}
    assert tli.certify(model).dt == expect
    assert tli.certify(model, dt="1/300").dt == Fraction(1, 300)


def test_the_session_runs_a_project_the_test_writes(tmp_path: Path) -> None:
    """open_project from the folder, the model, the spec and the task file: the same files,
    one episode, the certificate's period."""
    root = _drawer(tmp_path / "p", dt=None)
    spec = root / "specs" / "reach.toml"
    task = tli.load_task(root / "tasks" / "reach.toml")
    out = root / "models" / "reach.model.json"
    tli.learn(task.demonstrate(seed=0, n_demos=2), spec=spec, out=out, handoff=False)
    tli.certify(out, out=root / "certificates" / "reach.cert.json")
    seen = set()
    for path in (root, out, spec, root / "tasks" / "reach.toml"):
        s = open_project(path)
        seen.add((os.path.realpath(s.files.model), os.path.realpath(s.files.spec),
                  os.path.realpath(s.files.certificate)))
    assert len(seen) == 1
    episode = s.run(seed=0)
    assert episode.success
    assert s.control_period == DEFAULT_DT
    doc = json.loads((root / "certificates" / "reach.cert.json").read_text("utf-8"))
    assert Fraction(doc["control_period"]["dt"]) == DEFAULT_DT
    with pytest.raises(tli.TaskError, match="outside the workspace"):
        s.run(start=np.full(task.dim, 1e6))
    with pytest.raises(tli.TaskError, match="no such project folder or file"):
        open_project(tmp_path / "nowhere")


def test_tli_verify_reads_every_file_once_and_parses_it_once_in_the_driver(
        capsys: pytest.CaptureFixture[str], counting: Counter[str], tmp_path: Path) -> None:
    """``tli verify`` opens its project session once: the model, the spec and the
    certificate are opened once each (the serial backend runs the campaign in this process,
    so the count covers the runs too), and parsed once each."""
    model = ROOT / "models" / "scoop.model.json"
    spec = ROOT / "specs" / "scoop.toml"
    cert = ROOT / "certificates" / "scoop.cert.json"
    _WATCH[:] = [os.path.realpath(p) for p in (model, spec, cert)]
    _OPENS.clear()
    try:
        code, out, err = tli_run(capsys, "verify", "--model", str(model), "--examples", "3",
                                 "--workers", "1", "--backend", "serial", "--out",
                                 str(tmp_path))
    finally:
        watched = dict(_OPENS)
        _WATCH.clear()
    assert code == 0, err
    assert "3 runs" in out and "no violation found" in out, out
    assert watched == {os.path.realpath(model): 1, os.path.realpath(spec): 1,
                       os.path.realpath(cert): 1}, watched
    assert counting == {"model": 1, "spec": 1}, counting
