"""The scoop task's closed-loop setups: the bundled one, and ones learned from seeded demos.

:func:`scoop_setup` loads the bundled ``tasks/scoop.toml`` with its spec, model and certificate;
:func:`learn_setup` learns and certifies a scoop model (at the task's ``dt``) from seeded
demonstrations of the scoop task's scripted demonstrator, with BC nets per mode if asked. Both
give a :class:`~tli_verify.runtime.setup.Setup` of the generic closed loop
(:mod:`tli_verify.runtime.setup`); this module names the scoop task on purpose.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 and appendix "Multi-modal Experiments".
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path
from typing import Any

from tli_verify.demos import load_demo
from tli_verify.ds.bc import train_bc
from tli_verify.logic.check import synthesize
from tli_verify.logic.spec import load_spec
from tli_verify.model.learn import learn_model
from tli_verify.model.serialize import load_model, save_model
from tli_verify.project import open_project
from tli_verify.runtime.setup import Setup
from tli_verify.segmentation import segment_demos, spec_labeler
from tli_verify.tasks.demonstrator import write_demos
from tli_verify.tasks.registry import find_task

__all__ = [
    "learn_setup",
    "scoop_setup",
]


def scoop_setup(*, lag: int = 0) -> Setup:
    """The bundled scoop task, spec, model and certificate (the project session of task
    ``scoop``: :func:`~tli_verify.project.open_project`)."""
    return open_project(task="scoop", lag=lag).setup


def learn_setup(seed: int, n_demos: int, directory: str | os.PathLike[str], *,
                lag: int = 0, bc_epochs: int = 0) -> Setup:
    """Learn and certify a scoop model from ``n_demos`` seeded demonstrations.

    Writes ``scoop_<i>.csv``, ``scoop.model.json`` and ``scoop.cert.json`` (at the task's
    control period, ``dt = 1/100``) under ``directory``; with ``bc_epochs > 0`` also trains
    one BC net per DS key on the raw (unshifted) segments of its mode.
    """
    from tli_verify.certification.certificate import issue_certificate, write_certificate

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    task = find_task("scoop")
    spec_path = task.spec_path
    assert spec_path is not None
    demos = write_demos(task, d, seed=seed, n_demos=n_demos)
    mpath, cpath = d / "scoop.model.json", d / "scoop.cert.json"
    dt = Fraction(repr(task.dt))  # the task's control period: the certificate proves it
    model = learn_model(demos, out_path=mpath, spec_path=spec_path, seed=seed,
                        control_dt=float(dt))
    save_model(model, mpath)
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt=dt), cpath)
    spec = load_spec(spec_path)
    bc: dict[str, Any] = {}
    if bc_epochs > 0:

        labeler, modes, labels = spec_labeler(spec)
        seg = segment_demos([load_demo(p) for p in demos], labeler=labeler, modes=modes,
                            labels=labels, shift=False)
        for key, data in seg.data.items():
            bc[key] = train_bc(data.x, data.dx, seed=seed, max_epochs=bc_epochs)
    return Setup(task=task.with_lag(lag), automaton=synthesize(spec), model=load_model(mpath),
                 certificate=str(cpath), spec=str(spec_path), bc=bc)
