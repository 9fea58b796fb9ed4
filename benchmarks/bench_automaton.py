"""Task automata over many inputs: symbolic reading cubes keep the automaton small.

Specs with 4 to 200 inputs, in two families:

* ``free``: a two-mode alternation ``a, b, a, ...`` whose inputs no formula mentions (the
  issue's "12 unconstrained inputs ran > 90 s, 200 crashed");
* ``read``: a mode copies the next value of one input (``G(X b <-> X x0)``), the other inputs
  are free (``x0`` as well: only its next value matters, which the edges' cubes carry);
* ``lag``: a mode follows the previous values of two inputs (``G(X b <-> (x0 & x1))``): the
  states must remember ``x0`` and ``x1``.

Times are medians of ``REPEATS`` runs from a parsed spec to the automaton (game, fixpoint and
extraction). Before reading cubes, extraction enumerated every valuation of the inputs per
state: 2^n edges per state.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from tli_verify.io import atomic_write_text
from tli_verify.logic.automaton import MAX_AUTOMATON_EDGES, MAX_AUTOMATON_STATES
from tli_verify.logic.check import synthesize
from tli_verify.logic.escape import markdown_text
from tli_verify.logic.spec import GR1Spec, parse_spec

REPEATS = 3
SIZES = (4, 12, 50, 100, 200)


def spec_text(n_inputs: int, family: str) -> str:
    """A realizable spec with ``n_inputs`` inputs (see the module docstring)."""
    inputs = ", ".join(f'"x{i}"' for i in range(n_inputs))
    if family == "free":
        safety = '"G(a -> X b)", "G(b -> X a)", "G(!(a & b))"'
        init, goal = "a & !b", "a"
    elif family == "read":
        safety = '"G(X b <-> X x0)", "G(X a <-> !X b)"'
        init, goal = "a <-> !b", "a | b"
    else:
        safety = '"G(X b <-> (x0 & x1))", "G(X a <-> !X b)"'
        init, goal = "a <-> !b", "a | b"
    return (f'name = "{family}-{n_inputs}"\ninputs = [{inputs}]\noutputs = ["a", "b"]\n'
            f'[guarantee]\ninit = "{init}"\nsafety = [{safety}]\nliveness = ["GF({goal})"]\n')


def _measure(spec: GR1Spec) -> tuple[float, int, int, int]:
    times = []
    aut = None
    for _ in range(REPEATS):
        start = time.perf_counter()
        aut = synthesize(spec)
        times.append(time.perf_counter() - start)
    assert aut is not None
    return statistics.median(times), len(aut.states), len(aut.transitions), len(aut.free_inputs)


def main(out_dir: Path) -> str:
    rows = []
    for family in ("free", "read", "lag"):
        for n in SIZES:
            spec = parse_spec(spec_text(n, family))
            seconds, states, edges, free = _measure(spec)
            rows.append((f"{family}, {n} inputs", n, free, states, edges, seconds))
    lines = [
        "## Task automata over many inputs (reading cubes)",
        "",
        f"Median of {REPEATS} runs from a parsed spec to the automaton. Limits: "
        f"{MAX_AUTOMATON_STATES} states, {MAX_AUTOMATON_EDGES} edges (larger automata are "
        "refused with a SpecError naming the limit).",
        "",
        "| spec | inputs | free inputs | states | edges | seconds |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, n, free, states, edges, seconds in rows:
        lines.append(f"| {markdown_text(name)} | {n} | {free} | {states} | {edges} | "
                     f"{seconds:.3f} |")
    section = "\n".join(lines) + "\n"
    atomic_write_text(out_dir / "automaton.md", section)
    return section
