"""The pipeline from Python, with objects as well as paths, on a task no shipped file has.

The 3-D drawer (:mod:`tests.support.drawer3d`: a ball among boxes, a latch, a goal mode that is
not a sink) goes spec -> automaton -> demonstrations in memory -> model -> certificate ->
policy -> episode through the public namespace only (``import tli_verify as tli``), and the
result is the one the files give: the certificate a saved pair re-issues is the same
document, and a certificate of another model is refused where the policy is built.
"""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

import pytest

import tli_verify as tli
from tests.support.drawer3d import write_project


@pytest.fixture(scope="module")
def drawer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_project(tmp_path_factory.mktemp("drawer-api"))


@pytest.fixture(scope="module")
def learned(drawer: Path) -> tli.Model:
    """Learned from demonstrations in memory (no CSV written): a model with no file."""
    task = tli.load_task(drawer / "tasks" / "drawer.toml")
    return tli.learn(task.demonstrate(seed=0), spec=tli.load_spec(drawer / "specs" /
                                                                   "drawer.toml"))


def test_the_pipeline_runs_from_python_with_objects(drawer: Path, learned: tli.Model) -> None:
    spec = tli.load_spec(drawer / "specs" / "drawer.toml")
    assert tli.check_spec(spec).realizable
    automaton = tli.synthesize(spec)
    assert "d" in automaton.modes
    task = tli.load_task(drawer / "tasks" / "drawer.toml")
    assert task.dim == 3
    model = learned
    assert isinstance(model, tli.Model) and model.dim == 3 and model.path is None
    assert all(d["path"].startswith("in-memory:") for d in model.source["demos"])
    cert = tli.certify(model)  # an unsaved model: kept with the certificate
    assert isinstance(cert, tli.Certificate)
    assert cert.ok and cert.dt == Fraction(1, 100)  # the task's own control period
    policy = tli.make_policy(spec, model, cert)
    assert isinstance(policy, tli.LTLDSPolicy)
    episode = tli.run(policy, task=task, start=[0.2, 0.5, 0.8])
    assert episode.success and episode.modes[-1] == "d"
    # a push back out of the slide in 3-D: the executive replans and still finishes
    pushed = tli.run(policy, task=task, start=[0.2, 0.5, 0.8],
                     perturbations={250: [0.25, 0.5, 0.75]})
    assert pushed.success


def test_saved_files_give_the_same_certificate_and_policy(drawer: Path, tmp_path: Path
                                                         ) -> None:
    spec_path = drawer / "specs" / "drawer.toml"
    demos = tli.load_task(drawer / "tasks" / "drawer.toml").demonstrate(seed=0)
    model = tli.learn(demos, spec=spec_path, out=drawer / "models" / "drawer.model.json")
    assert model.path is not None and Path(model.path).is_file()
    cert = tli.certify(model, out=drawer / "certificates" / "drawer.cert.json")
    doc = json.loads((drawer / "certificates" / "drawer.cert.json").read_text())
    assert doc == cert.to_dict() and cert.ok
    # the certificate object and its file build the same policy
    from_files = tli.make_policy(spec_path, drawer / "models" / "drawer.model.json",
                                 drawer / "certificates" / "drawer.cert.json")
    from_objects = tli.make_policy(tli.load_spec(spec_path), model, cert)
    a = tli.run(from_files, start=[0.2, 0.5, 0.8])
    b = tli.run(from_objects, start=[0.2, 0.5, 0.8])
    assert a.success and a.steps == b.steps
    assert a.states == pytest.approx(b.states, abs=1e-12)
    # Certificate.save writes the pair elsewhere and re-issues for the saved bytes
    moved = cert.save(tmp_path / "c.cert.json", model=tmp_path / "m.model.json")
    assert moved.ok and moved.model_path == tmp_path / "m.model.json"


def test_a_certificate_of_another_model_is_refused(drawer: Path, learned: tli.Model) -> None:
    spec_path = drawer / "specs" / "drawer.toml"
    model = learned
    other = tli.learn(tli.load_task(drawer / "tasks" / "drawer.toml").demonstrate(seed=1),
                      spec=spec_path)
    cert_other = tli.certify(other)
    cert = tli.certify(model)  # its private folder (the model file) lives as long as it does
    with pytest.raises(tli.CertificateError):
        tli.make_policy(spec_path, cert.model_path, cert_other)
    folder = cert.model_path.parent
    del cert
    import gc

    gc.collect()
    assert not folder.exists()  # nothing left behind
    # never saved, and no certificate object to find its file: bad input, a ValueError
    with pytest.raises(ValueError, match="never saved"):
        tli.make_policy(spec_path, model, cert_other.path)
