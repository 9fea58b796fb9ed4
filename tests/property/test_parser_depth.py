"""Issue 31, class 4: one depth limit (``MAX_FORMULA_DEPTH``), checked when a formula loads, in
every parser -- Spectra, structured slugs, slugsin, our GR(1) specs and task formulas.

A formula that loads is then handled without recursion trouble (chains of one associative
operator are one n-ary node, expanded and written in loops); one that nests too deeply, directly
or through a chain of defines, predicates or patterns, or a pattern that instantiates itself,
is refused in one line that names the limit or the cycle -- never by the ``RecursionError``
backstop (``formulas nested too deeply to translate``), never with an internal error.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tli_verify.errors import SpecError, TaskError
from tli_verify.logic.foreign import import_spec_text
from tli_verify.logic.spec import parse_spec

HYP = settings(max_examples=40, deadline=None, derandomize=True,
               suppress_health_check=list(HealthCheck))
BACKSTOP = "too deeply to translate"
HEAD = "module M\nenv boolean a;\nsys boolean b;\n"
SLUGS = "[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n"


def _import_or_refuse(text: str, fmt: str) -> str | None:
    """The translation, or None when refused by a load-time check (one short line)."""
    try:
        return import_spec_text(text, fmt=fmt, where="x")
    except SpecError as exc:
        msg = str(exc)
        assert BACKSTOP not in msg, msg[:300]
        assert "\n" not in msg and len(msg) < 400, msg[:400]
        return None


@HYP
@given(fmt=st.sampled_from(["spectra", "structuredslugs"]), op=st.sampled_from(["&", "|"]),
       n=st.integers(2, 2500))
def test_a_long_chain_of_one_associative_operator_imports(fmt: str, op: str, n: int) -> None:
    """``b & a & b & ...`` is one level however long: it imports, and the spec it writes loads
    with every operand (before: a Spectra chain of ~800 or more hit the backstop)."""
    body = f" {op} ".join(["b", "a"] * (n // 2) + ["b"] * (n % 2))
    text = (HEAD + f"gar G {body};\n") if fmt == "spectra" else (SLUGS + body + "\n")
    out = import_spec_text(text, fmt=fmt, where="x")
    spec = parse_spec(out, path="x.toml")
    assert spec.guarantee.safety
    assert out.count(f" {op} ") >= n - 1


@HYP
@given(fmt=st.sampled_from(["spectra", "structuredslugs", "slugsin"]),
       shape=st.sampled_from(["parens", "not", "xor", "iff", "implies", "mixed"]),
       n=st.integers(1, 6000))
def test_any_nesting_loads_or_is_refused_at_load(fmt: str, shape: str, n: int) -> None:
    """Parentheses, prefix chains and chains of the non-associative (or, in our reading,
    level-counting) operators: imported, or refused by the depth check, never the backstop."""
    if fmt == "slugsin":
        op = {"parens": "!", "not": "!", "xor": "^", "iff": "^", "implies": "|",
              "mixed": "&"}[shape]
        body = f"{op} b " * n + "b" if op != "!" else "! " * n + "b"
        _import_or_refuse(SLUGS + body + "\n", fmt)
        return
    xor = "xor" if fmt == "spectra" else "^"
    body = {"parens": "(" * n + "b" + ")" * n, "not": "!" * n + "b",
            "xor": f" {xor} ".join(["b"] * (n + 1)),
            "iff": " <-> ".join(["b"] * (n + 1)), "implies": " -> ".join(["b"] * (n + 1)),
            "mixed": "".join(f"(b {'&|'[k % 2]} " for k in range(n)) + "b" + ")" * n}[shape]
    text = (HEAD + f"gar G {body};\n") if fmt == "spectra" else (SLUGS + body + "\n")
    out = _import_or_refuse(text, fmt)
    if out is None:
        return
    parse_spec(out, path="x.toml")


def _chain(kind: str, k: int) -> str:
    """``k`` defines, predicates or patterns, each using the one before."""
    if kind == "define":
        return ("define d0 := b;\n" + "".join(f"define d{i} := !d{i - 1};\n"
                                               for i in range(1, k))
                + f"gar G d{k - 1};\n")
    if kind == "predicate":
        return ("predicate p0(boolean x): x;\n"
                + "".join(f"predicate p{i}(boolean x): !p{i - 1}(x);\n" for i in range(1, k))
                + f"gar G p{k - 1}(b);\n")
    return ("pattern P0(x) {\n  G x;\n}\n"
            + "".join(f"pattern P{i}(x) {{\n  P{i - 1}(x);\n}}\n" for i in range(1, k))
            + f"gar P{k - 1}(b);\n")


@HYP
@given(kind=st.sampled_from(["define", "predicate", "pattern"]), k=st.integers(1, 3000))
def test_chains_of_defines_predicates_and_patterns_are_bounded_at_load(kind: str,
                                                                      k: int) -> None:
    """Each define, predicate or pattern is shallow; a chain of them inlines into a deep
    formula: refused by the same limit as the expansion goes (before: the backstop)."""
    out = _import_or_refuse(HEAD + _chain(kind, k), "spectra")
    if k <= 20:
        assert out is not None, (kind, k)
    if out is None:
        with pytest.raises(SpecError, match=r"MAX_FORMULA_DEPTH"):
            import_spec_text(HEAD + _chain(kind, k), fmt="spectra", where="x")
    else:
        parse_spec(out, path="x.toml")


@HYP
@given(cycle=st.integers(1, 6), extra=st.integers(0, 3))
def test_a_pattern_that_instantiates_itself_is_refused_naming_the_cycle(cycle: int,
                                                                       extra: int) -> None:
    """``P0 -> P1 -> ... -> P0`` (reached through ``extra`` patterns first): one line naming
    the cycle (before: a RecursionError, caught only by the backstop)."""
    pats = "".join(f"pattern P{i}(x) {{\n  var boolean q{i};\n  P{(i + 1) % cycle}(x);\n}}\n"
                   for i in range(cycle))
    pats += "".join(f"pattern E{j}(x) {{\n  {'E' + str(j + 1) if j + 1 < extra else 'P0'}"
                    "(x);\n}\n" for j in range(extra))
    top = "E0" if extra else "P0"
    with pytest.raises(SpecError) as info:
        import_spec_text(HEAD + pats + f"gar {top}(b);\n", fmt="spectra", where="x")
    msg = str(info.value)
    cycle_text = " -> ".join([f"P{i}" for i in range(cycle)] + ["P0"])
    assert f"pattern 'P0' instantiates itself ({cycle_text})" in msg, msg


@pytest.mark.parametrize("op", ["&", "|", "^", "<->", "->", "xor"])
@pytest.mark.parametrize("n", [800, 2000])
def test_a_long_chain_in_a_gr1_spec_loads_or_is_refused_at_load(op: str, n: int) -> None:
    """Our own specs (Spot's parser): ``&``/``|`` are n-ary and load; the binary operators nest
    one level per operand and are refused by the depth limit, in one line."""
    body = f" {op} ".join(["a", "r"] * (n // 2))
    text = ('name = "x"\ninputs = ["r"]\noutputs = ["a"]\n[guarantee]\ninit = "a"\n'
            f'liveness = ["GF({body})"]\n')
    try:
        spec = parse_spec(text, path="x.toml")
    except SpecError as exc:
        assert op not in ("&", "|"), str(exc)[:300]
        assert "deeper than the limit of 100 levels" in str(exc) and "\n" not in str(exc)
        return
    assert op in ("&", "|") and spec.guarantee.liveness


@HYP
@given(op=st.sampled_from(["&", "|", "^", "<->"]), n=st.integers(1, 2400))
def test_a_loaded_task_formula_is_evaluated_without_recursion(
        tmp_path_factory: pytest.TempPathFactory, op: str, n: int) -> None:
    """A chain of 800-2,400 operands in a task's sensor formula: refused at load (the length
    limit) or evaluated in a loop -- at a recursion limit far below the chain's length, so an
    evaluation that recursed per operand would fail here."""
    import sys

    from tli_verify.tasks.taskfile import load_task

    scoop = (Path(__file__).resolve().parents[2] / "tasks" / "scoop.toml").read_text()
    formula = f" {op} ".join(["yellow"] * (n + 1))
    path = tmp_path_factory.mktemp("f") / "t.toml"
    path.write_text(scoop.replace('r = "yellow & !delivered"', f'r = "{formula}"', 1))
    try:
        task = load_task(path)
    except TaskError as exc:
        assert "longer than" in str(exc) or "MAX_FORMULA_DEPTH" in str(exc), str(exc)[:300]
        return
    X = np.array([[0.0, -6.0], [0.0, 0.0], [5.0, 7.0]])
    old = sys.getrecursionlimit()
    sys.setrecursionlimit(400)
    try:
        readings = task.sensors(X)
    finally:
        sys.setrecursionlimit(old)
    want = {"&": True, "|": True, "^": n % 2 == 0, "<->": True}[op]  # yellow at row 0
    assert readings.shape == (3, 3) and bool(readings[0, 0]) == want
