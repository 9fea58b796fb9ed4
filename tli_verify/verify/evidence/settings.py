"""A campaign's recorded settings: what is recorded, how a configuration is rebuilt from them, and
which settings the CLI could not have produced.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from tli_verify.limits import MAX_BATCH_SIZE, MAX_CAMPAIGN_STEPS, MAX_EXAMPLES, MAX_PUSHES

if TYPE_CHECKING:
    pass

__all__ = [
    "settings_for_config",
    "settings_problems",
]

_CORE = frozenset({"task", "spec", "model", "certificate", "examples", "seed", "modulation",
                   "workers", "backend", "scheduler"})


def _settings(config: Any) -> dict[str, Any]:
    """The config's other fields with JSON values (tuples as lists), for a faithful re-run."""
    import dataclasses

    if not dataclasses.is_dataclass(config):
        return {}
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        if f.name in _CORE:
            continue
        value = getattr(config, f.name)
        if isinstance(value, tuple):
            value = list(value)
        if value is None or isinstance(value, bool | int | float | str) or (
                isinstance(value, list)
                and all(isinstance(v, bool | int | float | str) for v in value)):
            out[f.name] = value
    return out


def settings_for_config(settings: Mapping[str, Any], config_type: Any) -> dict[str, Any]:
    """Recorded settings as keyword arguments of ``config_type`` (lists back to tuples; fields
    it does not have are dropped)."""
    import dataclasses

    names = {f.name for f in dataclasses.fields(config_type)} - _CORE
    return {k: tuple(v) if isinstance(v, list) else v for k, v in settings.items()
            if k in names}


def settings_problems(settings: Mapping[str, Any], task: Any) -> list[str]:
    """What in a kinematic campaign's recorded settings no ``tli verify`` or ``tli evidence``
    command line could have produced on ``task`` (an edited evidence file): the gate refuses
    such evidence whatever its digest says.

    The CLI records: ``start`` the task's first nominal start (or none, with random starts),
    ``levels`` all of them, ``max_cycles`` none, ``lag`` the task's, and every number within
    the options' ranges; no other keys.

    Parameters
    ----------
    settings : mapping
        ``campaign.settings`` of the evidence.
    task : Task
        The task the evidence binds.

    Returns
    -------
    list of str
        One line per problem (empty: the settings are ones the CLI writes).
    """
    from tli_verify.verify.strategies import LEVELS

    out: list[str] = []
    known = {"batch_size", "lag", "levels", "max_cycles", "max_pushes", "random_starts",
             "shrink", "start", "target_examples", "window"}
    extra = sorted(set(settings) - known)
    if extra:
        out.append(f"campaign.settings.{extra[0]}: not a setting tli verify records")

    def whole(name: str, lo: int, hi: int) -> None:
        if name not in settings:  # absent: the option's default
            return
        v = settings[name]
        if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
            out.append(f"campaign.settings.{name}: {v!r} is not an integer in [{lo}, {hi}] "
                       "(what the tli verify option takes)")

    whole("batch_size", 1, MAX_BATCH_SIZE)
    whole("window", 1, MAX_CAMPAIGN_STEPS)
    whole("max_pushes", 0, MAX_PUSHES)
    whole("target_examples", 0, MAX_EXAMPLES)
    whole("lag", 0, MAX_CAMPAIGN_STEPS)
    for name in ("shrink", "random_starts"):
        if name in settings and not isinstance(settings[name], bool):
            out.append(f"campaign.settings.{name}: {settings[name]!r} is not true or false")
    if "levels" in settings and (not isinstance(settings["levels"], list | tuple)
                                 or list(settings["levels"]) != list(LEVELS)):
        out.append(f"campaign.settings.levels: {settings['levels']!r}; tli verify always "
                   f"draws every level ({', '.join(LEVELS)})")
    if settings.get("max_cycles") is not None:
        out.append(f"campaign.settings.max_cycles: {settings['max_cycles']!r}; tli verify "
                   "records none (the oracle's default)")
    lag = settings.get("lag")
    if isinstance(lag, int) and not isinstance(lag, bool) and lag != task.lag:
        out.append(f"campaign.settings.lag: {lag}, but task {task.name!r} has lag {task.lag}")
    start = settings.get("start")
    if start is not None:
        nominal = [[float(v) for v in s] for s in task.starts.nominal]
        try:
            recorded = [float(v) for v in start]
        except (TypeError, ValueError, OverflowError):
            recorded = None
        if settings.get("random_starts") is True:
            out.append("campaign.settings.start: a fixed start with random starts")
        elif not nominal or recorded != nominal[0]:
            first = nominal[0] if nominal else "none"
            out.append(f"campaign.settings.start: {start!r} is not the task's first nominal "
                       f"start ({first}), the only fixed start tli verify records")
    return out
