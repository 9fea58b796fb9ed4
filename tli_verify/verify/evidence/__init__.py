"""Campaign evidence: ``certificates/<name>.campaign.json``, required by ``tli gate``.

A deployed model needs, besides its Lyapunov certificate, evidence that a bisimulation campaign
(``tli verify``: generated perturbation sequences against invariance and reachability, paper
Sec. 4.4, Thm. 2, Asm. 2) ran on *its exact files* and found nothing. The evidence file (schema
``tli_verify/schemas/campaign.schema.json``) binds, by SHA-256 of their exact bytes (the
certificate's convention, :mod:`tli_verify.certification.certificate`):

* the spec, the model and the certificate (paths relative to the evidence file's directory);
* the task the campaign ran on (``task``): a task file by its SHA-256, an entry point by its
  distribution, version and the SHA-256 of its module's source. The gate recomputes it for the
  task the deployed spec names (:func:`tli_verify.tasks.project.resolve`) and blocks on any
  difference: another task's evidence, an edited region, a renamed task;
* the seed, the number of examples (perturbation sequences) and of runs (simulations), whether
  modulation was on (it must be: that is the deployed policy) and whether the campaign was
  interrupted (``partial``: then it is not evidence);
* the violations found, by kind (``total`` must be 0 to deploy) and the counterexample (null);
* what the campaign means, :data:`CAMPAIGN_SEMANTICS` (``campaign_semantics``: the gate requires
  this tool's), and the tool version (``tool``: information only, never compared, so a release
  that changes nothing a campaign means keeps the evidence valid); and ``digest``, the SHA-256
  of the canonical JSON of everything else.

Nothing in it is trusted: :func:`check_evidence` re-reads it (bounded, regular files only, never
a symlink), recomputes the digest and the three hashes, requires the spec to be the one the
model names and the certificate to cover the model, and requires ``violations.total == 0``,
no counterexample, modulation on, a complete campaign and at least
:data:`MIN_EVIDENCE_EXAMPLES` examples. ``tli gate --rerun N`` additionally re-runs a short
campaign with the evidence's seed (:mod:`tli_verify.deploy.gate`).

Write evidence with :func:`write_evidence` (``tli verify ... --evidence``, or
``tli evidence DIR`` for every model of a project).

Physical campaigns
-----------------------------
The Franka policy (``sim/franka``) runs in MuJoCo, not in a 2-D world: its evidence has the world
``"franka-physics"`` (a :class:`PhysicalWorld`, whose checks live in
:mod:`tli_verify.sim.physics_checks`) and a ``physics`` block (robot, variant, duration,
pushes and tilts per trial, trials, successes, the MuJoCo version, per-trial outcomes), written
by ``tli sim franka --evidence`` or ``tli evidence sim/franka``
(:func:`tli_verify.sim.physics_evidence.write_physics_evidence`).
Each example is one perturbed physical
trial (seconds each), so the minimum is
:data:`~tli_verify.sim.physics_checks.MIN_PHYSICS_TRIALS` (the paper's 30 trials), and
the gate also requires every trial to have delivered soup, the deployed variant (``LTL-DS``) and
both perturbation levels (pushes and tilts). ``tli gate --rerun N`` re-runs ``N`` physical
trials with the recorded settings.
"""

from __future__ import annotations

from tli_verify.verify.evidence.check import (
    EvidenceCheck,
    check_evidence,
    deployed_task_block,
)
from tli_verify.verify.evidence.common import (
    evidence_digest,
    evidence_path_for,
    model_stem,
    task_block,
    task_content_sha256,
)
from tli_verify.verify.evidence.rules import (
    CAMPAIGN_SEMANTICS,
    EVIDENCE_KIND,
    EVIDENCE_SCHEMA_VERSION,
    EVIDENCE_SUFFIX,
    MIN_EVIDENCE_EXAMPLES,
    MIN_MAX_PUSHES,
    MIN_WINDOW,
    PhysicalWorld,
)
from tli_verify.verify.evidence.settings import (
    settings_for_config,
    settings_problems,
)
from tli_verify.verify.evidence.write import (
    build_evidence,
    weaker_than_recorded,
    write_campaign_evidence,
    write_evidence,
)

__all__ = [
    "CAMPAIGN_SEMANTICS",
    "EVIDENCE_KIND",
    "EVIDENCE_SCHEMA_VERSION",
    "EVIDENCE_SUFFIX",
    "MIN_EVIDENCE_EXAMPLES",
    "MIN_MAX_PUSHES",
    "MIN_WINDOW",
    "EvidenceCheck",
    "PhysicalWorld",
    "build_evidence",
    "check_evidence",
    "deployed_task_block",
    "evidence_digest",
    "evidence_path_for",
    "model_stem",
    "settings_for_config",
    "settings_problems",
    "task_block",
    "task_content_sha256",
    "weaker_than_recorded",
    "write_campaign_evidence",
    "write_evidence",
]
