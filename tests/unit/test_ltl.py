"""GR(1) slot classification of Spot formulas (every formula checked in its slot)."""

from __future__ import annotations

import re

import pytest

from tli_verify.errors import SpecError
from tli_verify.logic.ltl import Slot, classify, gr1_body, parse_formula


@pytest.mark.parametrize(
    ("text", "slot"),
    [
        ("a & !b", Slot.INIT),
        ("G(a -> X(b | c))", Slot.SAFETY),
        ("G(a) & G(b -> X !a)", Slot.SAFETY),
        ("G(a <-> X b)", Slot.SAFETY),
        ("GF(!a | r)", Slot.LIVENESS),
        ("G F d", Slot.LIVENESS),
        ("G(a | !a)", Slot.SAFETY),
    ],
)
def test_accepts_formulas_in_their_slot(text: str, slot: Slot) -> None:
    f = parse_formula(text, where="t")
    classify(f, slot, where="t")
    assert gr1_body(f, slot).is_boolean() or slot is Slot.SAFETY


@pytest.mark.parametrize(
    ("text", "slot", "message"),
    [
        ("F G a", Slot.LIVENESS, "not GF(p)"),
        ("G(a -> X X b)", Slot.SAFETY, "nested X"),
        ("G(a U b)", Slot.SAFETY, "not allowed"),
        ("F a", Slot.SAFETY, "not G(p)"),
        ("GF(a U b)", Slot.LIVENESS, "not propositional"),
        ("X a", Slot.INIT, "not propositional"),
        ("GF(X a)", Slot.LIVENESS, "not propositional"),
    ],
)
def test_rejects_formulas_outside_their_slot(text: str, slot: Slot, message: str) -> None:
    f = parse_formula(text, where="spec.toml:3 guarantee.safety[0]")
    with pytest.raises(SpecError, match=re.escape(message)) as info:
        classify(f, slot, where="spec.toml:3 guarantee.safety[0]")
    assert "spec.toml:3" in str(info.value)


def test_offending_subformula_is_named() -> None:
    f = parse_formula("G(a -> X(b & X c))", where="w")
    with pytest.raises(SpecError, match=r"'X c'.*nested X|nested X"):
        classify(f, Slot.SAFETY, where="w")


@pytest.mark.parametrize("text", ["G(a -> ", "a U", "", "   ", "a &&& b", "(a", "{a;b}[]-> c"])
def test_parse_errors_are_spec_errors(text: str) -> None:
    with pytest.raises(SpecError):
        parse_formula(text, where="w")


def test_bodies() -> None:
    assert str(gr1_body(parse_formula("G(a -> X b)", where="w"), Slot.SAFETY)) == "a -> Xb"
    assert str(gr1_body(parse_formula("GF(a | b)", where="w"), Slot.LIVENESS)) == "a | b"
