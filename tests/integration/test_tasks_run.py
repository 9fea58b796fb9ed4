"""``tli run --task T`` on every bundled task's certified model.

Each task: one seeded perturbed episode reaches its goal with LTL-DS (through the CLI, on
the shipped spec, model and certificate). Cooking: the DS learned once are shared by the four
models of cooking-cb/bc/c/cc bit for bit, each certified for its own spec; cooking-c's
green -> white DS (the detour demonstration) runs after a push into the broccoli. Color
tracing: without the recovery demonstrations the dark modes are refused, naming the mode.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tli_verify.cli import main

COOKING = ("cooking-cb", "cooking-bc", "cooking-c", "cooking-cc")


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, dict]:
    code = main(["run", *argv, "--json"])
    out = capsys.readouterr().out
    return code, json.loads(out)


@pytest.mark.parametrize(("task", "spec", "seed", "first", "goal"), [
    ("scoop", None, 2, "a", "d"),
    ("cooking", None, 1, "w1", "d2"),
    ("cooking", "cooking-bc", 0, "w1", "d2"),
    ("cooking", "cooking-cc", 1, "w", "d"),
    ("color-tracing", None, 1, "y", "rd"),
    ("color-tracing", "color-tracing-c", 3, "y", "rd"),
    ("inspection", None, 3, "a", "b"),
])
def test_a_seeded_perturbed_episode_reaches_the_goal(
        repo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], task: str,
        spec: str | None, seed: int, first: str, goal: str) -> None:
    argv = ["--task", task, "--seed", str(seed), "--random-start", "--perturb", "random:2",
            "--out", str(tmp_path)]
    if spec is not None:
        argv += ["--spec", str(repo / "specs" / f"{spec}.toml")]
    code, rec = _run(argv, capsys)
    assert code == 0 and rec["success"] is True
    assert len(rec["perturbations"]) == 2
    assert any(e["event"] == "Perturbation" for e in rec["events"])
    trace = [m for m, _ in rec["mode_trace"]]
    assert trace[0] == first and trace[-1] == goal
    assert (tmp_path / "run.png").stat().st_size > 0


def test_inspection_is_done_at_the_release_not_on_entering_the_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, rec = _run(["--task", "inspection", "--seed", "2", "--random-start",
                      "--out", str(tmp_path)], capsys)
    assert code == 0
    from tli_verify.tasks.registry import find_task

    end = np.array(rec["final_state"])
    # the release station (8 <= x1 <= 9 on the line), not the entry of the track
    assert find_task("inspection").true_mode(end[None])[0] == "release"
    code, rec = _run(["--task", "inspection", "--seed", "2", "--random-start", "--steps", "60",
                      "--out", str(tmp_path)], capsys)
    assert code == 1 and rec["success"] is False  # on the line, not yet released


def test_cooking_c_runs_the_detour_ds_after_a_push_into_the_broccoli(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], repo: Path) -> None:
    # from white, pushed into green at step 20: cooking-c's automaton runs g -> w (the DS
    # learned from the detour demonstration only), then chicken, then the pot
    code, rec = _run(["--task", "cooking", "--spec", str(repo / "specs" / "cooking-c.toml"),
                      "--start", "5,2", "--perturb", "20:3.5,4", "--out", str(tmp_path)],
                     capsys)
    assert code == 0
    assert [m for m, _ in rec["mode_trace"]] == ["w", "g", "w", "y", "d"]


def test_a_model_given_without_spec_runs_to_the_goal_of_the_spec_it_names(
        repo: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # cooking-cc repeats forever (no sink mode): its spec names the goal d; --model alone
    # must pick that goal through the spec the model names, not the task's default spec
    code, rec = _run(["--task", "cooking", "--model",
                      str(repo / "models" / "cooking-cc.model.json"), "--certificate",
                      str(repo / "certificates" / "cooking-cc.cert.json"), "--seed", "1",
                      "--random-start", "--out", str(tmp_path)], capsys)
    assert code == 0 and [m for m, _ in rec["mode_trace"]] == ["w", "y", "d"]


def test_no_replan_runs_a_model_with_per_transition_ds_only(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # cooking-cb's w1 has only 'w1->y': the open-loop sequence follows the automaton's plan
    # (it used to stop at w1 and exit 2, "no DS for 'w1'")
    code, rec = _run(["--task", "cooking", "--seed", "3", "--random-start", "--perturb", "random:2",
                      "--no-replan", "--out", str(tmp_path)], capsys)
    assert code in (0, 1) and rec["variant"] == "no-replan"
    assert [m for m, _ in rec["mode_trace"]][:2] == ["w1", "y"]


def _ds_arrays(entry: dict) -> str:
    """The DS of a model entry as canonical text (everything but its mode names)."""
    return json.dumps({k: v for k, v in entry.items() if k not in ("mode", "next_mode")},
                      sort_keys=True)


def test_cooking_ds_are_shared_bit_for_bit_and_each_model_is_certified_for_its_spec(
        repo: Path) -> None:
    from tli_verify.certification.certificate import check_certificate
    from tli_verify.model.serialize import load_model

    by_learned: dict[str, set[str]] = {}
    users: dict[str, set[str]] = {}
    for name in COOKING:
        path = repo / "models" / f"{name}.model.json"
        doc = json.loads(path.read_text())
        learned_keys = doc["source"]["learned_keys"]
        assert set(learned_keys) == set(doc["modes"])
        for key, learned in learned_keys.items():
            by_learned.setdefault(learned, set()).add(_ds_arrays(doc["modes"][key]))
            users.setdefault(learned, set()).add(name)
        model = load_model(path)
        assert model.spec_path is not None and model.spec_path.name == f"{name}.toml"
        check = check_certificate(repo / "certificates" / f"{name}.cert.json")
        assert check.ok, check
        cert = json.loads((repo / "certificates" / f"{name}.cert.json").read_text())
        assert cert["spec"]["path"].endswith(f"specs/{name}.toml")
        assert cert["control_period"]["dt"] == "1/100"
    # one learned DS -> one set of numbers, wherever it is bound
    assert all(len(texts) == 1 for texts in by_learned.values()), by_learned.keys()
    # and the DS are reused: the chicken DS and the white -> chicken DS serve all four specs
    assert users["ch & !br & !pot"] == set(COOKING)
    assert users["!ch & !br & !pot->ch & !br & !pot"] == set(COOKING)
    # the four models hold seven learned DS in all (one tli learn), not one learn per spec
    assert len(by_learned) == 7


def test_rebinding_refuses_an_undemonstrated_mode_naming_it(repo: Path, tmp_path: Path) -> None:
    from types import MappingProxyType

    from tli_verify.errors import DemoError
    from tli_verify.logic.spec import load_spec
    from tli_verify.model.serialize import load_model
    from tli_verify.model.types import Model, ModeModel
    from tli_verify.rebind import rebind_model

    # the tile DS only, named by their readings as a spec-free learn names them: what the
    # paper's single tile demonstration gives (no recovery data: paper Asm. 3)
    spec_path = repo / "specs" / "color-tracing-a.toml"
    labels = dict(load_spec(spec_path).modes or {})
    bound = load_model(repo / "models" / "color-tracing-a.model.json")
    tiles = {}
    for mm in bound.modes.values():
        if mm.mode.startswith("d"):
            continue
        name = labels[mm.mode]
        tiles[name] = ModeModel(key=name, mode=name, next_mode=None, ds=mm.ds, fit=mm.fit)
    spec_free = Model(state_names=bound.state_names, modes=MappingProxyType(tiles),
                      spec=None, path=str(tmp_path / "tiles.json"))
    with pytest.raises(DemoError, match=r"mode 'd1' .*no learned DS.*Asm\. 3"):
        rebind_model(spec_free, spec_path, tmp_path / "a.model.json")
    # with the recovery DS (dark -> yellow) it binds, every tile and d1 covered
    dark = bound.modes["d1->y"]
    dark_name, y_name = labels["d1"], labels["y"]
    tiles[f"{dark_name}->{y_name}"] = ModeModel(key=f"{dark_name}->{y_name}", mode=dark_name,
                                                next_mode=y_name, ds=dark.ds, fit=dark.fit)
    spec_free = Model(state_names=bound.state_names, modes=MappingProxyType(tiles),
                      spec=None, path=str(tmp_path / "tiles.json"))
    again = rebind_model(spec_free, spec_path, tmp_path / "a.model.json")
    assert set(again.modes) == set(bound.modes)
    assert again.modes["d1->y"].ds is dark.ds  # the same DS object: nothing relearned
