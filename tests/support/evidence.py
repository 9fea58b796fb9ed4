"""Binding-only campaign evidence for tests of the gate's *other* checks.

The gate requires campaign evidence for every deployed model. Tests that exercise
the certificate, spec, modes or dimension checks attach evidence with :func:`attach_evidence`:
it binds the project's current files exactly as ``tli verify --evidence`` does, with the minimum
number of examples and no violation. It says nothing about the policy; the campaign itself is
tested in ``tests/integration/test_verify_cli.py`` and the evidence check in
``tests/unit/test_evidence.py``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tli_verify.verify.evidence import (
    MIN_EVIDENCE_EXAMPLES,
    evidence_path_for,
    task_block,
    write_evidence,
)


def attach_evidence(project: Path, name: str = "scoop", **overrides: Any) -> Path:
    """Write ``certificates/<name>.campaign.json`` for ``models/<name>.model.json``.

    Parameters
    ----------
    project : Path
        Holds ``models/<name>.model.json``, ``certificates/<name>.cert.json`` and the spec the
        model names (``specs/scoop.toml`` for the bundled model).
    name : str, optional
    **overrides
        Fields of :func:`tli_verify.verify.evidence.build_evidence` to change.

    Returns
    -------
    Path
        The evidence file.
    """
    from tli_verify.logic.spec import load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.tasks.project import spec_task
    from tli_verify.tasks.registry import find_task

    model = project / "models" / f"{name}.model.json"
    spec = load_model(model).spec_path or project / "specs" / "scoop.toml"  # none named: any
    path = evidence_path_for(model)
    try:  # the task the spec names (the gate binds it), else the bundled scoop task
        task = spec_task(load_spec(spec), spec) or find_task("scoop")
    except Exception:
        task = find_task("scoop")
    fields: dict[str, Any] = {
        "world": task.name, "task": task_block(task, path.parent), "spec": spec, "model": model,
        "certificate": project / "certificates" / f"{name}.cert.json", "seed": 0,
        "examples": MIN_EVIDENCE_EXAMPLES, "runs": MIN_EVIDENCE_EXAMPLES, "violations": {},
        "modulation": True, "backend": "process", "workers": 2, "inconclusive": 0,
        "settings": {"window": 700, "max_pushes": 3, "batch_size": 100},
    }
    fields.update(overrides)
    write_evidence(path, **fields)
    return path
