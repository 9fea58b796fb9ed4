"""Property tests of a certified policy: the public testing API of tli-verify.

A property test of your own policy, on your own task, in any dimension (run by pytest from the
project folder: the plugin's ``tli_project`` fixture is that project)::

    from hypothesis import given
    from tli_verify.testing import assert_satisfies, cases

    @given(case=cases(max_pushes=2))
    def test_the_drawer_opens_despite_pushes(tli_project, case):
        assert_satisfies(tli_project, case)

Without the fixture: ``drawer = project(__file__)`` and ``cases(drawer)``.

* :func:`project` -- resolve the files by the project rules (the ones every ``tli`` command
  follows) and load the closed loop: a :class:`Project`;
* :func:`cases` -- hypothesis strategies of perturbation sequences with the task's defaults
  (starts, window, count and magnitude of the pushes), shrinking toward fewer, smaller, later
  perturbations;
* :func:`check`, :func:`check_many` -- simulate cases and return the oracle's verdicts (the four
  checks of ``tli verify``);
* :func:`assert_satisfies` -- passes only when the run is decided, reached a goal mode and
  violated nothing; otherwise an :class:`AssertionError` showing the (shrunk) case and the
  ``tli replay PATH`` command of the regression case file it saved;
* the pytest plugin (:mod:`tli_verify.testing.plugin`, loaded by pytest): the ``tli_project``
  fixture, ``--tli-examples`` and ``--tli-seed``, and saved cases replayed as tests
  (``--tli-cases DIR``); the how-to "Property tests of your own policy"
  (``docs/howto/property-tests.md``).

Importing this package is cheap: its names load their modules (hypothesis, the simulator) when
first used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from tli_verify._lazy import lazy_namespace

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs
    from tli_verify.testing.projects import Project, project
    from tli_verify.testing.runner import (
        assert_satisfies,
        check,
        check_many,
        replay_command,
        save_case,
    )
    from tli_verify.testing.strategies import cases
    from tli_verify.verify.oracle import Verdict
    from tli_verify.verify.strategies import Case, Push

_NAMES: dict[str, str] = {
    "Project": "tli_verify.testing.projects",
    "project": "tli_verify.testing.projects",
    "cases": "tli_verify.testing.strategies",
    "check": "tli_verify.testing.runner",
    "check_many": "tli_verify.testing.runner",
    "assert_satisfies": "tli_verify.testing.runner",
    "save_case": "tli_verify.testing.runner",
    "replay_command": "tli_verify.testing.runner",
    "Case": "tli_verify.verify.strategies",
    "Push": "tli_verify.verify.strategies",
    "Verdict": "tli_verify.verify.oracle",
}

__all__ = [
    "Case",
    "Project",
    "Push",
    "Verdict",
    "assert_satisfies",
    "cases",
    "check",
    "check_many",
    "project",
    "replay_command",
    "save_case",
]


__getattr__, __dir__ = lazy_namespace("tli_verify.testing", _NAMES, globals(), __all__)
