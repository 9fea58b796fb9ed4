"""The C evaluator (``tli_verify/deploy/c``) against the Python runtime: parity on random states
and on whole perturbed closed-loop episodes with cuts learned online, on the bundled tasks and on
a task the test writes in 2-D to 7-D; its loader refuses tampered, truncated and oversized
artifacts; SHA-256; fixed cut storage.

Parity contract (docs/howto/deploy-to-robot.md): the automaton's states, modes, DS keys and
invariance failures are identical; the velocity of a DS without cuts is bit for bit the
runtime's (same products, same summation order, libm ``exp``); with cuts (eq. 7 and the corner
guard's projection, where numpy and the C loops sum in other orders) within
``REL = 1e-12`` relative (``|v_c - v_py|_inf <= REL max(1, |v_py|_inf)``).
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.support.cpolicy import (
    F_ASSUMPTION,
    F_DONE,
    F_FAILURE,
    F_HOLDING,
    CError,
    CPolicy,
    build,
    c_source_dir,
    compiler,
    library,
    mask,
    run_side_by_side,
    step_both,
)
from tests.support.ndtask import NDSensors, write_nd
from tli_verify.boundary.cuts import Cut
from tli_verify.deploy.export import build_artifact, write_artifact
from tli_verify.runtime.events import AssumptionViolationEvent, InvarianceFailure
from tli_verify.runtime.executive import LTLDSPolicy

REL = 1e-12
NO_SOURCES: dict[str, Any] = {k: None for k in ("spec", "model", "certificate", "task",
                                                 "evidence")}

pytestmark = pytest.mark.skipif(compiler() is None, reason="no system C compiler (cc/gcc)")


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """The evaluator built with the system compiler (-std=c99 -pedantic -Werror)."""
    return library(build(tmp_path_factory.mktemp("cbuild")))


@pytest.fixture(scope="module")
def nd_artifacts(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Any]:
    """The written task in 2-D to 7-D: its pieces and exported artifact (K = 3; 10 at 7-D)."""
    out = {}
    for n in (2, 3, 4, 5, 6, 7):
        root = tmp_path_factory.mktemp(f"nd{n}")
        nd = write_nd(root, n, K=10 if n == 7 else 3, seed=n)
        art = build_artifact(nd.setup, goal_modes=("d",), goal_inputs=(), sources=NO_SOURCES,
                             max_online_cuts=60)
        nd.exported = write_artifact(art, root / "nd.tli.json")
        out[n] = nd
    return out


def _check_trace(tr: Any) -> None:
    assert tr.modes_c == tr.modes_py
    assert tr.keys_c == tr.keys_py
    assert tr.failures_c == tr.failures_py
    for a, b, cut in zip(tr.v_py, tr.v_c, tr.cut_steps, strict=True):
        if not cut:
            assert np.array_equal(a, b), (a, b)  # bit for bit
        else:
            assert np.max(np.abs(a - b)) <= REL * max(1.0, float(np.max(np.abs(a))))


# ------------------------------------------------------------------------------- SHA-256
@pytest.mark.parametrize("size", [0, 1, 55, 56, 63, 64, 65, 119, 120, 1000, 4099])
def test_sha256_is_hashlib(lib: Any, size: int) -> None:
    import ctypes

    data = bytes(np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8))
    out = ctypes.create_string_buffer(32)
    lib.tli_sha256(data, len(data), out)
    assert out.raw == hashlib.sha256(data).digest()


# ------------------------------------------------------------------------------- random states
def test_ds_velocity_parity_on_random_states(lib: Any, nd_artifacts: dict[int, Any]) -> None:
    """Nominal f(x): bit for bit; with cuts (added alike to both sides): within REL."""
    rng = np.random.default_rng(7)
    checked_guard = 0
    for n, nd in nd_artifacts.items():
        c = CPolicy(lib, nd.exported.text_path)
        model = nd.model
        for di, key in enumerate(model.modes):
            mm = model.modes[key]
            X = mm.ds.attractor + rng.normal(scale=1.5, size=(200, n))
            for x in X:
                assert np.array_equal(c.ds_velocity(di, x, modulate=False), mm.ds.velocity(x))
            # three cuts keeping x* inside, the same on both sides
            for _ in range(3):
                w = rng.normal(size=n)
                w /= np.linalg.norm(w)
                p = mm.ds.attractor + rng.uniform(0.2, 1.0) * w
                model = model.add_cut(key, Cut(normal=w, point=p))
                c.add_cut(c.lib.tli_policy_ds_mode(c.handle, di), w, p)
            mm = model.modes[key]
            assert c.n_cuts(di) == len(mm.cuts) == 3
            for x in X:
                v_py = mm.velocity(x, dt=0.01)
                v_c = c.ds_velocity(di, x, modulate=True)
                assert np.max(np.abs(v_py - v_c)) <= REL * max(1.0, float(np.max(np.abs(v_py))))
                checked_guard += int(not np.allclose(mm.modulator.eq5(x[None], mm.ds.velocity(
                    x)[None])[0], v_py))
    assert checked_guard > 0  # the corner guard's projection was exercised


# ------------------------------------------------------------------------------- episodes
@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 7])
def test_closed_loop_parity_written_task(lib: Any, nd_artifacts: dict[int, Any], n: int) -> None:
    nd = nd_artifacts[n]
    rng = np.random.default_rng(100 + n)
    cuts = failures = 0
    for _ in range(3 if n == 7 else 6):
        pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01)
        c = CPolicy(lib, nd.exported.text_path)
        x0 = np.r_[rng.uniform(0.0, 1.0), rng.uniform(-0.3, 0.3, n - 1)]
        tr = run_side_by_side(pol, c, nd.exported.artifact, NDSensors(n), x0,
                              400 if n == 7 else 800, rng,
                              push_prob=0.01, push_scale=0.5)
        assert tr.refused == 0
        _check_trace(tr)
        cuts += tr.cuts_added
        failures += len(tr.failures_py)
    assert cuts > 0 and failures > 0  # cuts were learned online and run on both sides


def _bundled(project_root: Path, name: str, tmp: Path) -> tuple[Any, Any]:
    from tli_verify.loaded import load_project
    from tli_verify.runtime.setup import check_goal

    project = load_project(model=project_root / "models" / f"{name}.model.json")
    setup = project.setup
    goal = check_goal(setup.automaton, project.goal, where=name)
    art = build_artifact(setup, goal_modes=goal, goal_inputs=project.goal.sensors,
                         sources=NO_SOURCES, max_online_cuts=60)
    return setup, write_artifact(art, tmp / f"{name}.tli.json")


@pytest.mark.parametrize("name", ["scoop", "inspection", "cooking-c", "cooking-bc",
                                  "cooking-cb", "cooking-cc", "color-tracing-a",
                                  "color-tracing-b", "color-tracing-c"])
def test_closed_loop_parity_bundled_tasks(lib: Any, repo: Path, tmp_path: Path,
                                          name: str) -> None:
    from tli_verify.runtime.setup import make_policy
    from tli_verify.runtime.task_sensors import TaskSensors

    setup, ex = _bundled(repo, name, tmp_path)
    lo, hi = np.asarray(setup.task.lo), np.asarray(setup.task.hi)
    rng = np.random.default_rng(3)
    steps = 0
    for _ in range(4):
        pol = make_policy(setup, "LTL-DS")
        c = CPolicy(lib, ex.text_path)
        x0 = rng.uniform(lo, hi)
        span = float(np.max(hi - lo))
        tr = run_side_by_side(pol, c, ex.artifact, TaskSensors(setup.task), x0, 1500, rng,
                              push_prob=0.01, push_scale=0.1 * span)
        _check_trace(tr)
        steps += len(tr.v_py)
    assert steps > 100


# ------------------------------------------------------------------------------- loader refusals
def _rehash(body: str) -> bytes:
    return (body + f"sha256 {hashlib.sha256(body.encode()).hexdigest()}\n").encode()


def _body(nd: Any) -> str:
    text = nd.exported.text_path.read_text()
    return text[: text.rindex("sha256 ")]


def _refused(lib: Any, data: bytes) -> CError:
    with pytest.raises(CError) as info:
        CPolicy(lib, data=data)
    assert info.value.code != 0 and info.value.message
    return info.value


def test_loader_refuses_tampered_artifacts(lib: Any, nd_artifacts: dict[int, Any],
                                          tmp_path: Path) -> None:
    nd = nd_artifacts[3]
    good = nd.exported.text_path.read_bytes()
    assert CPolicy(lib, data=good).sha256 == nd.exported.content_sha256
    body = _body(nd)
    # one digit changed: hash mismatch
    i = body.index("attractor ") + len("attractor ")
    edited = body[:i] + ("9" if body[i] != "9" else "8") + body[i + 1:]
    err = _refused(lib, (edited + good.decode()[len(body):]).encode())
    assert err.code == 4 and "hash mismatch" in err.message
    # truncated anywhere
    for cut in (10, len(good) // 2, len(good) - 1):
        err = _refused(lib, good[:cut])
        assert err.code == 2 and "truncated" in err.message
    # a NaN (re-hashed: a buggy exporter, not an edit)
    nan = re.sub(r"(attractor )(\S+)", r"\1nan", body, count=1)
    err = _refused(lib, _rehash(nan))
    assert err.code == 6 and "not finite" in err.message
    # sizes: fewer components in the header than the data holds, more records than the file
    sizes = re.search(r"^sizes (.*)$", body, re.M)
    assert sizes is not None
    f = sizes.group(1).split()
    fewer = list(f)
    fewer[7] = str(int(f[7]) - 1)
    err = _refused(lib, _rehash(body.replace(sizes.group(0), "sizes " + " ".join(fewer))))
    assert err.code == 5 and "beyond the header" in err.message
    more = list(f)
    more[5] = "9000000"
    err = _refused(lib, _rehash(body.replace(sizes.group(0), "sizes " + " ".join(more))))
    assert err.code == 5 and "beyond the file" in err.message
    big = list(f)
    big[0] = "33"
    err = _refused(lib, _rehash(body.replace(sizes.group(0), "sizes " + " ".join(big))))
    assert err.code == 5 and "dim" in err.message
    # another schema version
    err = _refused(lib, _rehash(body.replace("tli-policy-text 2", "tli-policy-text 1", 1)))
    assert err.code == 3 and "schema version" in err.message
    # an edge to a state that does not exist
    bad = re.sub(r"^edge (\d+) (\d+)", r"edge \1 999", body, count=1, flags=re.M)
    err = _refused(lib, _rehash(bad))
    assert err.code == 5 and "edge to" in err.message
    # the file loader: a missing file is an I/O error
    with pytest.raises(CError) as info:
        CPolicy(lib, tmp_path / "missing.tli.txt")
    assert info.value.code == 1 and "cannot open" in info.value.message


def test_cut_storage_is_fixed_and_refuses_when_full(lib: Any, nd_artifacts: dict[int, Any],
                                                    tmp_path: Path) -> None:
    nd = nd_artifacts[2]
    art = build_artifact(nd.setup, goal_modes=("d",), goal_inputs=(), sources=NO_SOURCES,
                         max_online_cuts=2)
    ex = write_artifact(art, tmp_path / "two.tli.json")
    c = CPolicy(lib, ex.text_path)
    xs = np.asarray(nd.model.modes["a"].ds.attractor)
    w = np.array([1.0, 0.0])
    c.add_cut(0, w, xs + 0.5 * w)
    with pytest.raises(CError) as info:  # x* outside the plane
        c.add_cut(0, w, xs - 0.5 * w)
    assert info.value.code == 9 and "attractor" in info.value.message
    with pytest.raises(CError) as info:  # not a unit normal
        c.add_cut(0, 2 * w, xs + 0.5 * w)
    assert info.value.code == 9 and "unit" in info.value.message
    c.add_cut(0, -w, xs - 0.5 * w)
    assert c.n_cuts(0) == 2
    with pytest.raises(CError) as info:
        c.add_cut(0, np.array([0.0, 1.0]), xs + np.array([0.0, 0.5]))
    assert info.value.code == 8 and "full" in info.value.message
    assert c.n_cuts(0) == 2  # nothing changed


def test_decide_reports_the_failure_triple(lib: Any, nd_artifacts: dict[int, Any]) -> None:
    """A mode exit no perturbation caused, to a mode that is not planned progress: the C
    evaluator flags it with (x^0, x^{T_f-1}, x^{T_f}), as the runtime's InvarianceFailure."""
    nd = nd_artifacts[2]
    c = CPolicy(lib, nd.exported.text_path)
    inputs = nd.exported.artifact["automaton"]["inputs"]
    r = 1 << inputs.index("r")
    x0, x1, x2 = np.array([0.5, 0.0]), np.array([1.2, 0.0]), np.array([1.3, 0.0])
    c.reset(x0, 0)
    assert c.decide(x1, r).flags & F_FAILURE == 0  # a -> b: planned
    info = c.decide(x2, 0)  # b -> a unperturbed: an invariance failure of b
    assert info.flags & F_FAILURE
    assert list(info.entry)[:2] == list(x1) and list(info.last_inside)[:2] == list(x1)
    assert list(info.outside)[:2] == list(x2)
    c.decide(x1, r)
    info = c.decide(x2, 0, True)  # the same exit after a push: no failure
    assert info.flags & F_FAILURE == 0


def test_no_allocation_after_load() -> None:
    """Only the loader allocates: no malloc/calloc/realloc in any function after it."""
    src = (c_source_dir() / "tli_policy.c").read_text()
    funcs = re.split(r"\n(?=(?:static )?[a-z_ ]+\*? ?\**[a-z_0-9]+\([^;]*\)\s*\{)", src)
    allocating = {re.match(r"(?:static )?[a-z_ ]+?\**([a-z_0-9]+)\(", f.strip()).group(1)  # type: ignore[union-attr]
                  for f in funcs if re.search(r"\b(malloc|calloc|realloc)\(", f)
                  and re.match(r"(?:static )?[a-z_ ]+?\**([a-z_0-9]+)\(", f.strip())}
    assert allocating == {"parse", "tli_policy_load_buffer", "tli_policy_load"}


@pytest.mark.parametrize("n", [2, 5])
def test_automaton_parity_under_arbitrary_readings(lib: Any, nd_artifacts: dict[int, Any],
                                                   n: int) -> None:
    """Readings no physics would produce (random bits, random pushes): assumption violations,
    resynchronisation and holding -- the same states, modes, DS, failures, holding and done
    flags, and velocities (no cuts learned: ``learn_cuts=False``, so bit for bit)."""
    nd = nd_artifacts[n]
    inputs = nd.exported.artifact["automaton"]["inputs"]
    modes = nd.exported.artifact["automaton"]["modes"]
    rng = np.random.default_rng(n)
    seen = {"assumption": 0, "holding": 0, "failure": 0, "done": 0}
    for _ in range(5):
        pol = LTLDSPolicy(nd.automaton, nd.model, nd.certificate, dt=0.01, learn_cuts=False)
        c = CPolicy(lib, nd.exported.text_path)
        reading = frozenset(v for v in inputs if rng.random() < 0.3)
        x = rng.normal(size=n)
        pol.reset(x, reading)
        info = c.reset(x, mask(reading, inputs))
        assert (info.state, modes[info.mode]) == (pol.state, pol.mode)
        assert bool(info.flags & F_HOLDING) == pol.holding
        for _ in range(400):
            if rng.random() < 0.2:
                reading = frozenset(v for v in inputs if rng.random() < 0.3)
            x = x + rng.normal(scale=0.05, size=n)
            perturbed = bool(rng.random() < 0.1)
            v_py, info, v_c, new = step_both(pol, c, x, reading, perturbed,
                                             nd.exported.artifact)
            assert bool(info.flags & F_HOLDING) == pol.holding
            assert bool(info.flags & F_DONE) == pol.done
            assert bool(info.flags & F_FAILURE) == any(isinstance(e, InvarianceFailure)
                                                       for e in new)
            assert bool(info.flags & F_ASSUMPTION) == any(
                isinstance(e, AssumptionViolationEvent) for e in new)
            assert np.array_equal(v_py, v_c)
            seen["assumption"] += bool(info.flags & F_ASSUMPTION)
            seen["holding"] += bool(info.flags & F_HOLDING)
            seen["failure"] += bool(info.flags & F_FAILURE)
            seen["done"] += bool(info.flags & F_DONE)
    assert all(v > 0 for v in seen.values()), seen
