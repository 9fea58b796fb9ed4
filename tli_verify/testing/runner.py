"""Run cases of a project's closed loop, check them with the oracle, and assert on the verdict.

:func:`check` simulates one case in this process and returns the oracle's
:class:`~tli_verify.verify.oracle.Verdict` (the four checks of ``tli verify``: invariance, the
certified reachability deadline, the automaton run, no looping); :func:`check_many` does a batch
in one vectorised call. :func:`assert_satisfies` is the assertion of a property test: it passes
only when the run is **decided** (``conclusive``), **reached** a goal mode and violated
**nothing** -- ``verdict.ok`` alone would accept a run whose reachability was never decided.
On failure it saves the case as a regression case file (``tli replay`` reads it) and raises an
:class:`AssertionError` whose message shows the case, the oracle's findings and the exact
``tli replay PATH`` command.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tli_verify.errors import CampaignError
from tli_verify.io import atomic_write_text, canonical_json
from tli_verify.limits import MAX_CAMPAIGN_STEPS

if TYPE_CHECKING:  # pragma: no cover - types only
    from tli_verify.testing.projects import Project
    from tli_verify.verify.oracle import Verdict
    from tli_verify.verify.strategies import Case

__all__ = ["TARGET_LABEL", "assert_satisfies", "check", "check_many", "failure_reasons",
           "replay_command", "save_case"]

TARGET_LABEL = "tli-verify: negated robustness"
"""The :func:`hypothesis.target` label :func:`assert_satisfies` reports the run's margin
under (another label than :func:`tli_verify.verify.strategies.target_robustness`'s default, so a
test may call both)."""


# ------------------------------------------------------------------------------ running
def _budget(proj: Project, cases: Sequence[Case], budget: int | None) -> int:
    """The step budget of a batch: the certified one (the last perturbation's step plus the
    worst-case deadline), unless given."""
    if budget is not None:

        top = max(MAX_CAMPAIGN_STEPS, int(proj.loaded.budget))
        if not isinstance(budget, int) or isinstance(budget, bool) or not 1 <= budget <= top:
            raise CampaignError(f"budget: expected an integer in [1, {top}] (control steps), "
                                f"got {budget!r}")
        return budget
    last = max((c.last_step for c in cases), default=0)
    return int(proj.loaded.oracle.budget(max(proj.window, last)))


def check(project: Project, case: Case, *, budget: int | None = None) -> Verdict:
    """Simulate one case and return the oracle's verdict.

    Parameters
    ----------
    project : Project
        :func:`tli_verify.testing.project`.
    case : Case
        A start and a perturbation sequence (:func:`tli_verify.testing.cases`, or built by
        hand: ``Case((0.2, 0.5, 0.8), (Push(300, (-0.3, 0.0, 0.2)),))``).
    budget : int, optional
        Control steps the run may take (default: the certified budget, which decides
        reachability: the last perturbation's step plus the worst-case deadline). A smaller
        one can leave the run undecided (``verdict.conclusive`` False).

    Returns
    -------
    Verdict
    """
    return check_many(project, [case], budget=budget)[0]


def check_many(project: Project, cases: Sequence[Case], *, budget: int | None = None,
               batch_size: int = 100) -> list[Verdict]:
    """:func:`check` for many cases, simulated in vectorised batches of ``batch_size``.

    Parameters
    ----------
    project : Project
    cases : sequence of Case
    budget : int, optional
        As :func:`check` (default: the certified budget of each batch's latest perturbation).
    batch_size : int, optional
        Runs per vectorised call.

    Returns
    -------
    list of Verdict
        In the order of ``cases``.
    """
    from tli_verify.verify.simulate import simulate

    if not isinstance(batch_size, int) or isinstance(batch_size, bool) or batch_size < 1:
        raise CampaignError(f"batch_size: expected a positive integer, got {batch_size!r}")
    items = list(cases)
    out: list[Verdict] = []
    oracle = project.loaded.oracle
    for i in range(0, len(items), batch_size):
        batch = items[i:i + batch_size]
        sims = simulate(project.sim, batch, budget=_budget(project, batch, budget))
        out += oracle.check_many([trace for trace, _ in sims])
    return out


# ------------------------------------------------------------------------------ asserting
def failure_reasons(verdict: Verdict) -> list[str]:
    """Why a verdict does not pass :func:`assert_satisfies` (empty: it passes): each
    violation, an undecided reachability, a goal not reached."""
    reasons = [f"{v.kind.value} (step {v.step}): {v.message}" for v in verdict.violations]
    if not verdict.conclusive:
        if not verdict.assumptions_ok:
            why = ("a reading left the spec's environment assumptions, after which nothing is "
                   "owed")
        elif verdict.deadline_step is not None:
            why = (f"the run ended before the certified deadline (step "
                   f"{verdict.deadline_step}) without reaching a goal mode")
        else:
            why = "the run ended before reachability was decided"
        reasons.append(f"undecided: reachability was not decided: {why}")
    elif not verdict.reached and not verdict.violations:
        reasons.append("the run did not reach a goal mode")
    assert bool(reasons) != verdict.satisfied  # one definition of passing
    return reasons


def assert_satisfies(project: Project, case: Case, *, verdict: Verdict | None = None,
                     budget: int | None = None, case_dir: str | os.PathLike[str] | None = None,
                     save: bool = True, target: bool = True) -> Verdict:
    """Assert that the closed loop satisfies its spec on ``case``: the run is decided, reached
    a goal mode, and violated no check. No verdict passes while undecided.

    Parameters
    ----------
    project : Project
        :func:`tli_verify.testing.project`.
    case : Case
    verdict : Verdict, optional
        The verdict of ``case`` if already computed (:func:`check`); default: simulate it.
    budget : int, optional
        Control steps (default: the certified budget; see :func:`check`).
    case_dir : path-like, optional
        Where a failing case is saved (default: :attr:`Project.regression_dir`: the project's
        ``tests/regressions/``, the plugin's ``--tli-case-dir``, else a temporary directory).
    save : bool, optional
        Save a failing case (default True).
    target : bool, optional
        Inside a hypothesis test, report the run's robustness margin to
        :func:`hypothesis.target` (label :data:`TARGET_LABEL`), steering the search toward runs
        close to failing.

    Returns
    -------
    Verdict
        When it passes.

    Raises
    ------
    AssertionError
        The run violated a check, did not reach a goal or was undecided. The message shows the
        case (under ``@given``: the shrunk one), the oracle's findings, and -- when the run
        violated a check -- the case file it saved and the ``tli replay PATH`` command that
        replays it. An undecided run without a violation documents no violation, so no case
        file is written (``tli replay`` replays violations); the message shows the case to
        re-run with :func:`check`.

    Notes
    -----
    Under ``@given`` hypothesis runs the test many times while it shrinks; the case file is
    written once, on the final run of the minimal failing case.
    """
    v = check(project, case, budget=budget) if verdict is None else verdict
    final = True
    in_hypothesis = _in_hypothesis()
    if in_hypothesis:
        if target:
            import math

            from hypothesis import target as _target
            from hypothesis.errors import InvalidArgument

            if math.isfinite(v.robustness):
                # a second assertion in one example: its margin is reported once
                with contextlib.suppress(InvalidArgument):
                    _target(-float(v.robustness), label=TARGET_LABEL)
        final = _is_final()
    reasons = failure_reasons(v)
    if not reasons:
        return v
    saved = None
    if save and final and v.violations:
        saved = save_case(project, case, v, case_dir=case_dir)
    raise AssertionError(_message(project, case, v, reasons, saved, budget=budget,
                                  shrinking=in_hypothesis and not final))


def _in_hypothesis() -> bool:
    import sys

    if "hypothesis" not in sys.modules:
        return False
    from hypothesis import currently_in_test_context

    return bool(currently_in_test_context())


def _is_final() -> bool:
    """Hypothesis runs this example for the last time (the minimal failing case, or an
    explicit ``@example``)."""
    try:
        from hypothesis.control import current_build_context

        return bool(getattr(current_build_context(), "is_final", True))
    except Exception:  # no build context: not shrinking
        return True


def _message(proj: Project, case: Case, v: Verdict, reasons: list[str], saved: Path | None,
             *, budget: int | None, shrinking: bool) -> str:
    mode = "LTL-DS" if proj.modulation else "no modulation"
    lines = [f"tli-verify: {proj.name} ({mode}) does not satisfy its spec on this case:"]
    lines += [f"  - {r}" for r in reasons[:6]]
    if len(reasons) > 6:
        lines.append(f"  - ... and {len(reasons) - 6} more")
    lines += [f"case: {case!r}",
              f"oracle modes: {v.oracle_modes[:120]}{'...' if len(v.oracle_modes) > 120 else ''}"]
    lines.append(f"files: model {proj.sim.model}, spec {proj.sim.spec}, certificate "
                 f"{proj.sim.certificate}, task {proj.sim.task}")
    if budget is not None:
        lines.append(f"budget: {budget} steps (given; the certified budget decides "
                     "reachability)")
    if saved is not None:
        lines += [f"saved: {saved}", f"replay: {replay_command(saved)}"]
    elif shrinking:
        lines.append("(hypothesis is shrinking: the minimal case is saved on its final run)")
    elif v.violations:
        lines.append("not saved (save=False)")
    else:
        lines.append("not saved: a case file documents a violation and this run has none "
                     "(re-run it with tli_verify.testing.check(project, case))")
    return "\n".join(lines)


# ------------------------------------------------------------------------------ cases
def replay_command(path: str | os.PathLike[str]) -> str:
    """``tli replay PATH`` (relative to the working directory when under it, shell-quoted)."""
    p = Path(os.path.abspath(path))
    try:
        shown = str(p.relative_to(Path.cwd()))
    except ValueError:
        shown = str(p)
    return f"tli replay {shlex.quote(shown)}"


def save_case(project: Project, case: Case, verdict: Verdict, *,
              case_dir: str | os.PathLike[str] | None = None, seed: int = 0) -> Path:
    """Save a violating case as a regression case file (written atomically).

    The file is :func:`tli_verify.verify.cases.case_document` (``tli replay`` reads it;
    the plugin's ``--tli-cases`` replays it as a test); files under the project folder are
    named relative to the case file when it lies in the project too (the project moves with
    its cases). Its name is ``TASK-MODE-KIND-DIGEST.json``, the digest of the case and the
    files, so the same case is saved once.

    Parameters
    ----------
    project : Project
    case : Case
    verdict : Verdict
        A verdict with a violation.
    case_dir : path-like, optional
        Default: :attr:`Project.regression_dir`.
    seed : int, optional
        Recorded as the case's seed (informational).

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        The verdict violates nothing.
    """
    from tli_verify.verify.cases import case_document

    doc = case_document(project.sim, case, verdict, seed=seed, shrunk=_in_hypothesis())
    target = Path(os.path.abspath(case_dir)) if case_dir is not None else \
        Path(os.path.abspath(project.regression_dir))
    _relocate(doc, project, target)
    key = json.dumps({"case": {k: doc[k] for k in ("start", "perturbations")},
                      "files": {k: v.get("sha256") for k, v in doc["files"].items()},
                      "modulation": doc["modulation"], "lag": doc["lag"],
                      "window": doc["window"]}, sort_keys=True)
    digest = hashlib.sha256(key.encode()).hexdigest()[:12]
    mode = "ltlds" if project.modulation else "no-modulation"
    name = f"{_slug(project.name)}-{mode}-{doc['expected']['violation']}-{digest}.json"
    target.mkdir(parents=True, exist_ok=True)
    out = target / name
    atomic_write_text(out, canonical_json(doc))
    return out


def _relocate(doc: dict[str, Any], proj: Project, case_dir: Path) -> None:
    """Name the project's files relative to the case file's folder when both lie in the
    project (``tli replay`` looks there first)."""
    root = Path(os.path.realpath(proj.root))
    if not Path(os.path.realpath(case_dir)).is_relative_to(root):
        return
    real_dir = os.path.realpath(case_dir)
    paths = {"spec": proj.sim.spec, "model": proj.sim.model,
             "certificate": proj.sim.certificate, "task": proj.sim.task}
    for name, entry in doc["files"].items():
        if "path" not in entry:
            continue
        real = Path(os.path.realpath(paths.get(name, entry["path"])))
        if real.is_relative_to(root) and real.is_file():
            entry["path"] = os.path.relpath(real, real_dir)


def _slug(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name) or "task"
