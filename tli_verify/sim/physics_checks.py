"""The MuJoCo Franka's physical campaign evidence, as the evidence check judges it.

:data:`FRANKA_PHYSICS` is the :class:`~tli_verify.verify.evidence.PhysicalWorld` that ``tli
gate`` passes to :func:`~tli_verify.verify.evidence.check_evidence`: world
``"franka-physics"``, at least :data:`MIN_PHYSICS_TRIALS` trials, and
:func:`check_physics_block` on the evidence's ``physics`` block. Importing this module loads no
simulator.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from tli_verify.sim.chunks import chunk_seeds
from tli_verify.sim.physics_options import DEFAULT_PHYSICS
from tli_verify.verify.evidence import PhysicalWorld
from tli_verify.verify.evidence.rules import MIN_PHYSICS_TRIALS, REQUIRED_ROBOT

__all__ = ["FRANKA_PHYSICS", "MIN_PHYSICS_TRIALS", "REQUIRED_CONTROLLER", "REQUIRED_ROBOT",
           "REQUIRED_SENSORS", "WORLD", "check_physics_block", "controller_law"]


REQUIRED_CONTROLLER = "measured"
"""The control law the Franka project's evidence must be made with, the one the project
deploys: the DS at the measured pose, its velocity integrated to the target pose of the
Cartesian impedance law (the paper's robot; :func:`tli_verify.sim.loop.run_trial`)."""

REQUIRED_SENSORS = "franka"
"""The sensor model the Franka project's evidence must be made with: the robot's own
(:mod:`tli_verify.sim.franka_sensors`), not the simulator's privileged ones."""


def controller_law(record: Mapping[str, Any]) -> str:
    """The control law an evidence's ``physics.controller`` record names: its ``law``
    (``"measured"``, ``"passive"``, ``"tracking"``); records made before the field said only
    their ``kind`` (``"passive-ds"``: passive; a Cartesian impedance: the tracking law, the
    only impedance law then)."""
    law = record.get("law")
    if isinstance(law, str):
        return law
    return "passive" if record.get("kind") == "passive-ds" else "tracking"


WORLD = "franka-physics"
"""The ``world`` of the Franka's physical campaign evidence."""


def check_physics_block(doc: Mapping[str, Any], shown: str, passed: list[str]) -> list[str]:
    """A physical campaign's block: consistent with the campaign, every trial delivered, made
    on the Panda (:data:`REQUIRED_ROBOT`), in the scene's current solver settings
    (``physics.scene`` equal to :data:`~tli_verify.sim.physics_options.DEFAULT_PHYSICS`), the
    deployed variant, both perturbation levels.

    Parameters
    ----------
    doc : mapping
        The evidence document (schema-valid, with a ``physics`` block).
    shown : str
        The evidence file as named in messages.
    passed : list of str
        What passed is appended here.

    Returns
    -------
    list of str
        The problems found.
    """
    phys = doc["physics"]
    out: list[str] = []
    camp = doc["campaign"]
    trials, successes = int(phys["trials"]), int(phys["successes"])
    if not trials == int(camp["examples"]) == int(camp["runs"]):
        out.append(f"{shown}: physics.trials {trials} differs from campaign.examples "
                   f"{camp['examples']} / runs {camp['runs']} (one run per trial)")
    if successes != trials and not int(doc["violations"]["total"]):
        out.append(f"{shown}: {trials - successes} of {trials} physical trial(s) delivered no "
                   "soup: not evidence for deployment")
    outcomes = phys.get("outcomes")
    if outcomes is not None:
        seeds = [int(o["seed"]) for o in outcomes]
        first = int(camp["seed"])
        if len(outcomes) != trials or seeds != list(range(first, first + len(outcomes))):
            out.append(f"{shown}: physics.outcomes lists {len(outcomes)} trial(s) with seeds "
                       f"other than {first}..{first + trials - 1}")
        elif sum(bool(o["success"]) for o in outcomes) != successes or any(
                o["violations"] for o in outcomes) != bool(doc["violations"]["total"]):
            out.append(f"{shown}: physics.outcomes disagree with physics.successes or the "
                       "violations")
    out += _check_partition(doc, shown)
    if phys["robot"] != REQUIRED_ROBOT:
        out.append(f"{shown}: the trials ran on the {phys['robot']!r} rig, not the Panda: "
                   "evidence for the Franka project must be made on the arm (tli sim franka "
                   "--robot panda --trials 30 --evidence)")
    controller = phys.get("controller")
    kind = controller.get("kind") if isinstance(controller, dict) else None
    if phys.get("controller") is None or phys.get("sensors") is None:
        out.append(f"{shown}: the evidence does not say which controller and sensors its "
                   "trials ran with; make it again (tli evidence sim/franka)")
    else:
        law = controller_law(controller) if isinstance(controller, dict) else None
        if law != REQUIRED_CONTROLLER:
            out.append(f"{shown}: the trials ran the {law!r} control law ({kind}), the "
                       f"project deploys {REQUIRED_CONTROLLER!r} (the DS at the measured pose "
                       "integrated to the impedance law's target): not evidence for it")
        if phys["sensors"] != REQUIRED_SENSORS:
            out.append(f"{shown}: the trials ran with the {phys['sensors']!r} sensors, the "
                       f"project's robot reads its own ({REQUIRED_SENSORS!r}): not evidence "
                       "for it")
    scene = phys.get("scene")
    current = DEFAULT_PHYSICS.to_dict()
    if scene is None:
        out.append(f"{shown}: physics.scene is missing: the evidence does not say which solver "
                   "settings its trials ran with; make it again (tli evidence sim/franka)")
    elif dict(scene) != current:
        out.append(f"{shown}: the trials ran the scene with {_settings(scene)}, but the scene's "
                   f"default (which tli gate --rerun and the deployed loop use) is "
                   f"{_settings(current)}: make the evidence again (tli evidence sim/franka)")
    if phys["variant"] != "LTL-DS":
        out.append(f"{shown}: the trials ran the {phys['variant']!r} ablation, the deployed "
                   "policy is LTL-DS (modulation and replanning on): not evidence for it")
    if int(phys["pushes"]) < 1 or int(phys["tilts"]) < 1:
        out.append(f"{shown}: {phys['pushes']} push(es) and {phys['tilts']} tilt(s) per trial: "
                   "the evidence must perturb at both levels (motion pushes and task tilts)")
    elif int(phys["pushes"]) > 1 or int(phys["tilts"]) > 1:  # the schema admits up to 64
        out.append(f"{shown}: {phys['pushes']} push(es) and {phys['tilts']} tilt(s) per trial: "
                   "tli sim franka records one push and one tilt per perturbed trial; no "
                   "command writes these settings (the gate's re-run would take them)")
    if not out:
        chunks = phys.get("chunks")
        split = "" if chunks is None or len(chunks) == 1 else \
            f" in {len(chunks)} chunks of seeds, one executive each"
        passed.append(f"{trials} perturbed physical trial(s){split} ({phys['pushes']} push(es), "
                      f"{phys['tilts']} tilt(s) each; robot {phys['robot']}, "
                      f"{controller_law(controller)} law, "
                      f"{phys['sensors']} sensors, stall rule "
                      f"{'on' if phys.get('retry', True) else 'off'}, "
                      f"{phys['duration']:g} s budget), all delivered soup")
    return out


FRANKA_PHYSICS = PhysicalWorld(name=WORLD, min_trials=MIN_PHYSICS_TRIALS,
                               check=check_physics_block)
"""The MuJoCo Franka's physical campaigns, for
:func:`~tli_verify.verify.evidence.check_evidence`."""


def _settings(scene: Mapping[str, Any]) -> str:
    """``sleep=..., sleep_tolerance=..., solver=..., impratio=...`` for messages."""
    return ", ".join(f"{k}={scene.get(k)!r}" for k in ("sleep", "sleep_tolerance", "solver",
                                                         "impratio"))


def _check_partition(doc: Mapping[str, Any], shown: str) -> list[str]:
    """``physics.workers`` and ``physics.chunks``, when recorded: the contiguous partition
    :func:`~tli_verify.sim.chunks.chunk_seeds` gives the campaign's seed, trials and workers,
    and the same workers as the campaign block."""
    phys, camp = doc["physics"], doc["campaign"]
    workers = int(phys.get("workers", 1))
    if "workers" in phys and camp.get("workers") is not None and \
            int(camp["workers"]) != workers:
        return [f"{shown}: physics.workers {workers} differs from campaign.workers "
                f"{camp['workers']}"]
    chunks = phys.get("chunks")
    if chunks is None:
        return []
    expected = chunk_seeds(int(camp["seed"]), int(phys["trials"]), workers)
    if [tuple(int(v) for v in c) for c in chunks] != list(expected):
        want = ", ".join(f"[{a}, {n}]" for a, n in expected)
        return [f"{shown}: physics.chunks is not the contiguous partition of the seeds into "
                f"{workers} chunk(s) (expected {want})"]
    return []
