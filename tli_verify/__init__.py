"""tli-verify: Temporal Logic Imitation (LTL-DS) with certificates anyone can re-check.

The public namespace (``__all__``) follows the data flow -- spec -> automaton; demos -> modes
-> DS -> certificate -> cuts/modulation -> policy -> campaign -> gate::

    import tli_verify as tli

    spec = tli.load_spec("specs/scoop.toml")
    assert tli.check_spec(spec).realizable
    model = tli.learn(["demos/scoop_1.csv", "demos/scoop_2.csv"], spec=spec)
    cert = tli.certify(model)
    policy = tli.make_policy(spec, model, cert)
    episode = tli.run(policy, start=[-5.0, 4.5])

Every name is imported lazily (``tli --help`` and ``import tli_verify`` stay fast: Spot, CUDD
and cvxpy load only when used). Everything else lives in the subpackages; names there may
change between releases, these do not without a changelog entry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from tli_verify._lazy import lazy_namespace

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from tli_verify._version import __version__
    from tli_verify.api import Certificate, certify, learn, make_policy, run, save_model
    from tli_verify.demos import Demonstration, load_demos
    from tli_verify.deploy.gate import GateReport, run_gate
    from tli_verify.errors import (
        CertificateError,
        CheckFailed,
        DemoError,
        GateError,
        InputError,
        ModelError,
        OutputError,
        SpecError,
        TaskError,
        TliError,
    )
    from tli_verify.logic.automaton import TaskAutomaton
    from tli_verify.logic.check import check_spec, synthesize
    from tli_verify.logic.spec import GR1Spec, load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.model.types import Model
    from tli_verify.project.period import control_period
    from tli_verify.project.session import Session, open_project
    from tli_verify.runtime.executive import LTLDSPolicy
    from tli_verify.runtime.loop import EpisodeResult
    from tli_verify.tasks.project import resolve
    from tli_verify.tasks.registry import find_task
    from tli_verify.tasks.task import Task
    from tli_verify.tasks.taskfile import load_task
    from tli_verify.verify.campaign import run_campaign
    from tli_verify.verify.config import CampaignConfig
    from tli_verify.verify.evidence.write import write_campaign_evidence

_NAMES: dict[str, str] = {
    "__version__": "tli_verify._version",
    # specs and task automata (paper Sec. 4)
    "load_spec": "tli_verify.logic.spec",
    "GR1Spec": "tli_verify.logic.spec",
    "check_spec": "tli_verify.logic.check",
    "synthesize": "tli_verify.logic.check",
    "TaskAutomaton": "tli_verify.logic.automaton",
    # tasks as data
    "load_task": "tli_verify.tasks.taskfile",
    "find_task": "tli_verify.tasks.registry",
    "Task": "tli_verify.tasks.task",
    "resolve": "tli_verify.tasks.project",
    # a project opened once: files found, read and settled once
    "open_project": "tli_verify.project.session",
    "Session": "tli_verify.project.session",
    "control_period": "tli_verify.project.period",
    # demonstrations and learning (paper Sec. 5)
    "load_demos": "tli_verify.demos",
    "Demonstration": "tli_verify.demos",
    "learn": "tli_verify.api",
    "Model": "tli_verify.model.types",
    "load_model": "tli_verify.model.serialize",
    "save_model": "tli_verify.api",
    # certificates (paper eq. 5, checked exactly)
    "certify": "tli_verify.api",
    "Certificate": "tli_verify.api",
    # the executive (paper eq. 6) and one episode
    "make_policy": "tli_verify.api",
    "LTLDSPolicy": "tli_verify.runtime.executive",
    "run": "tli_verify.api",
    "EpisodeResult": "tli_verify.runtime.loop",
    # campaigns and the gate
    "CampaignConfig": "tli_verify.verify.config",
    "run_campaign": "tli_verify.verify.campaign",
    "write_campaign_evidence": "tli_verify.verify.evidence.write",
    "run_gate": "tli_verify.deploy.gate",
    "GateReport": "tli_verify.deploy.gate",
    # errors (each input error is also the builtin it means: ValueError, FileNotFoundError)
    "TliError": "tli_verify.errors",
    "SpecError": "tli_verify.errors",
    "TaskError": "tli_verify.errors",
    "DemoError": "tli_verify.errors",
    "ModelError": "tli_verify.errors",
    "CertificateError": "tli_verify.errors",
    "GateError": "tli_verify.errors",
    "InputError": "tli_verify.errors",
    "OutputError": "tli_verify.errors",
    "CheckFailed": "tli_verify.errors",
}

__all__ = [
    "CampaignConfig",
    "Certificate",
    "CertificateError",
    "CheckFailed",
    "DemoError",
    "Demonstration",
    "EpisodeResult",
    "GR1Spec",
    "GateError",
    "GateReport",
    "InputError",
    "LTLDSPolicy",
    "Model",
    "ModelError",
    "OutputError",
    "Session",
    "SpecError",
    "Task",
    "TaskAutomaton",
    "TaskError",
    "TliError",
    "__version__",
    "certify",
    "check_spec",
    "control_period",
    "find_task",
    "learn",
    "load_demos",
    "load_model",
    "load_spec",
    "load_task",
    "make_policy",
    "open_project",
    "resolve",
    "run",
    "run_campaign",
    "run_gate",
    "save_model",
    "synthesize",
    "write_campaign_evidence",
]


__getattr__, __dir__ = lazy_namespace("tli_verify", _NAMES, globals(), __all__)
