"""One project session: find the files once, load them once, settle the questions once.

:func:`open_project` is the one entry from "a folder, a task, a spec or a model" to every
object a command needs. It applies the project resolver's rules
(:func:`tli_verify.tasks.project.resolve`: model -> spec -> task -> certificate, evidence,
goal), reads each file once inside a snapshot (:mod:`tli_verify.snapshot`: hashes and parsers
see the same bytes) and returns a frozen :class:`Session`; the spec's automaton is synthesized
once, on first use (after a command has checked its outputs), and its goal checked reachable.
Its methods (:meth:`Session.policy`, :meth:`Session.run`, :meth:`Session.check_certificate`,
:meth:`Session.campaign`) run inside the same snapshot, so nothing is read twice, and nothing
changes between the check and the use.

The loading itself is :class:`tli_verify.loaded.LoadedProject` (one layer down, where the
campaign workers and the Franka loop load through it); :class:`Session` adds the campaigns.
Used by ``tli run``, ``tli verify``, ``tli evidence``, :func:`tli_verify.make_policy`, the
scoop experiments and the gate's re-run::

    import tli_verify as tli

    session = tli.open_project("models/scoop.model.json")
    episode = session.run(seed=3)                    # the task's nominal start
    assert episode.success
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import TliError
from tli_verify.loaded import LoadedProject, locate, run_policy

if TYPE_CHECKING:
    from tli_verify.runtime.executive import LTLDSPolicy
    from tli_verify.sim.campaign import PhysicsResult
    from tli_verify.sim.loop import TrialResult
    from tli_verify.sim.trial_oracle import TrialVerdict
    from tli_verify.tasks.task import Task
    from tli_verify.verify.campaign import CampaignResult
    from tli_verify.verify.config import CampaignConfig

__all__ = ["Session", "locate", "open_project", "run_policy"]

PathLike = str | os.PathLike[str]


@dataclass(frozen=True, eq=False)
class Session(LoadedProject):
    """A project's files, loaded once and settled (:func:`open_project`), with its campaigns:
    the loading of :class:`~tli_verify.loaded.LoadedProject` (``automaton``, ``policy``,
    ``run``, ``check_certificate``) and the falsification and physical campaigns on the same
    bytes.

    Attributes
    ----------
    files : Resolved
        The paths the resolver found (task, spec, model, certificate, evidence, goal).
    spec : GR1Spec
    model : Model
    snapshot : Snapshot
        The bytes every file was read as; every method of the session reads through it.
    """

    def campaign_config(self, config: CampaignConfig) -> CampaignConfig:
        """``config`` on this session's files (its own ``task``, ``spec``, ``model`` and
        ``certificate`` replaced by the session's), the task's defaults filled in
        (:func:`~tli_verify.verify.config.fill_config`): what :meth:`campaign` records as run.

        Raises
        ------
        CampaignError
            (exit 2) A start outside the workspace or of the wrong dimension.
        """
        from tli_verify.verify.config import fill_config

        files = self.files
        cfg = replace(config, task=files.task.where, spec=str(files.spec),
                      model=str(files.model), certificate=str(files.certificate),
                      lag=files.task.lag)
        return fill_config(cfg, files.task)

    def campaign(self, config: CampaignConfig, *, progress: bool = False,
                 on_event: Callable[[str], None] | None = None) -> CampaignResult:
        """A falsification campaign (Sec. 4.4) on this session's files
        (:meth:`campaign_config`), its workers re-checking every file's SHA-256 against the
        bytes the session read.

        Parameters
        ----------
        config : CampaignConfig
        progress : bool, optional
            A progress bar on stderr.
        on_event : callable, optional
            Called with each event line (a lost worker, a restarted batch).
        """
        from tli_verify.verify.campaign import run_campaign

        cfg = self.campaign_config(config)
        with self.snapshot.use():
            return run_campaign(cfg, progress=progress, on_event=on_event)

    @property
    def root(self) -> Path:
        """The project folder (the model's ``models/`` parent)."""
        return Path(self.files.model).resolve().parent.parent

    def physics_campaign(self, *, seed: int, trials: int,
                         recorded: Mapping[str, object] | None = None,
                         workers: int = 1, backend: str = "serial",
                         on_trial: Callable[[int, TrialResult, TrialVerdict], None] | None = None,
                         on_event: Callable[[str], None] | None = None,
                         wrap: Callable[[LTLDSPolicy], object] | None = None,
                         **settings: object) -> PhysicsResult:
        """Seeded physical trials of this project's policy in MuJoCo, judged by the physics
        oracle (``tli sim franka --evidence``'s campaign; :mod:`tli_verify.sim.campaign`).

        Parameters
        ----------
        seed : int
            The first trial's seed.
        trials : int
        recorded : mapping, optional
            An evidence file's ``physics`` block: the trials run with its settings (robot,
            variant, duration, pushes, tilts, stall handling, sensors).
        workers : int, optional
            Executives (contiguous chunks of seeds); 1 by default.
        backend : str, optional
            ``"serial"`` (default), ``"process"`` or ``"dask"``.
        on_trial, on_event : callable, optional
            Called after each judged trial and with each event line.
        wrap : callable, optional
            Applied to the executive before the trials (serial, one worker): e.g. the exported C
            evaluator in the loop (:func:`tli_verify.deploy.cloop.in_the_loop`).
        **settings
            :class:`~tli_verify.sim.physics_config.PhysicsConfig` fields (``robot``,
            ``duration``, ``retry``, ``sensors``, ...), over ``recorded``'s.

        Raises
        ------
        TliError
            MuJoCo is not installed, or the project is not a physical one.
        """
        try:
            from tli_verify.sim.campaign import run_physics_campaign
            from tli_verify.sim.physics_config import PhysicsConfig
            from tli_verify.sim.physics_evidence import settings_from
        except ImportError as exc:
            raise TliError(f"physical trials need MuJoCo (pip install 'tli-verify[sim]'): "
                           f"{exc}") from None
        chosen: dict[str, Any] = {**settings_from(dict(recorded or {})), **settings}
        config = PhysicsConfig(root=str(self.root), seed=int(seed), trials=int(trials),
                               workers=int(workers), backend=backend, **chosen)
        with self.snapshot.use():
            return run_physics_campaign(config, on_trial=on_trial, on_event=on_event, wrap=wrap)


def open_project(path: PathLike | None = None, *, task: PathLike | Task | None = None,
                 spec: PathLike | None = None, model: PathLike | None = None,
                 certificate: PathLike | None = None, lag: int | None = None) -> Session:
    """Open a project from one file (or a project folder) and any files named explicitly.

    Parameters
    ----------
    path : path-like, optional
        A model file (``*.json``), a spec or task file (``*.toml``: a task file has a
        ``[state]`` table), or a project folder (or a folder in one): its one model, else its
        one spec (:func:`~tli_verify.loaded.locate`).
    task, spec, model, certificate : optional
        As ``--task``, ``--spec``, ``--model``, ``--certificate``.
    lag : int, optional
        Override the task's sensor lag (control steps).

    Returns
    -------
    Session

    Raises
    ------
    TaskError, SpecError, ModelError
        (exit 2) As :func:`tli_verify.tasks.project.resolve`, the spec and model readers and
        :func:`tli_verify.tasks.project.check_goal`: a missing file, a model that does not fit
        the task, an unreachable goal.
    """
    return Session.open(path, task=task, spec=spec, model=model, certificate=certificate,
                        lag=lag)
