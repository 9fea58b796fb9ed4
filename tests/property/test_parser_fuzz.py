"""The parser never fails with anything but SpecError."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.errors import SpecError
from tli_verify.logic.ltl import Slot, classify, parse_formula
from tli_verify.logic.spec import parse_spec

TOKENS = ["a", "b", "r", "!", "&", "|", "->", "<->", "X", "G", "F", "U", "W", "R", "(", ")",
          "true", "false", " ", "[]", "<>", "{", "}", ";", "*", "1", "0", "^", "xor", "M", "\"",
          "X[2]", "F[1:3]"]


@settings(max_examples=400)
@given(st.lists(st.sampled_from(TOKENS), max_size=14))
def test_token_soup_parses_or_raises_spec_error(tokens: list[str]) -> None:
    text = " ".join(tokens)
    try:
        f = parse_formula(text, where="fuzz")
    except SpecError:
        return
    for slot in Slot:
        try:
            classify(f, slot, where="fuzz")
        except SpecError:
            pass


@settings(max_examples=300)
@given(st.text(max_size=60))
def test_any_text_parses_or_raises_spec_error(text: str) -> None:
    try:
        parse_formula(text, where="fuzz")
    except SpecError:
        pass


@settings(max_examples=200)
@given(st.text(max_size=200))
def test_any_spec_text_loads_or_raises_spec_error(text: str) -> None:
    try:
        parse_spec(text, path="fuzz.toml")
    except SpecError as exc:
        assert "\n" not in str(exc)


@settings(max_examples=200)
@given(formula=st.lists(st.sampled_from(TOKENS), min_size=1, max_size=10).map(" ".join))
def test_spec_with_fuzzed_formula(formula: str) -> None:
    text = ('inputs = ["r"]\noutputs = ["a", "b"]\n[guarantee]\n'
            f"safety = [{formula!r}]\n".replace("'", '"'))
    try:
        parse_spec(text, path="fuzz.toml")
    except SpecError as exc:
        assert str(exc).startswith("fuzz.toml")
