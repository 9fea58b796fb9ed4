"""Issue 31, classes 1 and 5: no data loss through the Python API or an interrupted
``tli evidence``; the public API checks its arguments at the boundary.

* The read/write rule is the library's (:func:`tli_verify.io.check_plan`): ``learn``,
  ``certify``, ``save_model`` and ``Certificate.save`` refuse, before any work, an output that is
  one of the files they read -- named or implied (the spec a model names, the spec's task, the
  certificate next to a model) -- exactly as the CLI does; every file stays as it was.
* An interrupted ``tli evidence`` (SIGINT to its process group, as Ctrl-C sends it, or SIGTERM
  to the process) exits 130 with one ``error: interrupted`` line, and the complete evidence
  already there is untouched (a real signal to a real process: nothing is mocked).
* Every public call given a wrong type or a value out of range raises an ``InputError`` that is
  also the builtin it means (``TypeError`` for a type, ``ValueError`` for a value), naming the
  parameter -- never an ``AttributeError``, a numpy or scikit-learn error, nor silence.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import tli_verify as tli
from tests.support.cli import interactive_signals
from tli_verify.errors import InputError, OutputError

REPO = Path(__file__).resolve().parents[2]
FILES = {  # the scoop project, relative to its root
    "task": "tasks/scoop.toml",
    "spec": "specs/scoop.toml",
    "model": "models/scoop.model.json",
    "certificate": "certificates/scoop.cert.json",
    "evidence": "certificates/scoop.campaign.json",
    "demo": "demos/scoop_1.csv",
}


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("hostile-api") / "p"
    for rel in FILES.values():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / rel, root / rel)
    return root


def _digest(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------ class 1: the API's rule
def _certify(out: str) -> Callable[[Path], Any]:
    return lambda r: tli.certify(r / FILES["model"], out=r / FILES[out])


def _certify_object(out: str) -> Callable[[Path], Any]:
    return lambda r: tli.certify(tli.load_model(r / FILES["model"]), out=r / FILES[out])


def _learn(out: str) -> Callable[[Path], Any]:
    return lambda r: tli.learn([r / FILES["demo"]], spec=r / FILES["spec"], out=r / FILES[out])


def _save_model(out: str) -> Callable[[Path], Any]:
    return lambda r: tli.save_model(tli.load_model(r / FILES["model"]), r / FILES[out])


def _cert_save(path: str, model: str | None = None) -> Callable[[Path], Any]:
    def call(r: Path) -> Any:
        cert = tli.Certificate(doc={"control_period": {"dt": "1/100"}},
                               path=r / FILES["certificate"], model_path=r / FILES["model"])
        return cert.save(r / FILES[path], model=None if model is None else r / FILES[model])
    return call


OVERWRITES: dict[str, Callable[[Path], Any]] = {
    **{f"certify(path, out={o})": _certify(o) for o in ("model", "spec", "task")},
    **{f"certify(Model, out={o})": _certify_object(o) for o in ("model", "spec", "task")},
    **{f"learn(out={o})": _learn(o) for o in ("demo", "spec", "task")},
    **{f"save_model(path={o})": _save_model(o)
       for o in ("spec", "task", "certificate", "evidence")},
    "Certificate.save(path=model)": _cert_save("model"),
    "Certificate.save(path=spec)": _cert_save("spec"),
    "Certificate.save(model=spec)": _cert_save("evidence", "spec"),
    "Certificate.save(model=task)": _cert_save("evidence", "task"),
    "Certificate.save(model=path)": _cert_save("evidence", "evidence"),
}


@pytest.mark.parametrize("case", sorted(OVERWRITES))
def test_the_api_never_writes_over_a_file_it_reads(project: Path, case: str) -> None:
    """The library's read/write rule: refused before any work (an OutputError, also a
    ValueError), every file of the project byte-identical."""
    before = _digest(project)
    t0 = time.perf_counter()
    with pytest.raises(OutputError) as info:
        OVERWRITES[case](project)
    assert isinstance(info.value, ValueError) and isinstance(info.value, InputError)
    assert "\n" not in str(info.value)
    assert time.perf_counter() - t0 < 20  # refused up front, not after learning
    assert _digest(project) == before, case


def test_the_cli_inherits_the_librarys_rule() -> None:
    """One rule: the commands' check_plan is the library's."""
    from tli_verify.commands import check_plan
    from tli_verify.io import check_plan as library

    assert check_plan is library


# ------------------------------------------------------------------ class 1: interrupted evidence
def _threads(pid: int) -> int:
    try:
        return len(os.listdir(f"/proc/{pid}/task"))
    except OSError:
        return 0


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs /proc")
@pytest.mark.parametrize("how", ["SIGINT-serial", "SIGTERM-workers-2"])
def test_an_interrupted_tli_evidence_exits_130_and_keeps_the_evidence(
        tmp_path: Path, how: str) -> None:
    """A real signal during a long campaign: exit 130, one ``error: interrupted`` line, and
    the complete evidence file unchanged (before: exit 1 and ``"partial": true, "runs": 0``
    written over it)."""
    root = tmp_path / "p"
    for key in ("task", "spec", "model", "certificate", "evidence"):
        (root / FILES[key]).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / FILES[key], root / FILES[key])
    before = _digest(root)
    argv = [sys.executable, "-m", "tli_verify.cli", "evidence", str(root), "--examples",
            "50000", "--backend", "serial" if how.endswith("serial") else "process"]
    if how.endswith("workers-2"):
        argv += ["--workers", "2"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1"}
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env, preexec_fn=interactive_signals)
    deadline = time.monotonic() + 120
    while _threads(proc.pid) < 2 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.1)  # the campaign's drawing thread has started: the campaign runs
    time.sleep(3.0)
    assert proc.poll() is None, proc.communicate()
    if how.startswith("SIGINT"):
        os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C: the whole foreground group
    else:
        proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, (proc.returncode, out, err)
    assert err.splitlines() == ["error: interrupted"], err
    assert _digest(root) == before


def test_the_library_never_replaces_evidence_with_a_partial_campaign(project: Path) -> None:
    """``write_campaign_evidence`` of a partial result onto an existing file is refused."""
    from types import SimpleNamespace

    from tli_verify.verify.evidence import write_campaign_evidence

    before = _digest(project)
    result = SimpleNamespace(partial=True, runs=0, violations={}, files={})
    config = SimpleNamespace(spec=str(project / FILES["spec"]),
                             model=str(project / FILES["model"]),
                             certificate=str(project / FILES["certificate"]), seed=0,
                             examples=10, modulation=True)
    result.files = {"task": {"path": str(project / FILES["task"]),
                             "sha256": hashlib.sha256(
                                 (project / FILES["task"]).read_bytes()).hexdigest()}}
    with pytest.raises(OutputError, match="partial"):
        write_campaign_evidence(config, result, path=project / FILES["evidence"])
    assert _digest(project) == before


# ------------------------------------------------------------------ class 5: the boundary
@pytest.fixture(scope="module")
def policy(project: Path) -> Any:
    r = project
    return tli.make_policy(r / FILES["spec"], r / FILES["model"], r / FILES["certificate"])


def _calls(r: Path, policy: Any) -> dict[str, tuple[Callable[[], Any], type, str]]:
    """name -> (call, the builtin it must also be, the parameter its message names)."""
    task = tli.load_task(r / FILES["task"])
    model = tli.load_model(r / FILES["model"])
    spec = r / FILES["spec"]
    huge = r / "huge.toml"
    huge.write_text((r / FILES["task"]).read_text().replace("lag = 0", "lag = 1" + "0" * 400))
    return {
        "check_spec(None)": (lambda: tli.check_spec(None), TypeError, "spec"),
        "check_spec(42)": (lambda: tli.check_spec(42), TypeError, "spec"),
        "check_spec('missing')": (lambda: tli.check_spec(r / "nope.toml"), ValueError,
                                  "nope.toml"),
        "synthesize(None)": (lambda: tli.synthesize(None), TypeError, "spec"),
        "run(None)": (lambda: tli.run(None), TypeError, "policy"),
        "run_campaign(None)": (lambda: tli.run_campaign(None), TypeError, "config"),
        "save_model(None)": (lambda: tli.save_model(None, r / "x.json"), TypeError, "model"),
        "save_model(path=None)": (lambda: tli.save_model(model, None), TypeError, "path"),
        "learn(seed=-1)": (lambda: tli.learn([r / FILES["demo"]], spec=spec, seed=-1),
                           ValueError, "seed"),
        "learn(demos=None)": (lambda: tli.learn(None), TypeError, "demos"),
        "learn(demos='a.csv')": (lambda: tli.learn("a.csv"), TypeError, "demos"),
        "learn([None])": (lambda: tli.learn([None]), TypeError, "demos[0]"),
        "learn(spec=3)": (lambda: tli.learn([r / FILES["demo"]], spec=3), TypeError, "spec"),
        "certify(None)": (lambda: tli.certify(None), TypeError, "model"),
        "certify(out=5)": (lambda: tli.certify(r / FILES["model"], out=5), TypeError, "out"),
        "certify(dt=-1)": (lambda: tli.certify(r / FILES["model"], dt="-1"), ValueError, "dt"),
        "load_spec(None)": (lambda: tli.load_spec(None), TypeError, "spec"),
        "load_model(7)": (lambda: tli.load_model(7), TypeError, "model"),
        "load_task(None)": (lambda: tli.load_task(None), TypeError, "task"),
        "load_task(huge int)": (lambda: tli.load_task(huge), ValueError, "lag"),
        "make_policy(variant='bogus')": (
            lambda: tli.make_policy(spec, r / FILES["model"], r / FILES["certificate"],
                                    variant="bogus"), ValueError, "variant"),
        "make_policy(certificate=None)": (
            lambda: tli.make_policy(spec, r / FILES["model"], None), TypeError, "certificate"),
        "run(seed=-1)": (lambda: tli.run(policy, seed=-1), ValueError, "seed"),
        "run(steps=-1)": (lambda: tli.run(policy, steps=-1), ValueError, "steps"),
        "run(steps=1.5)": (lambda: tli.run(policy, steps=1.5), TypeError, "steps"),
        "run(start='abc')": (lambda: tli.run(policy, start="abc"), TypeError, "start"),
        "run(start=3-D)": (lambda: tli.run(policy, start=[0.0, 0.0, 0.0]), ValueError,
                           "start"),
        "run(start=nan)": (lambda: tli.run(policy, start=[np.nan, 0.0]), ValueError, "start"),
        "run(start outside)": (lambda: tli.run(policy, start=[100.0, 0.0]), ValueError,
                               "start"),
        "run(perturbation 3-D)": (lambda: tli.run(policy, start=[-5.0, 4.5],
                                                  perturbations={5: [1.0, 0.0, 0.0]}),
                                  ValueError, "perturbations"),
        "run(perturbation step -1)": (lambda: tli.run(policy, start=[-5.0, 4.5],
                                                      perturbations={-1: [1.0, 0.0]}),
                                      ValueError, "perturbations"),
        "run(task=3)": (lambda: tli.run(policy, task=3), TypeError, "task"),
        "task.clearance(nan)": (lambda: task.clearance([np.nan, 0.0]), ValueError, "NaN"),
        "task.clearance('ab')": (lambda: task.clearance("ab"), TypeError, "x: expected numbers"),
        "task.sensors(NaN)": (lambda: task.sensors(np.full((3, 2), np.nan)), ValueError,
                              "NaN"),
        "task.sensors(inf)": (lambda: task.sensors(np.array([[np.inf, 0.0]])), ValueError,
                              "infinite"),
        "task.sensors('x')": (lambda: task.sensors("x"), TypeError, "X"),
        "run_gate(rerun=-1)": (lambda: tli.run_gate(r, rerun=-1), ValueError, "rerun"),
        "run_gate(rerun='5')": (lambda: tli.run_gate(r, rerun="5"), TypeError, "rerun"),
        "run_gate(None)": (lambda: tli.run_gate(None), TypeError, "root"),
        "find_task(None)": (lambda: tli.find_task(None), TypeError, "task"),
        "load_demos([None])": (lambda: tli.load_demos([None]), TypeError, "demo"),
    }


def test_every_public_call_refuses_bad_arguments_naming_them(project: Path, policy: Any
                                                             ) -> None:
    """42 hostile calls: each raises an InputError that is also the builtin it means, one
    line naming the parameter; nothing is written."""
    calls = _calls(project, policy)
    assert len(calls) >= 40
    failures = []
    for name, (call, builtin, word) in calls.items():
        try:
            call()
        except InputError as exc:
            if not isinstance(exc, builtin) or word not in str(exc) or "\n" in str(exc):
                failures.append(f"{name}: {type(exc).__mro__[:4]} {exc}")
        except Exception as exc:  # a bare error from deep inside
            failures.append(f"{name}: {type(exc).__name__}: {exc}")
        else:
            failures.append(f"{name}: accepted")
    assert not failures, "\n".join(failures)
