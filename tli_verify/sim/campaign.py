"""Physical perturbation campaigns of the Franka soup-scooping policy: run and judge the trials.

The 2-D tasks are verified by bisimulation campaigns (:mod:`tli_verify.verify.campaign`); the
Franka policy runs in MuJoCo, where a trial costs seconds, so its campaign is a few dozen
perturbed physical trials (the paper's 30). :func:`run_physics_campaign` runs the seeded trials
``seed, seed + 1, ...`` of a :class:`~tli_verify.sim.physics_config.PhysicsConfig`, as ``tli sim
franka --trials N --seed S`` runs them, each with the perturbations
:func:`tli_verify.sim.perturbations.draw` gives its seed, and judges each with the physics
oracle (:func:`tli_verify.sim.trial_oracle.check_trial`); the :class:`PhysicsResult` becomes
campaign evidence through :func:`tli_verify.sim.physics_evidence.write_physics_evidence`.

The trials run on the backends of the 2-D campaigns
(:func:`tli_verify.verify.backends.make_backend`: ``serial``, ``process`` or ``dask``). Work
travels in batches: :func:`~tli_verify.sim.chunks.chunk_seeds` splits the seeds into
``config.workers`` contiguous chunks, and each chunk is run by one worker with its own
executive, whose learned cuts carry over from trial to trial within the chunk, as on one robot.
The partition depends only on ``(seed, trials, workers)``, never on the scheduling, so the same
settings give the same trials and verdicts, in seed order, on every backend. ``workers=1`` (the
default) is one executive for all the trials.

References
----------
Wang, Figueroa, Li, Shah, Shah, "Temporal Logic Imitation: Learning Plan-Satisficing Motion
Policies from Demonstrations", CoRL 2022, Sec. 7.2 (30 perturbed trials on the Panda, all
successful) and Sec. 4.4 (perturbation campaigns, Asm. 2: finitely many perturbations).
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tli_verify.errors import CampaignError
from tli_verify.runtime.executive import LTLDSPolicy
from tli_verify.sim.chunks import chunk_seeds
from tli_verify.sim.franka_files import hash_files
from tli_verify.sim.franka_project import load_policy
from tli_verify.sim.loop import TrialResult, run_trial
from tli_verify.sim.perturbations import draw
from tli_verify.sim.physics_config import PhysicsConfig
from tli_verify.sim.trial_oracle import VIOLATION_KINDS, TrialVerdict, check_trial
from tli_verify.verify.backends import make_backend

__all__ = [
    "PhysicsResult",
    "chunk_seeds",  # from tli_verify.sim.chunks
    "run_physics_campaign",
]


@dataclass(frozen=True, slots=True)
class PhysicsResult:
    """A finished physical campaign.

    Attributes
    ----------
    config : PhysicsConfig
        Its ``workers`` and ``backend`` say where the trials ran.
    results : tuple of TrialResult
        In seed order.
    verdicts : tuple of TrialVerdict
        The oracle's, one per trial.
    files : tuple of (str, str, str)
        ``(name, path, SHA-256)`` of the spec, model and certificate when the campaign started
        (a file changed during it is refused when the evidence is written).
    wall_time : float
        Seconds.
    cuts_added : int
        Cuts the executives learned over the campaign (they carry over between the trials of
        a chunk).
    chunks : tuple of (int, int)
        The partition the trials ran in, ``(first seed, trials)`` per chunk, one executive each
        (:func:`chunk_seeds`; empty: the one ``chunk_seeds`` gives the config).
    """

    config: PhysicsConfig
    results: tuple[TrialResult, ...]
    verdicts: tuple[TrialVerdict, ...]
    files: tuple[tuple[str, str, str], ...]
    wall_time: float
    cuts_added: int = 0
    chunks: tuple[tuple[int, int], ...] = ()

    @property
    def successes(self) -> int:
        """Trials that delivered soup."""
        return sum(r.success for r in self.results)

    @property
    def violations(self) -> dict[str, int]:
        """Trials with each violation kind."""
        return {k: sum(k in v.violations for v in self.verdicts) for k in VIOLATION_KINDS}

    @property
    def ok(self) -> bool:
        """True iff every trial passed the oracle."""
        return all(v.ok for v in self.verdicts)


@dataclass(frozen=True, slots=True)
class _Chunk:
    """One batch of a physical campaign: the trials ``first .. first + count - 1`` (seeds
    ``config.seed + first ...``), run by one executive."""

    config: PhysicsConfig
    index: int
    first: int
    count: int


Trials = tuple[tuple[TrialResult, TrialVerdict], ...]


def _run_chunk(chunk: _Chunk, *, policy: Any = None,
               on_trial: Callable[[int, TrialResult, TrialVerdict], None] | None = None,
               frame: Callable[[Any], None] | None = None) -> Trials:
    """Run one chunk's trials with one executive (``policy``, default a fresh one behind the
    certificate); ``on_trial`` gets the campaign-wide trial index."""
    config = chunk.config
    if policy is None:
        policy = load_policy(config.variant, root=config.root, certificates=config.cert_dir)
    out: list[tuple[TrialResult, TrialVerdict]] = []
    for j in range(chunk.count):
        k = chunk.first + j
        seed = config.seed + k
        res = run_trial(policy, seed, variant=config.variant,
                        perturbations=draw(seed, pushes=config.pushes, tilts=config.tilts),
                        duration=config.duration, robot=config.robot, retry=config.retry,
                        sensors=config.sensors, controller=config.controller,
                        frame=frame if j == 0 else None)
        verdict = check_trial(res, policy.automaton, goal_modes=policy.goal_modes)
        out.append((res, verdict))
        if on_trial is not None:
            on_trial(k, res, verdict)
    return tuple(out)


def _chunk_task(chunk: _Chunk) -> Trials:
    """A chunk in a worker process (picklable: a fresh executive, no callbacks)."""
    return _run_chunk(chunk)


def run_physics_campaign(config: PhysicsConfig, *, policy: Any = None,
                         on_trial: Callable[[int, TrialResult, TrialVerdict], None] | None = None,
                         frame: Callable[[Any], None] | None = None,
                         on_event: Callable[[str], None] | None = None,
                         scheduler: str | None = None,
                         wrap: Callable[[LTLDSPolicy], object] | None = None) -> PhysicsResult:
    """Run ``config.trials`` seeded, perturbed trials and judge each, in ``config.workers``
    contiguous chunks on ``config.backend``.

    Chunk ``i`` (:func:`chunk_seeds`) runs its trials in seed order with its own executive,
    whose learned cuts carry over between its trials; the chunks share nothing. The results
    come back in seed order and do not depend on the backend or the completion order.

    Parameters
    ----------
    config : PhysicsConfig
    policy : LTLDSPolicy, optional
        The executive of the first chunk, already loaded behind the certificate (default:
        :func:`tli_verify.sim.franka_project.load_policy` of ``config.variant`` for
        ``config.root``, as for every other chunk); serial backend only.
    on_trial : callable, optional
        ``(k, result, verdict)`` with ``k`` the trial's index in the campaign: after each trial
        on the serial backend; on the others, for each trial of a chunk when the chunk
        completes (chunks complete in any order).
    frame : callable, optional
        Called with the rig at every control step of the first trial (video frames); serial
        backend only.
    on_event : callable, optional
        One line per notable backend event (a worker died, a chunk re-run).
    scheduler : str, optional
        Dask scheduler address (``backend="dask"``; default a ``LocalCluster``).
    wrap : callable, optional
        Applied to the first chunk's executive before any trial (serial backend only): e.g.
        the exported C evaluator put in the loop with it as the supervisor
        (:func:`tli_verify.deploy.cloop.in_the_loop`, the gate's re-run of a deployed artifact).

    Returns
    -------
    PhysicsResult

    Raises
    ------
    CertificateError
        (exit 1) The certificate is missing, does not re-check, or does not cover the model
        (:func:`tli_verify.sim.franka_project.load_policy`): nothing moves.
    CampaignError
        (exit 2) ``policy`` or ``frame`` on a backend other than serial; an unusable backend
        (:func:`tli_verify.verify.backends.make_backend`).
    WorkerLost
        (exit 1) A chunk's worker died more often than the retries allow.
    KeyboardInterrupt
        Ctrl-C: the pending chunks are cancelled and nothing is returned.
    """
    if config.backend != "serial" and (policy is not None or frame is not None
                                       or wrap is not None):
        raise CampaignError(f"backend {config.backend!r}: an executive or video frames in "
                            "this process need the serial backend")
    if wrap is not None and config.workers != 1:
        raise CampaignError(f"workers {config.workers}: a wrapped executive runs every trial, "
                            "so one worker (the other chunks would load their own)")
    files = hash_files(config.root, config.cert_dir)
    chunks = chunk_seeds(config.seed, config.trials, config.workers)
    if policy is None:  # nothing moves if the certificate does not cover the model
        checked = load_policy(config.variant, root=config.root, certificates=config.cert_dir)
        if config.backend == "serial":
            policy = checked  # the first chunk's executive; the workers load their own
    if wrap is not None:
        policy = wrap(policy)
    shipped = config if config.backend == "serial" else dataclasses.replace(
        config, root=os.path.abspath(config.root),  # workers may start elsewhere
        certificates=os.path.abspath(config.cert_dir))
    items: list[_Chunk] = []
    for i, (first_seed, count) in enumerate(chunks):
        items.append(_Chunk(config=shipped, index=i, first=first_seed - config.seed,
                            count=count))
    t0 = time.perf_counter()
    done: dict[int, Trials] = {}
    backend = make_backend(config.backend, workers=min(config.workers, len(chunks)),
                           scheduler=scheduler, on_event=on_event)
    try:
        if config.backend == "serial":
            def serial(chunk: _Chunk) -> Trials:
                return _run_chunk(chunk, policy=policy if chunk.index == 0 else None,
                                  on_trial=on_trial,
                                  frame=frame if chunk.index == 0 else None)

            for i, trials in backend.map_unordered(serial, items):
                done[i] = trials
        else:
            for i, trials in backend.map_unordered(_chunk_task, items):
                done[i] = trials
                if on_trial is not None:
                    for j, (res, verdict) in enumerate(trials):
                        on_trial(items[i].first + j, res, verdict)
    finally:
        backend.close()
    ordered = [t for i in range(len(items)) for t in done[i]]
    results = tuple(r for r, _ in ordered)
    return PhysicsResult(config=config, results=results,
                         verdicts=tuple(v for _, v in ordered), files=files,
                         wall_time=time.perf_counter() - t0,
                         cuts_added=sum(r.cuts_added for r in results), chunks=chunks)
