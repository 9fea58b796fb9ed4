"""``tli replay`` on hostile case files: every corruption of a case is exit 2 with ONE ``error:``
line naming the case file (and the field), never a traceback or an internal error (exit 70),
and never a replay: a corrupted regression case must not look fixed (exit 0) or reproduced.

The cases are the shipped regression cases (``tests/regressions/``, version 2), their version 1
form (``world`` instead of ``files.task``) and a counterexample ``tli verify`` finds; the
mutations are hand-written tables (one per field) and hypothesis-generated ones (a required key
dropped, a value of another type or out of range, an unknown key, a non-finite number, a
repeated key). Runs ``tli`` in-process.
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.cli import run
from tli_verify.errors import CampaignError
from tli_verify.io import validate_schema
from tli_verify.limits import MAX_CAMPAIGN_STEPS, MAX_PUSHES
from tli_verify.verify.oracle import ViolationKind
from tli_verify.verify.strategies import LEVELS

REPO = Path(__file__).resolve().parents[2]
REGRESSIONS = REPO / "tests" / "regressions"
FIG7 = REGRESSIONS / "scoop_fig7_looping_no_modulation.json"  # a task push into pink
CUT = REGRESSIONS / "scoop_ltlds_cut_failed.json"  # two free pushes, modulation on
KINDS = [k.value for k in ViolationKind]
SCHEMA = json.loads((REPO / "tli_verify" / "schemas" / "case.schema.json").read_text()) \
    if (REPO / "tli_verify" / "schemas" / "case.schema.json").is_file() else {}


def _load(path: Path) -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(path.read_text())
    return doc


def _v1(doc: dict[str, Any]) -> dict[str, Any]:
    """The version 1 form of a version 2 case: the task named by ``world``."""
    out = copy.deepcopy(doc)
    out["version"] = 1
    out["world"] = "scoop"
    del out["files"]["task"]
    return out


BASES = {"fig7": _load(FIG7), "cut": _load(CUT), "fig7-v1": _v1(_load(FIG7))}


def _replay(capsys: pytest.CaptureFixture[str], case: Path, content: dict[str, Any] | str
            ) -> tuple[int, str, str]:
    case.write_text(content if isinstance(content, str) else json.dumps(content))
    return run(capsys, "replay", str(case))


def _refusal(code: int, out: str, err: str, case: Path, field: str | None = None,
             needle: str | None = None) -> str | None:
    """Why ``(code, out, err)`` is not a clean refusal of ``case`` (None: it is): exit 2, no
    output, one ``error:`` line naming the case file (then ``field``, its own or one of its
    parts: ``start`` names ``start[0]`` too) and ``needle``."""
    lines = err.strip().splitlines()
    if code != 2 or out or len(lines) != 1 or not lines[0].startswith("error:"):
        return f"exit {code}, out {out[:120]!r}, err {err[:300]!r}"
    line = lines[0]
    if "Traceback" in err or "internal error" in line or str(case) not in line:
        return f"not a named refusal: {line!r}"
    if field is not None and re.search(re.escape(f"{case}: {field}") + r"[:.\[]", line) is None:
        return f"does not name {field}: {line!r}"
    if needle is not None and needle not in line:
        return f"does not say {needle!r}: {line!r}"
    return None


def _edited(base: str, path: tuple[str | int, ...], value: Any = None, *,
            drop: bool = False) -> dict[str, Any]:
    doc = copy.deepcopy(BASES[base])
    node: Any = doc
    for key in path[:-1]:
        node = node[key]
    if drop:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return doc


def _check_all(capsys: pytest.CaptureFixture[str], tmp_path: Path,
               rows: list[tuple[str, dict[str, Any] | str, str | None, str | None]]) -> None:
    """Replay every ``(label, case, field, needle)`` row; fail listing every row that was not
    refused cleanly."""
    bad = []
    for k, (label, content, field, needle) in enumerate(rows):
        case = tmp_path / f"case{k}.json"
        why = _refusal(*_replay(capsys, case, content), case, field, needle)
        if why is not None:
            bad.append(f"{label}: {why}")
    assert not bad, "\n".join(bad)


# --------------------------------------------------------------------------------------------
# the audit's findings, one table each
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("value", ["looping", ["looping"], [], 3, None, True],
                         ids=["string", "list", "empty-list", "number", "null", "bool"])
def test_expected_must_be_an_object(value: Any, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    """``"expected": "looping"`` was an AttributeError (exit 70)."""
    case = tmp_path / "case.json"
    why = _refusal(*_replay(capsys, case, _edited("fig7", ("expected",), value)), case,
                   "expected")
    assert why is None, why


@pytest.mark.parametrize("value", [["looping"], "loopy", "LOOPING", None, 3, {"kind": "looping"},
                                   "automaton"],
                         ids=["list", "unknown", "upper-case", "null", "number", "object",
                              "not-among-violations"])
@pytest.mark.parametrize("base", ["fig7", "cut"])
def test_expected_violation_must_be_a_kind_the_run_showed(
        base: str, value: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A corrupted expected violation was replayed as "does not reproduce" (exit 0): a broken
    regression case looked fixed. ``automaton`` is a kind, but not one of the case's
    ``expected.violations``."""
    case = tmp_path / "case.json"
    why = _refusal(*_replay(capsys, case, _edited(base, ("expected", "violation"), value)), case,
                   "expected.violation")
    assert why is None, why


SCALARS: dict[str, list[Any]] = {
    "version": [999, 0, 3, "2", True, 2.0, 1.5, None],
    "lag": [True, False, -1, 1.5, 0.0, "0", None, [0], MAX_CAMPAIGN_STEPS + 1],
    "modulation": ["yes", 1, 0, None, "false"],
    "window": [0, -700, 700.0, True, "700", None, MAX_CAMPAIGN_STEPS + 1],
    "max_cycles": [-1, 2.5, 4.0, True, "4", MAX_CAMPAIGN_STEPS + 1],
    "seed": [-1, 0.5, True, None, "0", 2**32],
    "index": [-1, 21.0, "21", True],
    "shrunk": ["yes", 1, None],
    "kind": ["tli-verify/campaign-evidence", None, 1],
    "start": [[-5.0], [-5.0, 4.5, 0.0], [True, 4.5], ["-5", 4.5], "-5,4.5", [], None],
}


# kind and start were already refused by name: each shares a row with a field that was not
GROUPS = [("kind", "version"), ("lag",), ("modulation",), ("window",), ("start", "max_cycles"),
          ("seed",), ("index",), ("shrunk",)]


@pytest.mark.parametrize("names", GROUPS, ids=["+".join(g) for g in GROUPS])
def test_a_bad_top_level_value_names_the_field(names: tuple[str, ...], tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """Booleans taken as integers (``"lag": true`` was lag 1), strings as booleans, floats as
    integers (``2.0`` was version 2), unknown versions, wrong-length starts: each is refused
    naming its field."""
    assert set(SCALARS) == {n for g in GROUPS for n in g}
    _check_all(capsys, tmp_path, [(f"{name}={v!r}", _edited("fig7", (name,), v), name, None)
                                  for name in names for v in SCALARS[name]])


def test_bad_perturbations_name_the_field(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """Negative, zero, float and huge steps, wrong-length or non-numeric displacements, unknown
    levels, a target on a free push (a level corrupted from task to free would silently replay
    another case), a task push without a region or into a region the task does not have
    (already refused naming the field: kept), unknown keys."""
    p0 = ("perturbations", 0)
    rows: list[tuple[str, dict[str, Any] | str, str | None, str | None]] = []
    for step in (-3, 0, 540.5, 540.0, "540", True, None, MAX_CAMPAIGN_STEPS + 1, 10**18):
        rows.append((f"step={step!r}", _edited("fig7", (*p0, "step"), step),
                     "perturbations[0].step", None))
    for disp in ([0.0], [0.0, 0.0, 0.0], [True, 0.0], ["0", 0.0], "0,0", [], None, [0.0] * 33):
        rows.append((f"displacement={disp!r}", _edited("fig7", (*p0, "displacement"), disp),
                     "perturbations[0].displacement", None))
    for level in ("cosmic", "", None, 1, "TASK"):
        rows.append((f"level={level!r}", _edited("fig7", (*p0, "level"), level),
                     "perturbations[0].level", None))
    rows += [
        ("free push with a target", _edited("cut", (*p0, "target"), "pink"),
         "perturbations[0].target", None),
        ("motion push with a target", _edited("fig7", (*p0, "level"), "motion"),
         "perturbations[0].target", None),
        ("task push with a null target", _edited("fig7", (*p0, "target"), None),
         "perturbations[0].target", None),
        ("task push into an unknown region", _edited("fig7", (*p0, "target"), "mauve"),
         "perturbations[0].target", "unknown region 'mauve' of task 'scoop'"),
        ("task push into an unknown region (version 1)",
         _edited("fig7-v1", (*p0, "target"), "mauve"), "perturbations[0].target",
         "unknown region 'mauve' of task 'scoop'"),
        ("task push into a bad name", _edited("fig7", (*p0, "target"), "../pink"),
         "perturbations[0].target", None),
        ("unknown key", _edited("fig7", (*p0, "magnitude"), 3.0), "perturbations[0]", None),
        ("steps not increasing", _edited("cut", ("perturbations", 1, "step"), 181),
         "perturbations[1].step", None),
        ("perturbations an object", _edited("fig7", ("perturbations",), {}), "perturbations",
         None),
        ("too many", _edited("cut", ("perturbations",), [
            {"step": k + 1, "displacement": [0.0, 0.0], "level": "free", "target": None}
            for k in range(MAX_PUSHES + 1)]), "perturbations", "MAX_PUSHES"),
    ]
    _check_all(capsys, tmp_path, rows)


def test_bad_files_and_versions_name_the_field(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """Version 1 names its task by ``world``, version 2 by ``files.task`` (one way, exactly);
    files must be objects with a path and a SHA-256; unknown keys anywhere are refused."""
    rows: list[tuple[str, dict[str, Any] | str, str | None, str | None]] = [
        ("version 2 with a world", _edited("fig7", ("world",), "scoop"), "world", None),
        ("version 1 with files.task", _edited("fig7", ("version",), 1) | {"world": "scoop"},
         "files.task", None),
        ("version 1 without world", _edited("fig7-v1", ("world",), drop=True), None, "world"),
        ("version 1 world a path", _edited("fig7-v1", ("world",), "tasks/scoop.toml"), "world",
         None),
        ("version 1 unknown world", _edited("fig7-v1", ("world",), "nowhere"), "world",
         "unknown task"),
        ("version 2 without files.task", _edited("fig7", ("files", "task"), drop=True), "files",
         None),
        ("files.task path and entry point", _edited("fig7", ("files", "task", "entry_point"),
                                                    "scoop"), "files.task", None),
        ("files.task neither", _edited("fig7", ("files", "task", "path"), drop=True),
         "files.task", None),
        ("files.task unknown entry point", _edited(
            "fig7", ("files", "task"), {"entry_point": "nowhere", "sha256": "0" * 64}),
         "files.task.entry_point", "unknown task"),
        ("files.task missing", _edited("fig7", ("files", "task", "path"), "tasks/none.toml"),
         "files.task.path", "no such task file"),
        ("files.spec missing", _edited("fig7", ("files", "spec", "path"), "specs/none.toml"),
         "files.spec.path", "no such file"),
        ("files.spec empty path", _edited("fig7", ("files", "spec", "path"), ""),
         "files.spec.path", None),
        ("files.spec NUL in path", _edited("fig7", ("files", "spec", "path"), "specs/a\0b"),
         "files.spec.path", None),
        ("files.model a list", _edited("fig7", ("files", "model"), ["models/scoop.model.json"]),
         "files.model", None),
        ("files.certificate sha256 short", _edited("fig7", ("files", "certificate", "sha256"),
                                                   "6a63fb"), "files.certificate.sha256", None),
        ("files.spec without sha256", _edited("fig7", ("files", "spec", "sha256"), drop=True),
         "files.spec", None),
        ("files unknown key", _edited("fig7", ("files", "demos"), {"path": "x", "sha256": "0"}),
         "files", None),
        ("top-level unknown key", _edited("fig7", ("verdict",), "looping"), None, "verdict"),
        ("expected unknown key", _edited("fig7", ("expected", "reproduced"), True), "expected",
         None),
        ("expected.violations a string", _edited("fig7", ("expected", "violations"), "looping"),
         "expected.violations", None),
        ("expected.violations an unknown kind", _edited(
            "fig7", ("expected", "violations"), ["looping", "loopy"]), "expected.violations[1]",
         None),
        ("expected.messages a string", _edited("fig7", ("expected", "messages"), "x"),
         "expected.messages", None),
        ("expected.oracle_modes a list", _edited("fig7", ("expected", "oracle_modes"), ["a"]),
         "expected.oracle_modes", None),
        ("note a number", _edited("fig7", ("note",), 3), "note", None),
        ("a list", "[1, 2]", None, None),
        ("a string", '"case"', None, None),
        ("empty", "", None, None),
        ("not JSON", "{", None, None),
        ("a repeated key (lag 0, then lag 5)",
         json.dumps(BASES["fig7"]).replace('"lag": 0', '"lag": 0, "lag": 5'), None, "lag"),
        ("a repeated key in expected",
         json.dumps(BASES["cut"]).replace('"violation": "invariance"',
                                          '"violation": "invariance", "violation": "looping"'),
         None, "violation"),
        ("NaN in a displacement",
         json.dumps(BASES["fig7"]).replace('"displacement": [0.0, 0.0]',
                                           '"displacement": [NaN, 0.0]'), None, "NaN"),
        ("1e400 in a displacement",
         json.dumps(BASES["fig7"]).replace('"displacement": [0.0, 0.0]',
                                           '"displacement": [1e400, 0.0]'), None, "1e400"),
        ("Infinity as the seed", json.dumps(BASES["fig7"]).replace('"seed": 0',
                                                                   '"seed": Infinity'),
         None, "Infinity"),
    ]
    _check_all(capsys, tmp_path, rows)


def test_shape_is_checked_before_the_files(tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    """The schema comes first: a case that is malformed AND names a missing file is refused for
    the malformed field (the corruption), not for the file."""
    doc = _edited("fig7", ("files", "spec", "path"), "specs/none.toml")
    doc["lag"] = True
    case = tmp_path / "case.json"
    why = _refusal(*_replay(capsys, case, doc), case, "lag")
    assert why is None, why


@pytest.mark.parametrize("variant", ["world", "files.task.path"])
@pytest.mark.parametrize("start", [[1.0, 4.5], [-5.0, 4.5]], ids=["start-in-both", "start-out"])
def test_a_task_whose_sensors_are_not_the_specs_inputs(
        variant: str, start: list[float], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A case naming task cooking with the scoop spec and model: one line naming the case file
    and the task field, saying the task's sensors are not the spec's inputs (was "unknown
    sensor" or a spec-only message with no case file, or "outside the workspace")."""
    base = "fig7-v1" if variant == "world" else "fig7"
    doc = _edited(base, ("start",), start)
    doc["perturbations"] = [{"step": 200, "displacement": [1.0, 0.0], "level": "free",
                             "target": None}]
    if variant == "world":
        doc["world"] = "cooking"
    else:
        doc["files"]["task"]["path"] = "tasks/cooking.toml"
    case = tmp_path / "case.json"
    code, out, err = _replay(capsys, case, doc)
    why = _refusal(code, out, err, case, None, "are not the sensors of task 'cooking'")
    assert why is None, why
    assert variant in err, err


# --------------------------------------------------------------------------------------------
# the schema: real cases validate, and it agrees with the code
# --------------------------------------------------------------------------------------------

def _validate(doc: Any, where: str) -> None:
    validate_schema(doc, "case.schema.json", where=where, error=CampaignError)


def test_schema_enums_are_the_codes() -> None:
    """The schema's violation kinds and perturbation levels are the oracle's and the
    strategies' (a new kind must be added to the schema too)."""
    assert SCHEMA, "tli_verify/schemas/case.schema.json is missing"
    assert SCHEMA["$defs"]["kind"]["enum"] == KINDS
    assert tuple(SCHEMA["$defs"]["perturbation"]["properties"]["level"]["enum"]) == LEVELS
    assert SCHEMA["properties"]["version"]["enum"] == [1, 2]


@pytest.mark.parametrize("base", list(BASES))
def test_shipped_cases_validate(base: str) -> None:
    _validate(BASES[base], base)


@pytest.fixture(scope="module")
def found(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``tli verify --task scoop --no-modulation --examples 60 --seed 0``: a looping case."""
    from tli_verify.cli import main

    out = tmp_path_factory.mktemp("found")
    code = main(["verify", "--task", "scoop", "--no-modulation", "--examples", "60", "--seed",
                 "0", "--backend", "serial", "--json", "--out", str(out)])
    assert code == 1
    return out / "counterexample.json"


def test_a_found_counterexample_validates_and_replays(
        found: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    doc = json.loads(found.read_text())
    _validate(doc, str(found))
    assert doc["version"] == 2 and doc["expected"]["violation"] == "looping"
    code, out, err = run(capsys, "replay", str(found), "--json")
    assert code == 1 and json.loads(out)["reproduced"] is True, err
    # its version 1 form is still read (and reproduces)
    v1 = tmp_path / "v1.json"
    v1.write_text(json.dumps(_v1(doc)))
    code, out, err = run(capsys, "replay", str(v1), "--json")
    assert code == 1 and json.loads(out)["reproduced"] is True, err


# --------------------------------------------------------------------------------------------
# generated corruptions
# --------------------------------------------------------------------------------------------

LO, HI = -8.0, 8.0  # the scoop task's workspace box
JUNK = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                 st.floats(allow_nan=False, allow_infinity=False, width=32),
                 st.text(max_size=6), st.lists(st.integers(0, 3), max_size=3),
                 st.dictionaries(st.text(max_size=3), st.integers(0, 3), max_size=2))
NOT_INT = JUNK.filter(lambda v: type(v) is not int)
NOT_STR = JUNK.filter(lambda v: not isinstance(v, str))
NOT_LIST = JUNK.filter(lambda v: not isinstance(v, list))
NOT_DICT = JUNK.filter(lambda v: not isinstance(v, dict))
NOT_BOOL = JUNK.filter(lambda v: not isinstance(v, bool))
NOT_NUMBER = JUNK.filter(lambda v: isinstance(v, bool) or not isinstance(v, int | float))


def bad_int(lo: int, hi: int | None, *, nullable: bool = False) -> st.SearchStrategy[Any]:
    """Values an integer field in ``[lo, hi]`` (or null) must refuse: other types, floats
    (``4.0`` too), integers out of range."""
    out = NOT_INT.filter(lambda v: not (nullable and v is None)) \
        | st.integers(max_value=lo - 1) | st.sampled_from([float(lo), float(lo) + 0.5])
    return out if hi is None else out | st.integers(min_value=hi + 1)


def bad_vector(dim: int, *, workspace: bool) -> st.SearchStrategy[Any]:
    """Values a vector of ``dim`` finite numbers (in the workspace) must refuse."""
    out = NOT_LIST | st.lists(st.floats(-1.0, 1.0), max_size=40).filter(lambda v: len(v) != dim) \
        | st.tuples(NOT_NUMBER, st.floats(-1.0, 1.0)).map(list)
    if workspace:  # a coordinate outside the box
        outside = st.floats(HI + 1e-6, 1e300) | st.floats(-1e300, LO - 1e-6)
        out = out | st.tuples(outside, st.floats(LO, HI)).map(list)
    return out


def _bad_kinds(doc: dict[str, Any]) -> st.SearchStrategy[Any]:
    want = doc["expected"]["violation"]
    return NOT_LIST | st.just([]) | st.lists(st.text(max_size=5).filter(
        lambda s: s not in KINDS), min_size=1, max_size=3).map(lambda v: [want, *v]) \
        | st.lists(st.sampled_from([k for k in KINDS if k != want]), min_size=1,
                   max_size=4, unique=True) | st.just([want, want])


def _fields(doc: dict[str, Any]) -> list[tuple[tuple[str | int, ...], st.SearchStrategy[Any]]]:
    """Every field of ``doc`` with the values it must refuse."""
    out: list[tuple[tuple[str | int, ...], st.SearchStrategy[Any]]] = [
        (("kind",), JUNK.filter(lambda v: v != "tli-verify/bisimulation-case")),
        (("version",), JUNK.filter(lambda v: not (type(v) is int and v in (1, 2)))
         | st.sampled_from([1.0, 2.0])),
        (("lag",), bad_int(0, MAX_CAMPAIGN_STEPS)),
        (("window",), bad_int(1, MAX_CAMPAIGN_STEPS)),
        (("max_cycles",), bad_int(0, MAX_CAMPAIGN_STEPS, nullable=True)),
        (("seed",), bad_int(0, 2**32 - 1)),
        (("index",), bad_int(0, None, nullable=True)),
        (("modulation",), NOT_BOOL), (("shrunk",), NOT_BOOL),
        (("start",), bad_vector(2, workspace=True)),
        (("start", 0), NOT_NUMBER | st.floats(HI + 1e-6, 1e300)),
        (("perturbations",), NOT_LIST),
        (("expected",), NOT_DICT),
        (("expected", "violation"), JUNK.filter(
            lambda v: v not in doc["expected"]["violations"])
         | st.sampled_from([k for k in KINDS if k not in doc["expected"]["violations"]])),
        (("expected", "violations"), _bad_kinds(doc)),
        (("expected", "messages"), NOT_LIST | st.lists(NOT_STR, min_size=1, max_size=2)
         | st.lists(st.just("m"), min_size=6, max_size=8)),
        (("expected", "oracle_modes"), NOT_STR | st.just("ab" * 101)),
        (("files",), NOT_DICT),
    ]
    for name in ("spec", "model", "certificate"):
        out += [(("files", name), NOT_DICT),
                (("files", name, "path"), NOT_STR | st.sampled_from(
                    ["", "specs/none.toml", "no\nline", "/nonexistent/x.json"])),
                (("files", name, "sha256"), NOT_STR | st.text(max_size=63))]
    if doc["version"] == 1:
        out.append((("world",), NOT_STR | st.sampled_from(["", "nowhere", "cooking", "a/b",
                                                           "tasks/scoop.toml", "x" * 101])))
    else:
        out += [(("files", "task"), NOT_DICT),
                (("files", "task", "path"), NOT_STR | st.sampled_from(
                    ["", "tasks/none.toml", "tasks/cooking.toml"])),
                (("files", "task", "sha256"), NOT_STR | st.text(max_size=63))]
    for i, push in enumerate(doc["perturbations"]):
        p = ("perturbations", i)
        out += [(p, NOT_DICT), ((*p, "step"), bad_int(1, MAX_CAMPAIGN_STEPS)),
                ((*p, "displacement"), bad_vector(2, workspace=False)),
                ((*p, "level"), JUNK.filter(lambda v: v not in LEVELS))]
        if push["level"] == "task":
            out.append(((*p, "target"), NOT_STR | st.sampled_from(
                ["mauve", "", "dark", "Pink", "pink pink"])))
        else:
            out.append(((*p, "target"), JUNK.filter(lambda v: v is not None)))
    return out


def _required(doc: dict[str, Any]) -> list[tuple[str | int, ...]]:
    """Every key ``doc`` cannot do without."""
    out: list[tuple[str | int, ...]] = [
        (k,) for k in ("kind", "version", "lag", "modulation", "max_cycles", "window", "files",
                       "seed", "index", "shrunk", "start", "perturbations", "expected")]
    out += [("expected", k) for k in ("violation", "violations", "messages", "oracle_modes")]
    for name in ("spec", "model", "certificate"):
        out += [("files", name), ("files", name, "path"), ("files", name, "sha256")]
    out += [("world",)] if doc["version"] == 1 else [
        ("files", "task"), ("files", "task", "path"), ("files", "task", "sha256")]
    for i, push in enumerate(doc["perturbations"]):
        out += [("perturbations", i, "step"), ("perturbations", i, "displacement")]
        if push["level"] == "task":  # without its level it is a free push with a target
            out += [("perturbations", i, "level"), ("perturbations", i, "target")]
    return out


def _objects(doc: Any, path: tuple[str | int, ...] = ()) -> list[tuple[str | int, ...]]:
    """The paths of every object in ``doc``."""
    if isinstance(doc, dict):
        return [path, *(q for k, v in doc.items() for q in _objects(v, (*path, k)))]
    if isinstance(doc, list):
        return [q for i, v in enumerate(doc) for q in _objects(v, (*path, i))]
    return []


def _leaves(doc: Any, path: tuple[str | int, ...] = ()) -> list[tuple[str | int, ...]]:
    if isinstance(doc, dict):
        return [q for k, v in doc.items() for q in _leaves(v, (*path, k))]
    if isinstance(doc, list) and doc:
        return [q for i, v in enumerate(doc) for q in _leaves(v, (*path, i))]
    return [path]


def _at(doc: Any, path: tuple[str | int, ...]) -> Any:
    for key in path:
        doc = doc[key]
    return doc


def _dumps_repeating(doc: Any, path: tuple[str | int, ...], key: str, value: Any) -> str:
    """JSON text of ``doc`` with ``key`` written a second time (as ``value``) in the object at
    ``path``."""
    def dump(node: Any, here: tuple[str | int, ...]) -> str:
        if isinstance(node, dict):
            items = [f"{json.dumps(k)}: {dump(v, (*here, k))}" for k, v in node.items()]
            if here == path:
                items.append(f"{json.dumps(key)}: {json.dumps(value)}")
            return "{" + ", ".join(items) + "}"
        if isinstance(node, list):
            return "[" + ", ".join(dump(v, (*here, i)) for i, v in enumerate(node)) + "]"
        return json.dumps(node)
    return dump(doc, ())


@st.composite
def hostile_cases(draw: st.DrawFn) -> tuple[str, str]:
    """``(what was done, the JSON text)`` of a corrupted case."""
    base = draw(st.sampled_from(sorted(BASES)))
    doc = copy.deepcopy(BASES[base])
    how = draw(st.sampled_from(["drop", "value", "value", "value", "unknown key", "non-finite",
                                "repeated key"]))
    if how == "drop":
        path = draw(st.sampled_from(_required(doc)))
        del _at(doc, path[:-1])[path[-1]]
        return f"{base}: drop {path}", json.dumps(doc)
    if how == "value":
        path, values = draw(st.sampled_from(_fields(doc)))
        value = draw(values)
        _at(doc, path[:-1])[path[-1]] = value
        return f"{base}: {path} = {value!r}", json.dumps(doc)
    if how == "unknown key":
        path = draw(st.sampled_from(_objects(doc)))
        key = "x" + draw(st.text(max_size=4))
        _at(doc, path)[key] = draw(JUNK)
        return f"{base}: unknown key {key!r} in {path}", json.dumps(doc)
    if how == "non-finite":
        path = draw(st.sampled_from(_leaves(doc)))
        raw = draw(st.sampled_from(["NaN", "Infinity", "-Infinity", "1e400", "-1e999"]))
        _at(doc, path[:-1])[path[-1]] = "@@RAW@@"
        return f"{base}: {path} = {raw}", json.dumps(doc).replace('"@@RAW@@"', raw)
    path = draw(st.sampled_from(_objects(doc)))
    key = draw(st.sampled_from(sorted(_at(doc, path))))
    value = draw(JUNK | st.just(_at(doc, path)[key]))
    return f"{base}: {key!r} repeated in {path}", _dumps_repeating(doc, path, key, value)


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(hostile=hostile_cases())
def test_every_generated_corruption_is_refused(
        hostile: tuple[str, str], tmp_path_factory: pytest.TempPathFactory,
        capsys: pytest.CaptureFixture[str]) -> None:
    what, text = hostile
    case = tmp_path_factory.getbasetemp() / "hostile-case.json"
    why = _refusal(*_replay(capsys, case, text), case)
    assert why is None, f"{what}: {why}"
