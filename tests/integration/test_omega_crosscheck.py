"""Our GR(1) verdicts against an independent solver (omega) on 300+ random specs."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

from tests.support.omega_oracle import omega_realizable
from tli_verify.logic.check import check_spec
from tli_verify.logic.generate import RandomSpecConfig, chain_spec_text, random_spec
from tli_verify.logic.spec import load_spec, parse_spec


def _omega(spec: object) -> bool:
    with contextlib.redirect_stdout(io.StringIO()):  # omega prints its reasons on stdout
        return omega_realizable(spec)  # type: ignore[arg-type]


def test_random_specs_agree_with_omega() -> None:
    configs = [
        RandomSpecConfig(),
        RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_live=2, n_sys_live=1),
        RandomSpecConfig(n_inputs=4, n_outputs=3, n_sys_safety=2, depth=3),
    ]
    verdicts = []
    for k, config in enumerate(configs):
        for seed in range(110):
            spec = random_spec(config, 1000 * k + seed)
            ours = check_spec(spec).realizable
            assert ours == _omega(spec), spec.path
            verdicts.append(ours)
    assert len(verdicts) >= 300
    # The sample is informative: both verdicts occur often.
    assert 0.1 < sum(verdicts) / len(verdicts) < 0.9


def test_shipped_specs_agree_with_omega(specs_dir: Path) -> None:
    for path in sorted(specs_dir.glob("*.toml")):
        spec = load_spec(path)
        assert check_spec(spec).realizable == _omega(spec), path


def test_task_chains_agree_with_omega() -> None:
    for n_modes in range(2, 7):
        spec = parse_spec(chain_spec_text(n_modes))
        result = check_spec(spec)
        assert result.realizable
        assert result.well_separated
        assert _omega(spec)


def test_state_safety_at_time_zero_agrees_with_omega() -> None:
    """Random specs whose assumptions include X-free G(p) (over inputs and outputs): the
    time-0 reading on both sides agrees with omega given the same initial conditions."""
    config = RandomSpecConfig(n_inputs=2, n_outputs=2, n_env_safety=3, n_sys_safety=3,
                              n_env_live=1, n_sys_live=1, env_state_safety=0.5)
    verdicts = []
    for seed in range(60):  # 12 of these 60 verdicts differ if G(p) skips time 0
        spec = random_spec(config, 40_000 + seed)
        ours = check_spec(spec).realizable
        assert ours == _omega(spec), spec.path
        verdicts.append(ours)
    assert 0.1 < sum(verdicts) / len(verdicts) < 0.9
