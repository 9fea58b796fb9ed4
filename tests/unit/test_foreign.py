"""Specs of other GR(1) tools (Spectra, structured slugs, slugsin) translated to our TOML.

Each test writes its own small spec inline; the imported spec must load, and its verdict in
both readings of safety at time 0 must equal omega's on the same formulas.
"""

from __future__ import annotations

import contextlib
import io
import itertools
from pathlib import Path

import pytest

from tests.support.ltl_eval import holds
from tests.support.omega_oracle import omega_realizable
from tli_verify.errors import SpecError
from tli_verify.logic.check import check_spec
from tli_verify.logic.foreign import import_spec_text
from tli_verify.logic.spec import GR1Spec, parse_spec


def imported(text: str, fmt: str, **kw: object) -> GR1Spec:
    return parse_spec(import_spec_text(text, fmt=fmt, where=f"t.{fmt}", **kw),  # type: ignore[arg-type]
                      path="t.toml")


def omega(spec: GR1Spec, semantics: str) -> bool:
    with contextlib.redirect_stdout(io.StringIO()):
        return omega_realizable(spec, semantics=semantics)


def agree_with_omega(spec: GR1Spec) -> dict[str, bool]:
    from tli_verify.logic.gr1 import build_game, solve

    out = {}
    for sem in ("tli", "textbook"):
        ours = solve(build_game(spec, semantics=sem), keep_iterates=False).realizable
        assert ours == omega(spec, sem), sem
        out[sem] = ours
    return out


ELEVATOR = """\
module Elevator
// a comment
env {LOWER, MIDDLE, UPPER} floor;
sys {FWD, BWD, STOP} mot;
sys Int(0..2) cnt;
env boolean req;
define
  stopped := mot = STOP;
guarantee -- initial state
  stopped;
gar count: G (cnt' = cnt + 1 | next(cnt) = 0);
/* block
   comment */
gar alwEv (mot=FWD);
gar GF (floor=LOWER -> mot=BWD);
asm G (stopped -> next(floor) != UPPER);
asm alwEv req;
"""


def test_spectra_bit_blasts_and_decides_like_omega() -> None:
    spec = imported(ELEVATOR, "spectra")
    assert spec.name == "Elevator" and spec.semantics == "textbook"
    assert spec.inputs == ("floor_0", "floor_1", "req")
    assert spec.outputs == ("mot_0", "mot_1", "cnt_0", "cnt_1")
    # 3-value domains do not fill 2 bits: a domain constraint per variable and side
    assert len(spec.assume.init) == 1 and len(spec.guarantee.init) == 3
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    assert check_spec(spec).realizable


def _eval_formula(spec: GR1Spec, section: str, index: int, values: dict[str, bool],
                  nxt: dict[str, bool] | None = None) -> bool:
    side, slot = section.split(".")
    f = getattr(getattr(spec, side), slot)[index]
    from tests.support.ltl_eval import body, conjuncts

    if slot == "safety":
        return all(holds(body(g), values, nxt) for g in conjuncts(f.ltl))
    return holds(f.ltl, values)


def _encode(prefix: str, value: int, width: int) -> dict[str, bool]:
    return {f"{prefix}_{b}": bool((value >> b) & 1) for b in range(width)}


def test_integer_arithmetic_is_bit_blasted_exactly() -> None:
    """``cnt' = cnt + 1 | cnt' = 0`` holds for exactly the pairs of values it should."""
    spec = imported(ELEVATOR, "spectra")
    base = {"floor_0": False, "floor_1": False, "req": False, "mot_0": False, "mot_1": True}
    for now, then in itertools.product(range(3), repeat=2):
        cur = {**base, **_encode("cnt", now, 2)}
        nxt = {**base, **_encode("cnt", then, 2)}
        want = then == now + 1 or then == 0
        assert _eval_formula(spec, "guarantee.safety", 0, cur, nxt) == want, (now, then)


def test_structuredslugs_integers_and_prefix_lines() -> None:
    text = """\
# a reservoir
[INPUT]
inflow

[OUTPUT]
level: 3...6
outflow

[ENV_TRANS]
| ! inflow ! inflow'

[SYS_INIT]
level = 4
! outflow

[SYS_TRANS]
inflow & !outflow -> level' = level + 1
!inflow & outflow -> level' + 1 = level
(inflow <-> outflow) -> level' = level
level' <= 5

[SYS_LIVENESS]
level = 4
"""
    spec = imported(text, "structuredslugs")
    assert spec.outputs == ("level_0", "level_1", "outflow")
    assert spec.semantics == "textbook"
    verdicts = agree_with_omega(spec)
    assert verdicts == {"tli": True, "textbook": True}
    # level 3..6 fills its two bits: no domain constraint added
    assert len(spec.guarantee.init) == 2


def test_slugsin_memory_buffers() -> None:
    text = """\
[INPUT]
a
[OUTPUT]
b
c
[SYS_TRANS]
$ 2 ^ a' b' & ? 0 ! c'
[SYS_LIVENESS]
b
[ENV_LIVENESS]
a
! a
"""
    spec = imported(text, "slugsin")
    # the buffer's value is its last element: (a' ^ b') & !c'
    f = spec.guarantee.safety[0]
    for a, b, c in itertools.product([False, True], repeat=3):
        nxt = {"a": a, "b": b, "c": c}
        assert _eval_formula(spec, "guarantee.safety", 0, {"a": False, "b": False,
                                                          "c": False}, nxt) == (
            (a != b) and not c), f.text
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}


def test_no_semantics_key_means_ours() -> None:
    spec = imported(ELEVATOR, "spectra", semantics=None)
    assert spec.semantics == "tli"


SPECTRA_HEAD = "module M\nenv boolean e;\nsys boolean s;\nsys Int(0..3) n;\n"


@pytest.mark.parametrize(("line", "reason"), [
    ("counter c(0..3) { inc: s; overflow: wrap; }", "counter 'c': unsupported entry"),
    ("gar trig [true]*[e] |=> [s];", "triggers"),
    ("weight w: s;", "weights"),
    ("asm G (s -> next(e));", None),  # allowed: next of an input
    ("asm G (e -> next(s));", "next of system variable 's' inside an assumption"),
    ("asm G (e -> next(PREV(e)));", "next of system variable 'PREV_aux_0' inside an "
     "assumption"),
    ("gar G (next(next(s)));", "nested next"),
    ("gar next(s);", "next inside an initial condition"),
    ("gar G (n / (n - n) = 2);", "division or remainder by an expression that can be 0"),
    ("gar G (unknown);", "unknown identifier 'unknown'"),
    ("gar G (q(s));", "q(...): unknown predicate or pattern"),
    ("gar F s;", "temporal operator 'F' outside GF"),
    ("gar G (s U e);", "'U'"),
    ("define d(x) := x;", "define 'd' with parameters"),
    ("sys boolean[0] arr;", "array size 0 outside"),
    ("sys boolean[K] arr;", "array size 'K' is not a constant integer"),
    ("gar G (s.min);", "array function"),
    ("gar G (s -> s.all);", "unknown identifier or array function"),
    ("gar n{Int(0..1) i}: G s;", "constraints with parameters"),
])
def test_spectra_refusals_name_the_construct_and_line(line: str, reason: str | None) -> None:
    text = SPECTRA_HEAD + ("define\n" if line.startswith("define") else "") + \
        (line.removeprefix("define ") if line.startswith("define") else line) + "\n"
    if reason is None:
        imported(text, "spectra")
        return
    with pytest.raises(SpecError) as err:
        imported(text, "spectra")
    msg = str(err.value)
    assert reason in msg, msg
    assert msg.startswith("t.spectra:"), msg
    assert "\n" not in msg


def test_refusals_of_slugs_constructs() -> None:
    with pytest.raises(SpecError, match=r"t\.structuredslugs:1: section \[OBSERVABLE_INPUT\]"):
        imported("[OBSERVABLE_INPUT]\na\n[OUTPUT]\nb\n", "structuredslugs")
    with pytest.raises(SpecError, match=r"t\.slugsin:6: recall \? 3"):
        imported("[INPUT]\na\n[OUTPUT]\nb\n[SYS_TRANS]\n$ 1 ? 3\n", "slugsin")
    with pytest.raises(SpecError, match=r"t\.slugsin:6: the variable|next of system variable"):
        imported("[INPUT]\na\n[OUTPUT]\nb\n[ENV_TRANS]\n& a b'\n", "slugsin")
    with pytest.raises(SpecError, match="no system variable"):
        imported("[INPUT]\na\n", "slugsin")
    with pytest.raises(SpecError, match=r"t\.slugsin:4: stray tokens"):
        imported("[OUTPUT]\nb\n[SYS_INIT]\n! b b\n", "slugsin")


def test_names_are_lowered_and_clashes_refused() -> None:
    spec = imported("module M\nenv boolean Req;\nsys boolean Grant;\ngar GF (Grant);\n",
                    "spectra")
    assert spec.inputs == ("req",) and spec.outputs == ("grant",)
    with pytest.raises(SpecError, match=r"t\.spectra:3: variable 'A' becomes AP 'a'"):
        imported("module M\nenv boolean a;\nsys boolean A;\n", "spectra")


def test_a_pattern_from_an_import_not_found_is_refused_where_used(tmp_path: Path) -> None:
    head = 'import "DwyerPatterns.spectra";\n' + SPECTRA_HEAD
    assert imported(head + "gar GF s;\n", "spectra").guarantee.liveness
    with pytest.raises(SpecError, match=r"t\.spectra:6: pRespondsToS\(\.\.\.\): unknown "
                       "predicate or pattern"):
        imported(head + "gar pRespondsToS(e, s);\n", "spectra")
    with pytest.raises(SpecError, match=r"import 'DwyerPatterns\.spectra' not found"):
        imported(head + "gar pRespondsToS(e, s);\n", "spectra", base=tmp_path)


def test_spectra_type_aliases() -> None:
    text = ('import "lib.spectra"\nmodule M\nenv Lift l;\ntype Cmd = {FWD, STOP, BWD};\n'
            "type Lift = {UP, STOP, DOWN};\nsys Cmd c;\ngar G (l = STOP -> c = STOP);\n"
            "gar GF (c = FWD);\n"
            "asm GF (l != STOP);\n")
    spec = imported(text, "spectra")
    assert spec.inputs == ("l_0", "l_1") and spec.outputs == ("c_0", "c_1")
    assert agree_with_omega(spec) == {"tli": True, "textbook": True}
    with pytest.raises(SpecError, match=r"t\.spectra:2: expected type NAME"):
        imported("module M\ntype = {A};\n", "spectra")
