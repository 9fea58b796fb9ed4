"""Issue 30: the hand-off between modes, established offline where the task declares its
regions, and shown where it is used: in closed loop, with the cuts and the P the runtime uses,
through the commands a user runs, on tasks the test writes (``tests/support/awkward.py``; no
shipped file has them).

* the 3-D ``relay`` task: box 1 is entered across faces its DS leaves through, and from
  starts behind the goal the free-space flow crosses the goal and box 2 on its way. With the
  offline step, a 500-run random-start campaign with the task's pushes finds no looping, no
  undecided run and no violation; the boxes' hand-offs are *proved*;
* a proved claim is re-decided by ``tli check-cert`` and the gate: a cut removed after the
  claim was made (and the model re-certified) is refused -- a forgery only the re-decision
  catches;
* the 4-D ``dock`` task (ellipsoid, rotated polytope, union, two latches, a goal that is a mode
  and a sensor) is slow to learn and runs in ``make test-all``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.awkward import write_project


def run(*argv: str, cwd: Path) -> tuple[int, str, str]:
    """``tli argv...`` as a user runs it (a new process in ``cwd``)."""
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, "-m", "tli_verify.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900, check=False)
    return proc.returncode, proc.stdout, proc.stderr


def _ok(*argv: str, cwd: Path, code: int = 0) -> str:
    rc, out, err = run(*argv, cwd=cwd)
    assert rc == code, f"tli {' '.join(argv)}: exit {rc}\n{out}\n{err}"
    return out


def _learned(root: Path, name: str, *extra: str) -> str:
    _ok("demos", f"tasks/{name}.toml", cwd=root)
    demos = sorted(str(p.relative_to(root)) for p in (root / "demos").glob("*.csv"))
    out = _ok("learn", *demos, "--spec", f"specs/{name}.toml", "-o",
              f"models/{name}.model.json", *extra, cwd=root)
    _ok("certify", f"models/{name}.model.json", cwd=root)
    return out


@pytest.fixture(scope="module")
def relay(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    root = write_project(tmp_path_factory.mktemp("relay"), "relay")
    return root, _learned(root, "relay")


def test_relay_hand_offs_are_proved_for_the_boxes(relay: tuple[Path, str]) -> None:
    root, out = relay
    assert "hand-off b: b -> c" in out and "hand-off c: c -> d" in out
    for line in out.splitlines():
        if line.startswith(("hand-off b:", "hand-off c:")):
            assert line.endswith("proved"), line
    model = json.loads((root / "models" / "relay.model.json").read_text())
    claims = {c["key"]: c for c in model["source"]["handoff"]["claims"]}
    assert claims["b"]["established"] == "proved" and claims["c"]["established"] == "proved"
    assert all(c["exits"] == 0 for c in claims.values())
    # the cuts are in the model the runtime modulates with: box 1's five facets that keep
    # its attractor inside (the sixth is the hand-off facet into box 2)
    assert len(model["modes"]["b"]["cuts"]) == 5


def test_relay_campaign_from_random_starts_has_no_loop_and_no_violation(
        relay: tuple[Path, str]) -> None:
    root, _ = relay
    _ok("verify", "--spec", "specs/relay.toml", "--examples", "500", "--random-starts",
        "--out", "out/on", "--no-shrink", cwd=root)
    rec = json.loads((root / "out" / "on" / "campaign.json").read_text())
    assert rec["runs"] == 500
    assert rec["violating_runs"] == 0 and rec["inconclusive"] == 0, rec["violations"]
    assert rec["task_satisfied"] == 500
    # no cut was learned online in the proved modes: the offline cuts hold
    by_mode = rec["cuts_by_mode"]
    assert "b" not in by_mode and "c" not in by_mode, by_mode
    md = (root / "out" / "on" / "campaign.md").read_text()
    assert "## Cuts per mode" in md and "| b | 5 | proved | 0 |" in md


def test_check_cert_and_the_gate_redecide_a_proved_claim(relay: tuple[Path, str],
                                                        tmp_path: Path) -> None:
    root, _ = relay
    out = _ok("check-cert", "certificates/relay.cert.json", cwd=root)
    assert "b: proved (re-decided" in out and "a: sampled (tested on" in out
    # forgery: drop one facet cut of box 1 after the claim was made, re-certify (the
    # certificate now covers the edited bytes: only the re-decision can tell)
    forged = tmp_path / "forged"
    forged.mkdir()
    for sub in ("tasks", "specs", "models"):
        (forged / sub).mkdir()
        for f in (root / sub).iterdir():
            (forged / sub / f.name).write_bytes(f.read_bytes())
    path = forged / "models" / "relay.model.json"
    doc = json.loads(path.read_text())
    doc["modes"]["b"]["cuts"] = doc["modes"]["b"]["cuts"][1:]
    path.write_text(json.dumps(doc))
    _ok("certify", "models/relay.model.json", cwd=forged)
    rc, out, err = run("check-cert", "certificates/relay.cert.json", cwd=forged)
    assert rc == 1 and "b: claimed proved, re-check fails" in out, (out, err)
    assert err.startswith("error:") and len(err.strip().splitlines()) == 1
    rc, out, err = run("gate", ".", cwd=forged)
    assert rc == 1 and "claimed proved, re-check fails" in out


def test_without_the_offline_step_nothing_is_claimed(tmp_path: Path) -> None:
    root = write_project(tmp_path, "relay")
    out = _learned(root, "relay", "--no-handoff")
    assert "hand-off" not in out
    model = json.loads((root / "models" / "relay.model.json").read_text())
    assert "handoff" not in (model.get("source") or {})
    assert all(not m.get("cuts") for m in model["modes"].values())
    out = _ok("check-cert", "certificates/relay.cert.json", cwd=root)
    assert "not established offline" in out


@pytest.mark.slow
def test_dock_4d_campaign_with_the_offline_step(tmp_path: Path) -> None:
    root = write_project(tmp_path, "dock")
    out = _learned(root, "dock")
    assert out.count("hand-off ") == 5
    _ok("verify", "--spec", "specs/dock.toml", "--examples", "500", "--random-starts",
        "--out", "out/on", "--no-shrink", cwd=root)
    rec = json.loads((root / "out" / "on" / "campaign.json").read_text())
    assert rec["runs"] == 500 and rec["violations"]["looping"] == 0, rec["violations"]


def test_a_loop_is_diagnosed_and_the_offline_step_removes_it(tmp_path: Path) -> None:
    """The 3-D template of ``tli init``, learned without the offline step, loops ``abab...``
    from a random start with no push (the zone is entered where its DS leaves); the campaign,
    ``tli replay`` and the case say so: the mode, the regions, where it entered, and the
    class. With the offline step the same campaign finds no loop."""
    _ok("init", "proj", "--name", "box", "--dim", "3", cwd=tmp_path)
    root = tmp_path / "proj"
    _ok("demos", "tasks/box.toml", cwd=root)
    demos = sorted(str(p.relative_to(root)) for p in (root / "demos").glob("*.csv"))
    campaign = ("verify", "--spec", "specs/box.toml", "--examples", "500", "--random-starts",
                "--max-pushes", "0", "--out")
    _ok("learn", *demos, "--spec", "specs/box.toml", "-o", "models/box.model.json",
        "--no-handoff", cwd=root)
    _ok("certify", "models/box.model.json", cwd=root)
    rc, out, err = run(*campaign, "out/off", cwd=root)
    rec = json.loads((root / "out" / "off" / "campaign.json").read_text())
    assert rc == 1 and rec["violations"]["looping"] >= 1, (out, err)
    md = (root / "out" / "off" / "campaign.md").read_text()
    assert "Diagnosis: mode b leaves into a" in md and "composition gap" in md
    assert "from region zone" in md and "into region free" in md
    rc, out, _ = run("replay", "out/off/counterexample.json", cwd=root)
    assert rc == 1 and "REPRODUCED" in out
    assert "Diagnosis: mode b leaves into a" in out and "where mode a's flow handed it off" in out
    # the workspace box is a bound: a run whose DS leaves it is flagged, not clipped
    corner = "--start=-0.9999,-0.6103,-0.2127"
    rc, out, err = run("run", "--spec", "specs/box.toml", corner, "--out", "out/r0", cwd=root)
    flag = json.loads((root / "out" / "r0" / "run.json").read_text()).get("beyond_workspace")
    assert flag is not None and flag["steps"] >= 1, (out, err)
    assert "left the workspace box at step" in err
    _ok("learn", *demos, "--spec", "specs/box.toml", "-o", "models/box.model.json", cwd=root)
    _ok("certify", "models/box.model.json", cwd=root)
    _ok(*campaign, "out/on", cwd=root)
    rec = json.loads((root / "out" / "on" / "campaign.json").read_text())
    assert rec["violating_runs"] == 0 and rec["cuts_added"] == 0, rec["violations"]
    assert rec["runs_beyond_workspace"] == 0
    _ok("run", "--spec", "specs/box.toml", corner, "--out", "out/r1", cwd=root)
    assert "beyond_workspace" not in json.loads((root / "out" / "r1" / "run.json").read_text())


def test_learn_refuses_demonstrations_of_another_dimension(tmp_path: Path) -> None:
    relay = write_project(tmp_path / "relay", "relay")
    dock = write_project(tmp_path / "dock", "dock")
    _ok("demos", "tasks/relay.toml", cwd=relay)
    rc, out, err = run("learn", str(relay / "demos" / "relay_1.csv"), "--spec",
                       "specs/dock.toml", "-o", "models/dock.model.json", cwd=dock)
    assert rc == 2 and out == ""
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1
    assert "relay_1.csv: 3 state column(s)" in err and "'dock'" in err and "4 states" in err
    assert not (dock / "models" / "dock.model.json").exists()


def test_the_gate_retests_a_sampled_claim_on_its_own_draw(relay: tuple[Path, str],
                                                         tmp_path: Path) -> None:
    """Forgery only the re-test catches: every cut removed, every claim rewritten as
    "sampled, 0 exits" (no proved claim left to re-decide), the model re-certified (its
    certificate now covers the forged bytes): the gate's own draw finds the exits."""
    root, _ = relay
    forged = tmp_path / "forged"
    for sub in ("tasks", "specs", "models"):
        (forged / sub).mkdir(parents=True)
        for f in (root / sub).iterdir():
            (forged / sub / f.name).write_bytes(f.read_bytes())
    path = forged / "models" / "relay.model.json"
    doc = json.loads(path.read_text())
    for m in doc["modes"].values():
        m["cuts"] = []
    for c in doc["source"]["handoff"]["claims"]:
        c.update(established="sampled", exits=0, rests=0, cuts=0, note="")
    path.write_text(json.dumps(doc))
    _ok("certify", "models/relay.model.json", cwd=forged)
    rc, out, _ = run("check-cert", "certificates/relay.cert.json", cwd=forged)
    assert rc == 0  # nothing proved to re-decide: check-cert reports the claims as tested
    rc, out, _ = run("gate", ".", cwd=forged)
    line = next(ln for ln in out.splitlines() if ": handoff: " in ln)
    assert line.startswith("BLOCK") and "the claim does not hold" in line, line


def test_the_python_api_learns_the_hand_off_too(tmp_path: Path) -> None:
    import tli_verify as tli

    root = write_project(tmp_path, "relay")
    task = tli.load_task(root / "tasks" / "relay.toml")
    model = tli.learn(task.demonstrate(seed=0), spec=root / "specs" / "relay.toml")
    claims = {c["key"]: c for c in model.source["handoff"]["claims"]}
    assert claims["b"]["established"] == "proved" and len(model.region_cuts("b")) == 5
    plain = tli.learn(task.demonstrate(seed=0), spec=root / "specs" / "relay.toml",
                      handoff=False)
    assert "handoff" not in (plain.source or {}) and not plain.region_cuts("b")


def test_task_check_finds_a_sensor_change_the_spec_rules_out(tmp_path: Path) -> None:
    """``tli task check --spec`` decides on the geometry every sensor change the task can
    produce under a push; the dock task's ``docked`` latch survives a push from home back
    into the dock, so a spec that allows only ``a -> b`` from mode ``a`` is a mismatch, named
    by its pair of regions (exit 1), and ``tli spec check`` warns of it."""
    root = write_project(tmp_path, "dock")
    out = _ok("task", "check", "tasks/dock.toml", "--spec", "specs/dock.toml", cwd=root)
    assert "ok    tasks/dock.toml: every sensor change" in out
    spec = root / "specs" / "dock.toml"
    text = spec.read_text()
    a_line = next(ln for ln in text.splitlines() if ln.startswith('  "G((!l & !k & !y & !h) ->'))
    spec.write_text(text.replace(a_line, '  "G((!l & !k & !y & !h) -> X((!l & !k & !y & !h) | '
                                         '(l & !k & !y & !h)))",'))
    rc, out, err = run("task", "check", "tasks/dock.toml", "--spec", "specs/dock.toml",
                       cwd=root)
    assert rc == 1 and err.startswith("error: specs/dock.toml: 2 sensor change(s)"), (out, err)
    assert "from region home to region dock with latches docked set" in out
    assert "{} -> {k}" in out
    out = _ok("spec", "check", "specs/dock.toml", cwd=root)
    assert "warning: task 'dock': a move or push from region home to region dock" in out
