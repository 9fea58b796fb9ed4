"""The one exception hierarchy of tli-verify.

Every error a user can cause is a :class:`TliError`. The CLI turns it into a one-line
``error: ...`` message on stderr and exit code 2 (bad input) or 1 (a check said no), see
``docs/design.md`` ("Exit codes"). Nothing else in the package prints errors or warnings.
"""

from __future__ import annotations

__all__ = [
    "AssetError",
    "CampaignError",
    "CertificateError",
    "DemoError",
    "EvidenceError",
    "GateError",
    "ModelError",
    "OutputError",
    "SolverError",
    "SpecError",
    "TaskError",
    "TliError",
    "UnrealizableError",
    "WorkerLost",
]


class TliError(Exception):
    """Base class of every error raised on purpose by tli-verify.

    Parameters
    ----------
    message : str
        One line that names the file, line or field at fault.
    exit_code : int, optional
        Exit code the CLI uses: 2 for bad input (default), 1 for "a check said no".
    """

    exit_code: int = 2

    def __init__(self, message: str, *, exit_code: int | None = None) -> None:
        super().__init__(" ".join(str(message).split()))
        if exit_code is not None:
            self.exit_code = exit_code


class SpecError(TliError):
    """A task specification (TOML, LTL formula) is malformed or outside GR(1)."""


class TaskError(TliError, ValueError):
    """A task file (state space, regions, sensors, goal, starts) is malformed, or a model, spec
    or evidence does not fit the task it runs on."""


class UnrealizableError(TliError):
    """A strategy was requested from a GR(1) game the system cannot win."""

    exit_code = 1


class DemoError(TliError):
    """A demonstration file is malformed or inconsistent with the spec."""


class ModelError(TliError):
    """A model file (per-mode LPV-DS and cuts) is malformed."""


class OutputError(TliError):
    """An output path cannot be written: a directory, under a regular file, not writable, or one
    of the command's own input files (which it would overwrite)."""


class SolverError(TliError):
    """A numerical solver failed or returned a status other than optimal."""

    exit_code = 1


class CertificateError(TliError):
    """A certificate is malformed, or does not re-check exactly."""

    exit_code = 1


class EvidenceError(TliError):
    """Campaign evidence (``certificates/<name>.campaign.json``) is malformed, or does not bind
    the deployed files."""

    exit_code = 1


class GateError(TliError):
    """The deployment gate blocks: something is uncertified or tampered with."""

    exit_code = 1


class AssetError(TliError):
    """A simulator asset (the MuJoCo Panda model files) cannot be fetched, fails its pinned
    sha256, or is missing: run ``python -m tli_verify.sim.assets fetch``."""


class WorkerLost(TliError):
    """A worker running a batch of a campaign died more often than the retries allow."""

    exit_code = 1


class CampaignError(TliError):
    """A campaign's configuration, case file or backend is unusable (exit 2)."""
