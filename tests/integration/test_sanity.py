"""Spec sanity: well-separation, unrealizable cores, vacuity hints."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.support.explicit_games import ExplicitGame
from tli_verify.cli import main
from tli_verify.logic.check import check_spec, check_spec_file
from tli_verify.logic.generate import RandomSpecConfig, random_spec
from tli_verify.logic.gr1 import build_game
from tli_verify.logic.sanity import _realizable, _with, unrealizable_core, well_separation
from tli_verify.logic.spec import load_spec, parse_spec


def test_well_separation_matches_explicit_construction() -> None:
    """Verdicts agree with an explicit-state fixpoint on 120 random specs, both kinds occur."""
    configs = [
        RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_safety=2, n_env_live=1),
        RandomSpecConfig(n_inputs=2, n_outputs=3, n_env_safety=3, n_env_live=2, depth=1),
        RandomSpecConfig(n_inputs=3, n_outputs=2, n_env_safety=1, n_env_live=1),
    ]
    verdicts = []
    for k, config in enumerate(configs):
        for seed in range(40):
            spec = random_spec(config, 5000 + 100 * k + seed)
            ours = well_separation(build_game(spec)).well_separated
            assert ours == ExplicitGame(spec).well_separated(), spec.path
            verdicts.append(ours)
    assert len(verdicts) >= 100
    assert 0.1 < sum(verdicts) / len(verdicts) < 0.95


def test_paper_literal_scoop_is_realizable_but_not_well_separated(specs_dir: Path) -> None:
    result = check_spec_file(specs_dir / "scoop-paper-literal.toml")
    assert result.realizable
    assert not result.well_separated
    assert result.well_separation.kind == "safety"
    assert any("assume.safety[0]" in f for f in result.well_separation.formulas)
    # The witness: the system switches mode while the sensors stay put.
    witness = result.well_separation.witness
    assert witness[-1].inputs == witness[0].inputs
    assert witness[-1].outputs != witness[0].outputs
    assert result.as_expected
    assert any("not well-separated" in w for w in result.warnings)


def test_every_other_shipped_spec_is_well_separated(specs_dir: Path) -> None:
    for path in sorted(specs_dir.glob("*.toml")):
        if path.name == "scoop-paper-literal.toml":
            continue
        result = check_spec_file(path)
        assert result.well_separated, path
        assert result.as_expected, path


def _check_core(spec: object) -> None:
    core = unrealizable_core(spec)  # type: ignore[arg-type]
    kept = list(core.formulas)
    assert not _realizable(_with(spec, guarantee=kept))  # type: ignore[arg-type]
    for k in range(len(kept)):
        assert _realizable(_with(spec, guarantee=kept[:k] + kept[k + 1:]))  # type: ignore[arg-type]


def test_core_of_shipped_unrealizable_spec(specs_dir: Path) -> None:
    spec = load_spec(specs_dir / "scoop-unrealizable.toml")
    _check_core(spec)
    texts = [f.text for f in unrealizable_core(spec).formulas]
    assert "GF d" in texts


def test_cores_of_random_unrealizable_specs() -> None:
    checked = 0
    for seed in range(60):
        spec = random_spec(RandomSpecConfig(n_sys_safety=4, n_sys_live=2), 9000 + seed)
        if check_spec(spec).realizable:
            continue
        _check_core(spec)
        checked += 1
    assert checked >= 20


def test_core_rejects_realizable_spec(specs_dir: Path) -> None:
    with pytest.raises(ValueError, match="realizable"):
        unrealizable_core(load_spec(specs_dir / "scoop.toml"))


def test_hints(specs_dir: Path) -> None:
    result = check_spec_file(specs_dir / "scoop.toml", hints=True)
    assert result.hints
    for hint in result.hints:  # each hinted assumption really is removable
        others = [f for f in result.spec.assume.all() if f is not hint.formula]
        assert _realizable(_with(result.spec, assume=others))
    bad = check_spec_file(specs_dir / "scoop-unrealizable.toml", core=True, hints=True)
    assert bad.core is not None
    core_ids = {id(f) for f in bad.core.formulas}
    assert all(id(h.formula) not in core_ids for h in bad.hints)


def test_cli_strict_core_json(specs_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    literal = str(specs_dir / "scoop-paper-literal.toml")
    assert main(["spec", "check", literal]) == 0
    assert "NOT well-separated" in capsys.readouterr().out
    assert main(["spec", "check", "--strict", literal]) == 1
    capsys.readouterr()
    assert main(["spec", "check", "--json", "--core", str(specs_dir / "scoop-unrealizable.toml"),
                 literal]) == 1
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert records[0]["core"] and all("line" in f for f in records[0]["core"])
    assert records[1]["well_separated"] is False
    assert records[1]["well_separation"]["kind"] == "safety"
    assert main(["spec", "check", "--core", str(specs_dir / "scoop-unrealizable.toml")]) == 1
    out = capsys.readouterr().out
    assert "unrealizable core" in out and "scoop-unrealizable.toml:27" in out


WS_TIME_ZERO = ('inputs = ["r"]\noutputs = ["a"]\n[assume]\nsafety = ["G(!r)"]\n'
                '[guarantee]\nliveness = ["GF a"]\n')


def test_assumption_safety_applies_at_time_zero(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """``G(!r)`` with no ``init`` forbids starting in ``r``: that is the
    environment's own violation, not one the system forces, so the spec is well-separated."""
    path = tmp_path / "ws.toml"
    path.write_text(WS_TIME_ZERO)
    result = check_spec_file(path)
    assert result.realizable and result.well_separated
    assert ExplicitGame(result.spec).well_separated()
    assert main(["spec", "check", "--strict", str(path)]) == 0
    assert "NOT well-separated" not in capsys.readouterr().out
    # The gate re-checks the spec and does not block it (other gate items may still block
    # a directory that holds no model).
    (tmp_path / "specs").mkdir()
    (tmp_path / "specs" / "ws.toml").write_text(WS_TIME_ZERO)
    main(["gate", str(tmp_path)])
    out = capsys.readouterr().out
    assert "specs/ws.toml" in out and "BLOCK spec" not in out


def test_unsatisfiable_safety_assumptions_are_an_initial_failure() -> None:
    """``G(r)`` and ``G(!r)``: no reading lets the assumptions hold at time 0."""
    s = parse_spec('inputs = ["r"]\noutputs = ["a"]\n[assume]\n'
                   'safety = ["G(r -> X r)", "G(r)", "G(!r)"]\n', path="u.toml")
    result = check_spec(s)
    assert result.realizable and not result.well_separated
    assert result.well_separation.kind == "initial"
    # the culprits: a minimal set, naming the two contradictory formulas only
    assert [f.split(": ", 1)[1] for f in result.well_separation.formulas] == ["G(r)", "G(!r)"]
    assert any("vacuously" in w for w in result.warnings)
    assert not ExplicitGame(s).well_separated()


def test_well_separation_with_state_assumptions_matches_explicit() -> None:
    """X-free assumptions G(p) over inputs and outputs: our verdicts agree with the explicit
    construction (which applies them at time 0 independently), both verdicts occur."""
    config = RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_safety=3, n_env_live=1,
                              env_state_safety=0.5)
    verdicts = []
    for seed in range(50):
        spec = random_spec(config, 60_000 + seed)
        ours = well_separation(build_game(spec)).well_separated
        assert ours == ExplicitGame(spec).well_separated(), spec.path
        verdicts.append(ours)
    assert 0.1 < sum(verdicts) / len(verdicts) < 0.95
