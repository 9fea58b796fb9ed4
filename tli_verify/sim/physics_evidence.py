"""The campaign evidence of a physical campaign (``certificates/franka-scoop.campaign.json``).

:func:`write_physics_evidence` writes the evidence ``tli gate`` requires of a Franka project
(:mod:`tli_verify.verify.evidence`, world :data:`WORLD`): the campaign's settings and outcomes,
the hashes of the files it ran on and, if a trial failed, how to reproduce it.
:func:`settings_from` reads a re-run's settings back from the evidence's ``physics`` block.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (30 perturbed trials on the Panda, all
successful) and Sec. 4.4 (perturbation campaigns).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from tli_verify.io import check_output_file
from tli_verify.runtime.stall import StallRule
from tli_verify.sim.campaign import PhysicsResult
from tli_verify.sim.chunks import chunk_seeds
from tli_verify.sim.contact import ContactDetector
from tli_verify.sim.demos import PANDA_IMPEDANCE
from tli_verify.sim.franka_files import MODEL_NAME
from tli_verify.sim.franka_limits import FrankaLimits
from tli_verify.sim.passive import PassiveGains
from tli_verify.sim.physics_checks import WORLD, controller_law
from tli_verify.sim.physics_options import DEFAULT_PHYSICS
from tli_verify.sim.target import LEASH
from tli_verify.verify.evidence import EVIDENCE_SUFFIX, deployed_task_block, write_evidence

__all__ = [
    "settings_from",
    "write_physics_evidence",
]


"""The evidence's world name for the physical campaign (:mod:`tli_verify.verify.evidence`)."""


def _counterexample(result: PhysicsResult) -> dict[str, Any] | None:
    """The first failing trial (how to reproduce it), or None."""
    for res, verdict in zip(result.results, result.verdicts, strict=True):
        if not verdict.ok:
            c = result.config
            return {"seed": res.seed, "violations": list(verdict.violations),
                    "messages": list(verdict.messages), "delivered": res.delivered,
                    "mode_sequence": res.mode_sequence(),
                    "perturbations": [p.to_dict() for p in res.perturbations],
                    "reproduce": f"tli sim franka --certificates {c.cert_dir} "
                                 f"--seed {res.seed} --trials 1 --robot {c.robot} "
                                 f"--duration {c.duration:g} --sensors {c.sensors}"
                                 + f" --controller {c.controller}"
                                 + ("" if c.retry else " --no-retry")}
    return None


def write_physics_evidence(result: PhysicsResult, path: str | os.PathLike[str] | None = None,
                           *, inputs: Sequence[str | os.PathLike[str]] = (),
                           evaluator: dict[str, Any] | None = None
                           ) -> tuple[Path, dict[str, Any]]:
    """Write the campaign evidence of a physical campaign (atomically, canonical JSON).

    Parameters
    ----------
    result : PhysicsResult
    path : path-like, optional
        Default ``<cert_dir>/franka-scoop.campaign.json`` (``<root>/certificates``).
    inputs : sequence of path-like, optional
        Other files the evidence must not overwrite (the demonstrations, a plot, ...).
    evaluator : dict, optional
        The trials ran an exported artifact in the C evaluator (``physics.evaluator``:
        ``kind``, ``artifact_sha256``, ``steps``, ``max_rel_diff``).

    Returns
    -------
    (Path, dict)
        The file and the document. Evidence of failing trials is written too, as an honest
        record: the gate refuses it.

    Raises
    ------
    EvidenceError
        (exit 2) A file changed since the campaign started, or is missing.
    OutputError
        (exit 2) The path cannot be written or is one of the inputs.
    """
    import mujoco

    c = result.config
    target = Path(path) if path is not None else \
        c.cert_dir / f"{MODEL_NAME}{EVIDENCE_SUFFIX}"
    check_output_file(target, inputs=list(inputs), what="campaign evidence")
    files = {name: Path(p) for name, p, _ in result.files}
    physics: dict[str, Any] = dict(c.settings())
    physics.update({
        "trials": len(result.results), "successes": result.successes,
        "delivered": sum(r.delivered for r in result.results),
        "cuts_added": result.cuts_added, "mujoco": str(mujoco.__version__),
        "wall_time": round(result.wall_time, 2),
        "controller": controller_record(c.robot, c.controller),
        "stall_rule": _stall_rule() if c.retry else None,
        "stalls": sum(r.stalls for r in result.results),
        "scene": DEFAULT_PHYSICS.to_dict(),  # the trials ran the scene's default (run_trial)
        "retries": sum(r.retries for r in result.results),
        # the partition: one executive per chunk, cuts carried over within it
        "workers": int(c.workers),
        "chunks": [[int(first), int(n)] for first, n in
                   (result.chunks or chunk_seeds(c.seed, len(result.results), c.workers))],
        "outcomes": [{"seed": r.seed, "success": bool(r.success), "delivered": r.delivered,
                      "violations": list(v.violations), "retries": r.retries,
                      "stalls": r.stalls, "stall_fired": r.stalls > 0,
                      "cut_gap": dict(r.cut_gap), "tank_low": r.tank_low,
                      "stopped": r.stopped, "perturbed_steps": r.perturbed_steps,
                      "limit_ratios": dict(r.limit_ratios)}
                     for r, v in zip(result.results, result.verdicts, strict=True)],
    })
    if evaluator is not None:
        physics["evaluator"] = dict(evaluator)
    doc = write_evidence(
        target, world=WORLD, task=deployed_task_block(files["model"], target.parent),
        spec=files["spec"], model=files["model"],
        certificate=files["certificate"], seed=c.seed, examples=len(result.results),
        runs=len(result.results), violations=result.violations,
        modulation=c.variant != "no-modulation", partial=False,
        backend=c.backend, workers=c.workers,
        counterexample=_counterexample(result), physics=physics,
        expected={name: sha for name, _, sha in result.files if sha})
    return target, doc


def _stall_rule() -> dict[str, float]:
    """The stall rule's settings (:class:`~tli_verify.runtime.stall.StallRule`)."""
    return StallRule().to_dict()


def controller_record(robot: str, controller: str = "measured") -> dict[str, Any]:
    """The controller settings a physical campaign ran with (the evidence's
    ``physics.controller``): the control law (``law``: measured, passive or tracking, and
    where the DS is evaluated, ``ds_at``), for the Panda its torque law (passive-DS with its
    gains, or the Cartesian impedance), the limits and the torque-loop period, and the
    perturbation detector; for the free tool its impedance law."""
    common = {"detector": ContactDetector().to_dict(), "leash": [float(v) for v in LEASH],
              "law": controller,
              "ds_at": "target" if controller == "tracking" else "measured pose"}
    if robot == "panda" and controller == "passive":
        return {"detector": ContactDetector().to_dict(), "kind": "passive-ds",
                "law": controller, "ds_at": "measured pose",
                "gains": PassiveGains().to_dict(), "limits": FrankaLimits().to_dict(),
                "torque_period": 0.002, "ds_period": 0.02}
    if robot == "panda":
        return dict(common, kind="cartesian-impedance", impedance=PANDA_IMPEDANCE.to_dict(),
                    limits=FrankaLimits().to_dict(), torque_period=0.002,
                    feed_forward=True)
    return dict(common, kind="free-body-impedance", stiffness_pos=2000.0, stiffness_rot=150.0)


def settings_from(physics: Mapping[str, Any]) -> dict[str, Any]:
    """:class:`~tli_verify.sim.physics_config.PhysicsConfig` keyword arguments from an
    evidence's ``physics`` block."""
    keys = ("robot", "variant", "duration", "pushes", "tilts", "retry", "sensors")
    out = {k: physics[k] for k in keys if k in physics}
    record = physics.get("controller")
    if isinstance(record, Mapping):  # the law is recorded with its gains
        out["controller"] = controller_law(record)
    return out
