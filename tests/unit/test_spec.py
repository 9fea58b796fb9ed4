"""Spec files: loading, validation errors naming file/line/field, the [modes] constraints."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tli_verify.errors import SpecError
from tli_verify.logic.ltl import MAX_FORMULA_DEPTH, MAX_FORMULA_NODES
from tli_verify.logic.spec import MAX_TOML_DEPTH, label_holds, load_spec, parse_spec

MINIMAL = """
name = "t"
inputs = ["r"]
outputs = ["a", "b"]
[guarantee]
safety = ["G(a -> X b)"]
"""


def test_shipped_specs_load(specs_dir: Path) -> None:
    paths = sorted(specs_dir.glob("*.toml"))
    assert len(paths) >= 10
    for path in paths:
        spec = load_spec(path)
        assert spec.outputs and spec.path == str(path)


def test_scoop_modes_and_added_constraints(specs_dir: Path) -> None:
    spec = load_spec(specs_dir / "scoop.toml")
    assert spec.mode_names == ("a", "b", "c", "d")
    added = [f.text for f in spec.added()]
    assert "G(X(a -> (!r & !s & !t)))" in added
    assert any(f.section == "assume.safety" for f in spec.added())
    assert label_holds(spec, "b", {"r": True, "s": False, "t": False})
    assert not label_holds(spec, "a", {"r": True, "s": False, "t": False})


def test_line_numbers_point_at_the_formula(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(MINIMAL)
    spec = load_spec(path)
    f = spec.guarantee.safety[0]
    assert f.line == 6
    assert f.where(str(path)).endswith(":6 guarantee.safety[0]")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty spec file"),
        ("name = ", "invalid TOML"),
        ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = ["G(a -> X q)"]',
         "unknown AP 'q'"),
        ('inputs = ["a"]\noutputs = ["a"]', "both an input and an output"),
        ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nliveness = ["F G a"]', "not GF(p)"),
        ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = ["G(a -> X X a)"]', "nested X"),
        ('inputs = ["r"]\noutputs = ["a"]\n[assume]\nsafety = ["G(r -> X a)"]',
         "next value of output"),
        ('inputs = ["r"]\noutputs = ["a"]\n[assume]\ninit = "a"', "mentions output 'a'"),
        ('inputs = ["R"]\noutputs = ["a"]', "not a valid AP name"),
        ('inputs = ["r"]\noutputs = ["a"]\nbogus = 1', "unknown top-level key 'bogus'"),
        ('inputs = ["r"]\noutputs = ["a"]\n[modes]\nz = "r"', "'z' is not an output"),
        ('inputs = ["r"]\noutputs = ["a"]\n[modes]\na = "a"', "labels are formulas over the"),
        ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = "G a"', "list of formula"),
        ('inputs = ["r"]\noutputs = []', "at least one system AP"),
        ('inputs = ["r"]\noutputs = ["a"]\nexpect = "maybe"', "'expect'"),
    ],
)
def test_bad_specs_raise_spec_errors_with_the_file(tmp_path: Path, text: str, message: str
                                                   ) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SpecError, match=re.escape(message)) as info:
        load_spec(path)
    assert str(path) in str(info.value)
    assert "\n" not in str(info.value)


def test_binary_and_huge_files(tmp_path: Path) -> None:
    binary = tmp_path / "bin.toml"
    binary.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(SpecError, match="not a text file"):
        load_spec(binary)
    huge = tmp_path / "huge.toml"
    huge.write_text("# " + "x" * (5 * 1024 * 1024))
    with pytest.raises(SpecError, match="larger than the limit"):
        load_spec(huge)
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "missing.toml")
    with pytest.raises(SpecError, match="is a directory"):
        load_spec(tmp_path)


def test_parse_spec_defaults() -> None:
    spec = parse_spec(MINIMAL)
    assert spec.name == "t"
    assert spec.modes is None
    assert spec.expect_realizable
    assert spec.mode_names == ("a", "b")


# --- hostile specs: nesting limits ---------------------------------------------------------------

def _nest(kind: str, depth: int) -> str:
    """A formula over ``r`` and ``a`` nested ``depth`` levels by one constructor."""
    if kind == "paren":
        return "(" * depth + "a" + ")" * depth
    if kind == "not":
        return "!(" * depth + "a" + ")" * depth
    if kind == "or":
        return "(a | " * depth + "a" + ")" * depth
    if kind == "implies":  # right-associative: nests without parentheses
        return "r -> " * depth + "a"
    return "(r <-> " * depth + "r" + ")" * depth


_FIELDS = {
    # field -> (spec text around the formula, expected field tag in the message)
    "init": ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\ninit = "{f}"\n',
             ":4: guarantee.init[0]"),
    "safety": ('inputs = ["r"]\noutputs = ["a"]\n[guarantee]\nsafety = ["G({f})"]\n',
               ":4: guarantee.safety[0]"),
    "label": ('inputs = ["r", "s"]\noutputs = ["a", "b"]\n[modes]\na = "{f}"\nb = "!r"\n',
              ":4: modes.a"),
}


@settings(max_examples=60, deadline=None)
@given(kind=st.sampled_from(["paren", "not", "or", "implies", "iff"]),
       field=st.sampled_from(sorted(_FIELDS)), depth=st.integers(101, 4000))
def test_deep_formulas_are_refused_naming_file_line_field_and_limit(
        kind: str, field: str, depth: int) -> None:
    template, tag = _FIELDS[field]
    formula = _nest(kind, depth)
    if field == "label":
        formula = formula.replace("a", "s")
    text = template.replace("{f}", formula)
    with pytest.raises(SpecError) as info:
        parse_spec(text, path="deep.toml")
    message = str(info.value)
    assert message.startswith("deep.toml" + tag), message
    assert f"limit of {MAX_FORMULA_DEPTH} levels" in message


@pytest.mark.parametrize("kind", ["paren", "not", "or", "implies", "iff"])
def test_formulas_within_the_depth_limit_load(kind: str) -> None:
    text = _FIELDS["safety"][0].replace("{f}", _nest(kind, 40))
    assert parse_spec(text, path="ok.toml").guarantee.safety


def test_deep_toml_nesting_is_refused() -> None:
    for depth in (MAX_TOML_DEPTH + 1, 5000):
        text = 'inputs = ["r"]\noutputs = ["a"]\nname = ' + "[" * depth + "]" * depth + "\n"
        with pytest.raises(SpecError, match=f"limit of {MAX_TOML_DEPTH} levels"):
            parse_spec(text, path="deep.toml")


def test_gate_blocks_a_deep_spec(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tli_verify.cli import main

    (tmp_path / "specs").mkdir()
    (tmp_path / "specs" / "deep.toml").write_text(
        _FIELDS["init"][0].replace("{f}", _nest("or", 3000)))
    assert main(["gate", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    assert err.startswith("error: gate blocked")
    blocked = [line for line in out.splitlines() if line.startswith("BLOCK spec")]
    assert len(blocked) == 1 and "deep.toml" in blocked[0] and "limit of" in blocked[0]


@pytest.mark.parametrize("name", ["a\\nb", "tab\\tbed", "bell\\u0007", "nul\\u0000"])
def test_spec_names_with_control_characters_are_refused(name: str) -> None:
    with pytest.raises(SpecError, match=r"n.toml:1: 'name' must be one line"):
        parse_spec(f'name = "{name}"\n' + MINIMAL.replace('name = "t"\n', ""), path="n.toml")


def test_labels_at_the_depth_limit_load_with_their_mode_constraints() -> None:
    """The constraints the tool builds around a label add a few levels: a label within the
    limit must not fail there (with a message that names no file line)."""
    label = "r -> " * (MAX_FORMULA_DEPTH - 1) + "s"
    spec = parse_spec(f'inputs = ["r", "s"]\noutputs = ["a", "b"]\n[modes]\na = "{label}"\n'
                      'b = "!r"\n', path="m.toml")
    assert spec.added()


def test_long_wide_formulas_load_and_cost_is_what_is_bounded() -> None:
    """No limit on characters: a wide formula of real shape (a disjunction of 9,000 cubes,
    ~250,000 characters, as bit-blasted benchmark specs have) loads; the node and depth
    limits refuse what costs, naming the limit."""
    cubes = " | ".join(f"(x{i % 7} & !y{i % 5} & X x{(i + 1) % 7} & X y{i % 3})"
                       for i in range(9000))
    assert len(cubes) > 200_000
    head = ("inputs = [" + ", ".join(f'"x{i}"' for i in range(7)) + "]\noutputs = ["
            + ", ".join(f'"y{i}"' for i in range(5)) + "]\n[guarantee]\n")
    spec = parse_spec(head + f'safety = ["G({cubes})"]\n', path="wide.toml")
    assert spec.guarantee.safety
    from tli_verify.logic.ltl import parse_formula

    with pytest.raises(SpecError, match=r"w: formula has \d+ operator nodes .* limit of 100"):
        parse_formula(cubes, where="w", max_nodes=100)
    # a 200,000-deep chain of X is refused before Spot parses it (Spot's recursion would die)
    with pytest.raises(SpecError, match=f"deeper than the limit of {MAX_FORMULA_DEPTH}"):
        parse_formula("X " * 200_000 + "a", where="w")


@pytest.mark.parametrize("n", [14, 30])
def test_formulas_that_expand_exponentially_are_refused(n: int) -> None:
    """``F[1:3]`` nested n times is a short text but a huge tree: refused at once (ranges are
    not GR(1) syntax), and a formula that expands past the node limit is refused too."""
    text = _FIELDS["safety"][0].replace("{f}", "F[1:3] " * n + "a")
    with pytest.raises(SpecError, match=r"deep.toml:4: guarantee.safety\[0\]: character '\['"):
        parse_spec(text, path="deep.toml")
    import spot

    from tli_verify.logic.ltl import formula_stats

    depth, size = formula_stats(spot.formula("F[1:3] " * n + "a"))  # DAG, counted fast
    assert size > MAX_FORMULA_NODES and depth == 5 * n + 1


@pytest.mark.parametrize("text", ["[] [] X X []", "{a;b}", "a*", '"quoted ap"', "F[1:3] a"])
def test_non_gr1_syntax_is_refused_before_spot(text: str) -> None:
    """PSL/SERE characters are refused up front (Spot needs ~14 s on ``[] [] X X []``)."""
    from tli_verify.logic.ltl import parse_formula

    with pytest.raises(SpecError, match=r"^f.toml:2 init: character .* is not allowed"):
        parse_formula(text, where="f.toml:2 init")
