"""Paper Fig. 7 on the bundled scoop model: without modulation the system loops a -> b -> a ...
until its step budget runs out; LTL-DS reaches d after the one cut its b -> a invariance
failure produces.

The documented case (docs/explanation/results.md, "Fig. 7"; ``tli experiment scoop``'s
``fig7`` field): the nominal start (-5, 4), pushed by (6.09, 6.01) before step 957, while
transporting the soup (mode c):
the soup is spilled (c -> a), a's DS brings the spoon back to the soup, and from where it
enters, b's (scooping) DS rises back out of the soup into white. Before the scooping
demonstrations (an earlier models/scoop.model.json) the unmodulated run reached d here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tli_verify.cli import main
from tli_verify.experiments.fig7 import (
    FIG7_MIN_ROUNDS,
    NOMINAL_START,
    b_to_a_failures,
    fig7_record,
    fig7_search,
    is_fig7_loop,
    is_fig7_rescue,
)
from tli_verify.experiments.fig7_plot import plot_fig7
from tli_verify.experiments.scoop_task import scoop_setup
from tli_verify.runtime.episodes import mode_string, run_variant
from tli_verify.runtime.events import CutAdded, InvarianceFailure
from tli_verify.runtime.loop import EpisodeResult

BUDGET = 3000
PUSH = {957: np.array([6.09, 6.01])}


@pytest.fixture(scope="module")
def episodes() -> dict[str, EpisodeResult]:
    setup = scoop_setup()
    return {v: run_variant(setup, v, NOMINAL_START, PUSH, steps=BUDGET)
            for v in ("no-modulation", "LTL-DS")}


def test_unmodulated_system_loops_until_the_budget(episodes: dict[str, EpisodeResult]) -> None:
    plain = episodes["no-modulation"]
    seq = mode_string(plain)
    assert not plain.success and plain.steps == BUDGET
    assert seq.startswith("abca")  # the nominal a -> b -> c, then the spill c -> a
    rounds = b_to_a_failures(plain)
    assert rounds >= FIG7_MIN_ROUNDS and seq.count("ab") >= FIG7_MIN_ROUNDS + 1
    assert seq.endswith("abababab") or seq.endswith("babababa")  # still looping at the end
    fails = [e for e in plain.events if isinstance(e, InvarianceFailure)]
    assert {(e.mode, e.to_mode) for e in fails} == {("b", "a")}
    # the loop sits at the soup's surface, left of pink: every failure state in white just
    # above yellow (x2 = -4), every last in-mode state in yellow
    outs = np.array([e.outside for e in fails])
    lasts = np.array([e.last_inside for e in fails])
    assert (outs[:, 1] > -4.0).all() and (outs[:, 1] < -3.8).all() and (outs[:, 0] < 2.0).all()
    assert (lasts[:, 1] <= -4.0).all()
    assert is_fig7_loop(plain, BUDGET)
    assert not is_fig7_rescue(plain)


def test_ltl_ds_reaches_d_after_the_one_cut_of_its_failure(
        episodes: dict[str, EpisodeResult]) -> None:
    ours = episodes["LTL-DS"]
    assert ours.success and ours.steps < BUDGET
    assert mode_string(ours) == "abcababcd"
    fails = [e for e in ours.events if isinstance(e, InvarianceFailure)]
    cuts = [e for e in ours.events if isinstance(e, CutAdded)]
    assert [(e.mode, e.to_mode) for e in fails] == [("b", "a")]
    assert len(cuts) == 1 and cuts[0].mode == "b" and cuts[0].step == fails[0].step
    assert ours.cuts_added == 1
    # the cut separates the failure state from the last in-mode state and keeps b's
    # attractor (in pink) inside
    cut = cuts[0].cut
    w, p = np.asarray(cut.normal), np.asarray(cut.point)
    assert w @ (fails[0].outside - p) > 0 >= w @ (fails[0].last_inside - p) - 1e-9
    assert w @ (ours.model.modes["b"].ds.attractor - p) < 0
    assert is_fig7_rescue(ours) and not is_fig7_loop(ours, BUDGET)


def test_nominal_run_neither_loops_nor_fails() -> None:
    nominal = run_variant(scoop_setup(), "no-modulation", NOMINAL_START, {}, steps=BUDGET)
    assert nominal.success and mode_string(nominal) == "abcd"
    assert b_to_a_failures(nominal) == 0 and not is_fig7_loop(nominal, BUDGET)
    assert not is_fig7_rescue(nominal)  # no failure, no cut: not Fig. 7's second row either


def test_search_finds_the_documented_case_and_draws_it(tmp_path: Path) -> None:
    search = fig7_search(0, 3, BUDGET)  # the third try of seed 0 is the documented case
    rec = fig7_record(search)
    json.dumps(rec)  # JSON-ready
    assert rec["found"] and rec["stage"] == "perturbed nominal run"
    assert rec["start"] == NOMINAL_START.tolist()
    assert rec["perturbations"] == [{"step": 957, "displacement": [6.09, 6.01]}]
    assert rec["replay"] == "tli run --task scoop --start=-5.0,4.0 --perturb 957:6.09,6.01"
    nm, ld = rec["no_modulation"], rec["ltl_ds"]
    assert nm["budget_exhausted"] and nm["steps"] == BUDGET and not nm["success"]
    assert nm["b_to_a_failures"] >= FIG7_MIN_ROUNDS and nm["ab_rounds"] >= FIG7_MIN_ROUNDS
    assert nm["mode_trace"][0] == ["a", 0] and nm["mode_sequence"].startswith("abcabab")
    assert ld["success"] and ld["cuts_added"] == 1 and ld["mode_sequence"] == "abcababcd"
    assert [e["event"] for e in ld["events"]] == ["InvarianceFailure", "CutAdded"]
    png = tmp_path / "fig7.png"
    plot_fig7(scoop_setup().task, search, png)
    assert png.stat().st_size > 10_000


def test_replay_from_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    args = ["run", "--task", "scoop", "--start=-5.0,4.0", "--perturb", "957:6.09,6.01",
            "--json"]
    code = main([*args, "--no-modulation", "--out", str(tmp_path / "plain")])
    plain = json.loads(capsys.readouterr().out)
    assert code == 1 and not plain["success"] and plain["steps"] == BUDGET
    assert sum(e["event"] == "InvarianceFailure" and e["mode"] == "b" and e["to_mode"] == "a"
               for e in plain["events"]) >= FIG7_MIN_ROUNDS
    code = main([*args, "--out", str(tmp_path / "ours")])
    ours = json.loads(capsys.readouterr().out)
    assert code == 0 and ours["success"] and ours["cuts_added"] == 1
    assert ours["mode_sequence"] == "abcababcd"
