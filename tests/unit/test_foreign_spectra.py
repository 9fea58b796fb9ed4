"""Spectra's derived constructs in ``tli spec import``: each one expanded into plain GR(1).

Each test writes its own small spec inline and checks the TOML (variables and the slot of each
generated constraint) and, where a verdict is at stake, that our solver and omega agree on it
in both readings of safety at time 0. The expansions follow spectra-synt's translators (cited
in ``tli_verify/logic/foreign.py``).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from tests.support.ltl_eval import body, conjuncts, holds
from tests.unit.test_foreign import agree_with_omega, imported
from tli_verify.errors import SpecError
from tli_verify.logic.foreign import import_spec_file
from tli_verify.logic.spec import GR1Spec, parse_spec


def texts(spec: GR1Spec, section: str) -> list[str]:
    side, slot = section.split(".")
    return [f.text for f in getattr(getattr(spec, side), slot)]


def test_aux_variables_are_system_outputs() -> None:
    spec = imported("module M\nenv boolean e;\nsys boolean s;\naux boolean a;\n"
                    "gar ini !a;\ngar G (next(a) <-> e);\ngar G (s <-> a);\nasm GF e;\n"
                    "gar GF s;\n", "spectra")
    assert spec.inputs == ("e",) and spec.outputs == ("s", "a")
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


def test_prev_is_a_memory_bit_false_at_time_zero() -> None:
    """``PREV(e)`` (and ``Y e``, the same argument: one bit) reads e one step late, false at
    time 0: the system cannot start with ``s`` if ``s`` needs ``PREV(e)``."""
    spec = imported("module M\nenv boolean e;\nsys boolean s;\n"
                    "gar G (s <-> PREV(e));\ngar G (Y e -> s);\n", "spectra")
    assert spec.outputs == ("s", "prev_aux_0")
    assert texts(spec, "guarantee.init") == ["!(prev_aux_0)"]
    assert "G(((X prev_aux_0) <-> (e)))" in texts(spec, "guarantee.safety")
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    late = imported("module M\nenv boolean e;\nsys boolean s;\ngar s;\n"
                    "gar G (s -> PREV(e));\n", "spectra")
    assert agree_with_omega(late) == {"tli": False, "textbook": False}


def test_once_historically_since_triggered_have_their_past_meaning() -> None:
    spec = imported("module M\nenv boolean a;\nenv boolean b;\nsys boolean s;\n"
                    "gar G (s <-> (O a & H b & (a S b) & (a T b)));\n", "spectra")
    assert spec.outputs == ("s", "once_aux_0", "historically_aux_1", "since_aux_2",
                            "triggered_aux_3")
    inits = texts(spec, "guarantee.init")
    assert inits == ["((once_aux_0) <-> (a))", "((historically_aux_1) <-> (b))",
                     "((since_aux_2) <-> (b))", "((triggered_aux_3) <-> ((a | b)))"]
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


def test_arrays_with_constant_indices_and_named_sizes() -> None:
    text = ("module M\ndefine N := 3;\nenv boolean[N] req;\nsys Int(0..(N - 1)) pick;\n"
            "sys boolean[2][N] grid;\n"
            "gar G (req[0] -> next(pick) = 0);\ngar G (grid[1][N - 1] <-> req[2]);\n"
            "gar G (next(req[1]) -> next(pick = 1));\n")
    spec = imported(text, "spectra")
    assert spec.inputs == ("req_0", "req_1", "req_2")
    assert spec.outputs[:2] == ("pick_0", "pick_1") and "grid_1_2" in spec.outputs
    assert agree_with_omega(spec) == {"tli": False, "textbook": False}  # req[0], req[1] both


def test_a_variable_array_index_is_a_case_split() -> None:
    spec = imported("module M\nenv boolean[3] r;\nsys Int(0..2) k;\nsys boolean s;\n"
                    "gar G (s <-> r[k]);\n", "spectra")
    f = next(t for t in texts(spec, "guarantee.safety") if "r_" in t)
    g = parse_spec(f'inputs=["r_0","r_1","r_2"]\noutputs=["k_0","k_1","s"]\n'
                   f'[guarantee]\nsafety=["{f}"]\n', path="t.toml").guarantee.safety[0]
    for r0, r1, r2, k, s in itertools.product([False, True], [False, True], [False, True],
                                              range(3), [False, True]):
        vals = {"r_0": r0, "r_1": r1, "r_2": r2, "k_0": bool(k & 1), "k_1": bool(k & 2),
                "s": s}
        want = s == (r0, r1, r2)[k]
        assert all(holds(body(c), vals, vals) for c in conjuncts(g.ltl)) == want


def test_predicates_are_inlined_also_inside_other_formulas() -> None:
    text = ("module M\nenv boolean e;\nsys boolean s;\nenv boolean[2] r;\n"
            "predicate both(boolean a, boolean b): a & b;\n"
            "predicate at(Int(0..1) i) { r[i] & both(e, r[1 - i]) }\n"
            "define go := at(0) | both(e, next(s));\n"
            "gar G (go -> next(s));\ngar GF (s | !e);\nasm GF e;\n")
    spec = imported(text, "spectra")
    assert texts(spec, "guarantee.safety") == [
        "G(((((r_0 & e & r_1) | (e & X s))) -> (X s)))"]
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


RESPOND = """\
pattern respond(p, q) {
  var { IDLE, WAIT } st;
  st = IDLE;
  G (next(st) = WAIT) <-> ((st = WAIT | p) & !q);
  GF st = IDLE;
}
"""


def test_a_pattern_is_its_automaton_over_fresh_system_variables() -> None:
    """A pattern instance (Spectra's PatternConstraintTranslator): fresh auxiliary (system)
    variables per instance; initial and safety parts are guarantees, the liveness part goes
    to the side that used the pattern."""
    text = ("module M\nenv boolean req;\nsys boolean grant;\n" + RESPOND
            + "gar respond(req, grant);\nasm G respond(grant, !req);\n")
    spec = imported(text, "spectra")
    assert spec.outputs == ("grant", "respond_st_0_0", "respond_st_1_0")  # st: one bit
    assert texts(spec, "assume.liveness") == ["GF(((!respond_st_1_0)))"]
    assert texts(spec, "guarantee.liveness") == ["GF(((!respond_st_0_0)))"]
    assert not spec.assume.init and not spec.assume.safety
    assert texts(spec, "guarantee.init") == ["((!respond_st_0_0))", "((!respond_st_1_0))"]
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


def test_patterns_and_predicates_come_from_imports(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "Lib.spectra").write_text(
        "module Lib\n" + RESPOND + "predicate idle(boolean x): !x;\n", encoding="utf-8")
    path = tmp_path / "m.spectra"
    path.write_text('import "lib/Lib.spectra"\nmodule M\nenv boolean req;\n'
                    "sys boolean grant;\ngar respond(req, grant);\ngar G (idle(req) -> "
                    "!grant);\n", encoding="utf-8")
    spec = parse_spec(import_spec_file(path), path="m.toml")
    assert spec.outputs == ("grant", "respond_st_0_0")
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    with pytest.raises(SpecError, match=r"a library of patterns and predicates only"):
        import_spec_file(tmp_path / "lib" / "Lib.spectra")


def test_a_monitor_is_a_system_variable_its_constraints_guarantees() -> None:
    text = ("module M\nenv boolean e;\nsys boolean s;\n"
            "monitor boolean seen {\n  !seen;\n  G next(seen) <-> (seen | e);\n}\n"
            "gar G (next(seen) -> next(s));\nasm GF e;\ngar GF s;\n")
    spec = imported(text, "spectra")
    assert spec.outputs == ("s", "seen")
    assert texts(spec, "guarantee.init") == ["!(seen)"]
    assert len(spec.guarantee.safety) == 2
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


@pytest.mark.parametrize(("op", "realizable"), [("<->", False), ("->", True)])
def test_a_monitor_without_a_value_for_some_state_blocks_that_state(op: str,
                                                                   realizable: bool) -> None:
    """SYNTECH17's Elevator_cmp_Elevator_54 (in ``all_realizable/``) in small: its monitor
    ``currentFloor`` is defined by ``G floorK <-> (currentFloor=K)`` for four heights only, so
    between floors no value satisfies it, and (the constraints being guarantees at every step,
    spectra-synt's ``MonitorTranslator``) the system can never leave floor 0. Our import, omega
    and slugs call it unrealizable; its siblings 42, 71, 72 write ``->`` and are realizable.
    Here: the height must pass through 1 to reach 2, and the monitor has no value at 1."""
    text = ("module M\nenv boolean e;\nsys Int(0..2) h;\n"
            f"monitor Int(0..1) f {{\n  f=0;\n  G (h=0) {op} (f=0);\n  G (h=2) {op} (f=1);\n}}\n"
            "gar ini h=0;\ngar G next(h) <= h+1 & h <= next(h)+1;\ngar GF h=2;\n")
    spec = imported(text, "spectra")
    assert spec.outputs == ("h_0", "h_1", "f_0")
    assert texts(spec, "guarantee.safety")[0] == f"G(((((!h_0 & !h_1))) {op} (((!f_0)))))"
    assert agree_with_omega(spec) == {"tli": realizable, "textbook": realizable}


def test_an_order_between_wide_integers_is_a_comparator_with_the_same_meaning() -> None:
    """``a < b`` over two 5-bit integers (1,024 value pairs) is written with a comparator over
    one operand's bits, not as the disjunction of the value pairs (which made SYNTECH17's
    ConvoyCar specs, two Int(0..255) compared, 2.8 million characters per formula). The
    comparator side's domain must fill its bits (``d``'s does not: ``a`` is the comparator
    there). Checked on random (current, next) assignments, both values of the output."""
    text = ("module M\nenv Int(0..31) a;\nenv Int(3..34) b;\nenv Int(0..20) d;\n"
            "sys boolean[5] s;\n"
            "gar G (s[0] <-> a < b);\ngar G (s[1] <-> next(a) >= b);\n"
            "gar G (s[2] <-> b <= a);\ngar G (s[3] <-> a > next(b));\n"
            "gar G (s[4] <-> d > a);\n")
    spec = imported(text, "spectra")
    tests = [(("a", False), "<", ("b", False)), (("a", True), ">=", ("b", False)),
             (("b", False), "<=", ("a", False)), (("a", False), ">", ("b", True)),
             (("d", False), ">", ("a", False))]
    lows = {"a": 0, "b": 3, "d": 0}
    bits = {"a": 5, "b": 5, "d": 5}
    cmp = {"<": lambda x, y: x < y, "<=": lambda x, y: x <= y, ">": lambda x, y: x > y,
           ">=": lambda x, y: x >= y}

    def assign(values: dict[str, int]) -> dict[str, bool]:
        return {f"{v}_{i}": bool(((values[v] - lows[v]) >> i) & 1)
                for v in values for i in range(bits[v])}

    safety = spec.guarantee.safety
    assert len(safety) == 5  # (d's domain constraint is an assumption)
    assert max(len(f.text) for f in safety[:4]) < 8_000  # the pairs took about 30,000
    rng = __import__("random").Random(7)
    for k, ((x, xn), op, (y, yn)) in enumerate(tests):
        g = body(safety[k].ltl)
        for _ in range(400):
            cur = {"a": rng.randint(0, 31), "b": rng.randint(3, 34), "d": rng.randint(0, 20)}
            nxt = {"a": rng.randint(0, 31), "b": rng.randint(3, 34), "d": rng.randint(0, 20)}
            want = cmp[op]((nxt if xn else cur)[x], (nxt if yn else cur)[y])
            for s_val in (want, not want):
                outs = {f"s_{i}": s_val for i in range(5)}
                got = holds(g, {**assign(cur), **outs}, {**assign(nxt), **outs})
                assert got == (s_val == want), (k, cur, nxt)


def test_quantifiers_in_sets_and_array_functions() -> None:
    text = ("module M\ntype Col = {RED, GREEN, BLUE};\nenv Col c;\nenv boolean[3] r;\n"
            "sys boolean s;\nsys boolean t;\n"
            "gar G (s <-> forall i in Int(0..2). r[i]);\ngar G (t <-> r.any);\n"
            "gar G (c in {RED, BLUE} -> r.all | !s);\n"
            "gar G (exists k in Col. c = k);\n")
    spec = imported(text, "spectra")
    safety = texts(spec, "guarantee.safety")
    assert safety[0] == "G(((s) <-> ((r_0 & r_1 & r_2))))"
    assert safety[1] == "G(((t) <-> ((r_0 | r_1 | r_2))))"
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


def test_spectra_precedence_implication_binds_loosest() -> None:
    """Spectra: ``a -> b <-> c`` is ``a -> (b <-> c)`` (Spectra.xtext); slugs reads
    ``(a -> b) <-> c``."""
    spec = imported("module M\nenv boolean e;\nsys boolean s;\ngar G (e -> s <-> e);\n",
                    "spectra")
    f = spec.guarantee.safety[0].ltl
    assert all(holds(body(g), {"e": False, "s": False}) for g in conjuncts(f))
    slugs = imported("[INPUT]\ne\n[OUTPUT]\ns\n[SYS_TRANS]\ne -> s <-> e\n", "structuredslugs")
    f = slugs.guarantee.safety[0].ltl
    assert not all(holds(body(g), {"e": False, "s": False}) for g in conjuncts(f))


def test_always_is_a_state_invariant_g_is_a_step_constraint() -> None:
    """Spectra's ``alw phi`` (no next) is ``ini phi`` and ``G next(phi)``
    (StateInvTranslator); ``G phi`` stays a constraint on each step's source state."""
    spec = imported("module M\nenv boolean e;\nsys boolean s;\nasm alw e;\ngar always s;\n"
                    "gar G s;\n", "spectra")
    assert texts(spec, "assume.init") == ["e"] and texts(spec, "assume.safety") == ["G(X e)"]
    assert texts(spec, "guarantee.init") == ["s"]
    assert texts(spec, "guarantee.safety") == ["G(X s)", "G(s)"]


def test_liveness_over_steps_gets_a_fresh_variable() -> None:
    """``GF phi(v, v')`` becomes ``GF j`` with ``j`` false at time 0 and ``j' <-> phi``
    (Spectra's PrimesInJusticeTranslator; slugs allows the same goals)."""
    spec = imported("module M\nenv boolean e;\nsys boolean s;\ngar GF (s & next(!s));\n",
                    "spectra")
    assert spec.outputs == ("s", "primed_justice_0")
    assert texts(spec, "guarantee.liveness") == ["GF(primed_justice_0)"]
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    slugs = imported("[INPUT]\na\n[OUTPUT]\nb\n[SYS_LIVENESS]\nb' & !b\n", "structuredslugs")
    assert slugs.outputs == ("b", "primed_justice_0")
    assert agree_with_omega(slugs) == {"tli": True, "textbook": True}


def test_multiplication_division_and_remainder_are_bit_blasted() -> None:
    """Exactly, over the operands' values; Spectra's ``mod`` binds looser than ``+``."""
    spec = imported("module M\nenv Int(0..3) x;\nsys Int(0..9) y;\n"
                    "gar G (next(y) = next(x) * 3 mod 4 + x / 2);\n", "spectra")
    f = spec.guarantee.safety[0].ltl

    def enc(p: str, v: int, w: int) -> dict[str, bool]:
        return {f"{p}_{b}": bool(v >> b & 1) for b in range(w)}

    for x0, x1, y1 in itertools.product(range(4), range(4), range(10)):
        now = {**enc("x", x0, 2), **enc("y", 0, 4)}
        nxt = {**enc("x", x1, 2), **enc("y", y1, 4)}
        want = y1 == x1 * 3 % (4 + x0 // 2)
        assert all(holds(body(g), now, nxt) for g in conjuncts(f)) == want, (x0, x1, y1)


def test_a_counter_is_a_system_integer_with_its_update_rules() -> None:
    text = ("module M\nenv boolean e;\nsys boolean s;\n"
            "counter c(0..2) {\n  c = 0;\n  inc: e;\n  reset: s & !e;\n  overflow: keep;\n}\n"
            "gar G (c = 2 -> next(s));\nasm GF e;\nasm GF !e;\ngar GF (c = 0);\n")
    spec = imported(text, "spectra")
    assert spec.outputs == ("s", "c_0", "c_1")
    assert len(spec.guarantee.safety) == 5  # inc, reset, no change, the use, c's domain
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    stuck = imported(text.replace("  overflow: keep;\n", ""), "spectra")  # overflow: false
    assert agree_with_omega(stuck) == {"tli": False, "textbook": False}  # e three times


def test_spec_check_reads_foreign_files_directly(tmp_path: Path) -> None:
    from tli_verify.logic.check import check_spec_file

    path = tmp_path / "m.spectra"
    path.write_text("module M\nenv boolean e;\nsys boolean s;\ngar G (s <-> PREV(e));\n",
                    encoding="utf-8")
    assert check_spec_file(path).realizable
    path.write_text("module M\nenv boolean e;\nsys boolean s;\ngar G (x);\n", encoding="utf-8")
    with pytest.raises(SpecError, match=r"m\.spectra:4: unknown identifier 'x'"):
        check_spec_file(path)


def test_an_initial_assumption_over_system_variables_is_read_as_spectra_reads_it() -> None:
    """Spectra checks ``forall X, Y. theta_e(X, Y) -> exists Y'. theta_s & Win`` (the system's
    values in ``theta_e`` are quantified universally, outside): ``theta_e`` acts through its
    projection ``exists Y. theta_e``. The import writes that projection over the inputs' bits;
    checked here against brute force over every input value, the system's values within their
    domains (``k`` in 0..2: its code 3 does not count)."""
    text = ("module M\nenv Int(0..3) a;\nenv boolean req;\nsys Int(0..2) k;\nsys boolean b;\n"
            "asm ini (a = k) | (req & b);\nasm ini !req | a != 0;\ngar ini k = 0;\n"
            "gar G (b <-> req);\nasm GF req;\ngar GF b;\n")
    spec = imported(text, "spectra")
    init = [f.ltl for f in spec.assume.init]
    assert all(set(map(str, __import__("spot").atomic_prop_collect(f))) <= set(spec.inputs)
               for f in init)
    for a, r in itertools.product(range(4), (False, True)):
        env = {"a_0": bool(a & 1), "a_1": bool(a & 2), "req": r}
        want = any((a == k) or (r and b) for k in range(3) for b in (False, True)) \
            and (not r or a != 0)
        got = all(holds(f, env) for f in init)
        assert got == want, (a, r)
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


@pytest.mark.parametrize(("assumptions", "expected"), [
    ("asm ini k = 3;", ["false"]),  # no value of k: the assumption is false
    ("asm ini b | k = 1;", []),     # some system value satisfies it: nothing is assumed
    # projected together, not conjunct by conjunct: exists k. (k = 0 -> req) & k = 0 is req
    ("asm ini (k = 0 -> req) & k = 0;", ["((req))"]),
    ("asm ini k = 0 -> req;\nasm ini k = 0;", ["((req))"]),
    # k's domain is the system's initial condition in Spectra: its unused code 3 counts
    ("asm ini !(k = 0) & !(k = 1) & !(k = 2);", []),
])
def test_initial_assumptions_over_system_variables_only_project_to_a_constant(
        assumptions: str, expected: list[str]) -> None:
    text = ("module M\nenv boolean req;\nsys Int(0..2) k;\nsys boolean b;\n"
            f"{assumptions}\ngar ini b;\ngar G (b -> req);\n")
    spec = imported(text, "spectra")
    assert texts(spec, "assume.init") == expected
    # the verdict follows: b must start true, and b -> req; realizable iff req is assumed
    assert agree_with_omega(spec)["textbook"] is (expected != [])


def test_a_projection_is_written_with_disjoint_cubes_not_every_assignment() -> None:
    """``exists k. a > k`` over 7-bit integers is ``a != 0``: 7 cubes, not 127 values."""
    spec = imported("module M\nenv Int(0..127) a;\nsys Int(0..127) k;\nasm ini a > k;\n"
                    "gar G k = 0;\n", "spectra")
    (init,) = spec.assume.init
    for a in range(128):
        assert holds(init.ltl, {f"a_{i}": bool((a >> i) & 1) for i in range(7)}) == (a != 0)
    assert init.text.count("|") == 6
