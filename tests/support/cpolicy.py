"""A ctypes binding of the C policy evaluator (``tli_verify/deploy/c``), for tests only.

:func:`build` compiles ``tli_policy.c`` with the system compiler into a shared library in a
directory the test owns; :class:`CPolicy` wraps one loaded artifact. :func:`run_side_by_side`
drives the C evaluator and the Python executive (:class:`~tli_verify.runtime.executive.LTLDSPolicy`)
with the same states, readings and perturbation flags, feeding the C side the cuts the Python
side learned (the cut QCQP is not in C), and returns both traces.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

MAX_DIM = 32
F_MODE_CHANGE, F_REPLAN, F_FAILURE, F_ASSUMPTION, F_HOLDING, F_DONE, F_PERTURBED = (
    1, 2, 4, 8, 16, 32, 64)
F_STALL, F_REENTERED = 128, 256
CFLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-pedantic", "-Werror"]


def c_source_dir() -> Path:
    """The packaged C sources (``tli_verify/deploy/c``)."""
    return Path(str(resources.files("tli_verify").joinpath("deploy", "c")))


def compiler() -> str | None:
    """The system C compiler, or None."""
    return shutil.which("cc") or shutil.which("gcc")


def build(out_dir: Path) -> Path:
    """Compile the evaluator into ``out_dir/libtli_policy.so`` (warnings are errors)."""
    cc = compiler()
    assert cc is not None, "no C compiler"
    lib = out_dir / "libtli_policy.so"
    subprocess.run([cc, *CFLAGS, "-fPIC", "-shared", "-o", str(lib),
                    str(c_source_dir() / "tli_policy.c"), "-lm"], check=True,
                   capture_output=True, text=True)
    return lib


class StepInfo(ctypes.Structure):
    _fields_ = [("state", ctypes.c_int), ("mode", ctypes.c_int), ("planned", ctypes.c_int),
                ("ds", ctypes.c_int), ("flags", ctypes.c_uint), ("steps", ctypes.c_long),
                ("failed_mode", ctypes.c_int), ("failed_ds", ctypes.c_int),
                ("entry", ctypes.c_double * MAX_DIM),
                ("last_inside", ctypes.c_double * MAX_DIM),
                ("outside", ctypes.c_double * MAX_DIM)]


class CError(Exception):
    """A non-zero status of the C evaluator: ``code`` and its message."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(f"status {code}: {message}")
        self.code = code
        self.message = message


_LIBS: dict[str, ctypes.CDLL] = {}


def library(path: Path) -> ctypes.CDLL:
    """Load (once) and declare the signatures."""
    key = str(path)
    if key in _LIBS:
        return _LIBS[key]
    lib = ctypes.CDLL(key)
    dp = ctypes.POINTER(ctypes.c_double)
    vp = ctypes.c_void_p
    lib.tli_policy_load.argtypes = [ctypes.c_char_p, ctypes.POINTER(vp), ctypes.c_char_p,
                                    ctypes.c_size_t]
    lib.tli_policy_load_buffer.argtypes = [ctypes.c_char_p, ctypes.c_size_t,
                                           ctypes.POINTER(vp), ctypes.c_char_p,
                                           ctypes.c_size_t]
    lib.tli_policy_free.argtypes = [vp]
    for name in ("tli_policy_dim", "tli_policy_n_inputs", "tli_policy_n_modes",
                 "tli_policy_n_ds"):
        getattr(lib, name).argtypes = [vp]
    lib.tli_policy_n_cuts.argtypes = [vp, ctypes.c_int]
    lib.tli_policy_ds_mode.argtypes = [vp, ctypes.c_int]
    lib.tli_policy_dt.argtypes = [vp]
    lib.tli_policy_dt.restype = ctypes.c_double
    lib.tli_policy_sha256.argtypes = [vp]
    lib.tli_policy_sha256.restype = ctypes.c_char_p
    lib.tli_policy_reset.argtypes = [vp, dp, ctypes.c_uint64, ctypes.POINTER(StepInfo)]
    lib.tli_policy_decide.argtypes = [vp, dp, ctypes.c_uint64, ctypes.c_int,
                                      ctypes.POINTER(StepInfo)]
    lib.tli_policy_velocity.argtypes = [vp, dp]
    lib.tli_policy_step.argtypes = [vp, dp, ctypes.c_uint64, ctypes.c_int, dp,
                                    ctypes.POINTER(StepInfo)]
    lib.tli_policy_add_cut.argtypes = [vp, ctypes.c_int, dp, dp, ctypes.c_char_p,
                                       ctypes.c_size_t]
    lib.tli_policy_ds_velocity.argtypes = [vp, ctypes.c_int, dp, ctypes.c_int, dp]
    lib.tli_sha256.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_char_p]
    _LIBS[key] = lib
    return lib


def _vec(x: Any, n: int) -> Any:
    a = np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(n))
    return a, a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class CPolicy:
    """One loaded artifact (text form)."""

    def __init__(self, lib: ctypes.CDLL, path: Path | None = None, *,
                 data: bytes | None = None) -> None:
        self.lib = lib
        self.handle = ctypes.c_void_p()
        err = ctypes.create_string_buffer(512)
        if data is not None:
            code = lib.tli_policy_load_buffer(data, len(data), ctypes.byref(self.handle), err,
                                              512)
        else:
            code = lib.tli_policy_load(str(path).encode(), ctypes.byref(self.handle), err, 512)
        if code != 0:
            raise CError(code, err.value.decode())
        self.n = lib.tli_policy_dim(self.handle)
        self.info = StepInfo()

    def __del__(self) -> None:
        if getattr(self, "handle", None):
            self.lib.tli_policy_free(self.handle)
            self.handle = ctypes.c_void_p()

    @property
    def sha256(self) -> str:
        return str(self.lib.tli_policy_sha256(self.handle).decode())

    def n_cuts(self, ds: int) -> int:
        return int(self.lib.tli_policy_n_cuts(self.handle, ds))

    def reset(self, x: Any, reading: int) -> StepInfo:
        _, p = _vec(x, self.n)
        code = self.lib.tli_policy_reset(self.handle, p, reading, ctypes.byref(self.info))
        if code:
            raise CError(code, "reset")
        return self.info

    def decide(self, x: Any, reading: int, perturbed: bool = False) -> StepInfo:
        _, p = _vec(x, self.n)
        code = self.lib.tli_policy_decide(self.handle, p, reading, int(perturbed),
                                          ctypes.byref(self.info))
        if code:
            raise CError(code, "decide")
        return self.info

    def velocity(self) -> np.ndarray:
        out = np.zeros(self.n)
        code = self.lib.tli_policy_velocity(self.handle,
                                            out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        if code:
            raise CError(code, "velocity")
        return out

    def ds_velocity(self, ds: int, x: Any, modulate: bool = True) -> np.ndarray:
        _, p = _vec(x, self.n)
        out = np.zeros(self.n)
        code = self.lib.tli_policy_ds_velocity(self.handle, ds, p, int(modulate),
                                               out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        if code:
            raise CError(code, "ds_velocity")
        return out

    def add_cut(self, mode: int, normal: Any, point: Any) -> None:
        _a, pa = _vec(normal, self.n)  # the arrays stay alive until the call returns
        _b, pb = _vec(point, self.n)
        err = ctypes.create_string_buffer(512)
        code = self.lib.tli_policy_add_cut(self.handle, mode, pa, pb, err, 512)
        if code:
            raise CError(code, err.value.decode())


def mask(reading: Collection[str], inputs: Sequence[str]) -> int:
    """The reading's bit mask (bit i = ``inputs[i]``)."""
    return sum(1 << i for i, v in enumerate(inputs) if v in reading)


def step_both(pol: Any, c: CPolicy, x: Any, reading: frozenset[str], perturbed: bool,
              art: dict[str, Any]) -> tuple[np.ndarray, StepInfo, np.ndarray, list[Any]]:
    """One control step of the Python executive ``pol`` and the C evaluator ``c`` on the same
    state, reading and flag; asserts they are in the same automaton state, mode and DS.

    Returns
    -------
    (v_py, info, v_c, events)
        Both velocities, the C step's info and the events the Python step added.
    """
    aut = art["automaton"]
    keys = [d["key"] for d in art["ds"]]
    n_events = len(pol.events)
    v_py = pol.step(x, reading, perturbed=perturbed)
    info = c.decide(x, mask(reading, aut["inputs"]), perturbed)
    v_c = c.velocity()
    assert (info.state, aut["modes"][info.mode]) == (pol.state, pol.mode)
    assert (keys[info.ds] if info.ds >= 0 else "") == ("" if pol.holding else pol.key)
    return v_py, info, v_c, pol.events[n_events:]


@dataclass
class Trace:
    """Both sides of one episode."""

    modes_py: list[str] = field(default_factory=list)
    modes_c: list[str] = field(default_factory=list)
    keys_py: list[str] = field(default_factory=list)
    keys_c: list[str] = field(default_factory=list)
    v_py: list[np.ndarray] = field(default_factory=list)
    v_c: list[np.ndarray] = field(default_factory=list)
    failures_py: list[int] = field(default_factory=list)
    failures_c: list[int] = field(default_factory=list)
    cut_steps: list[bool] = field(default_factory=list)
    cuts_added: int = 0
    refused: int = 0
    modulated_steps: int = 0

    def max_rel(self) -> float:
        """Largest ``|v_c - v_py| / max(1, |v_py|)`` (inf-norm) over the steps."""
        worst = 0.0
        for a, b in zip(self.v_py, self.v_c, strict=True):
            worst = max(worst, float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(a))))))
        return worst

    def bitwise(self) -> int:
        """Steps whose velocities agree bit for bit."""
        return sum(bool(np.array_equal(a, b)) for a, b in zip(self.v_py, self.v_c, strict=True))


def run_side_by_side(policy: Any, cpol: CPolicy, art: dict[str, Any], sensors: Any,
                     x0: np.ndarray, steps: int, rng: np.random.Generator, *,
                     push_prob: float = 0.0, push_scale: float = 1.0,
                     pushes: Sequence[tuple[int, np.ndarray]] = ()) -> Trace:
    """One closed-loop episode, the Python executive and the C evaluator in lock step.

    The state is moved by the *Python* velocity (explicit Euler, the policy's ``dt``); both
    sides read the same state and the same reading (``task`` sensors, no lag); a push (random
    with ``push_prob``, or the given ``(step, offset)`` list) adds an offset and is reported to
    both as a perturbation. Cuts the Python side learns are added to the C side at the same
    step, before its velocity.
    """
    from tli_verify.runtime.events import CutAdded, InvarianceFailure

    inputs = art["automaton"]["inputs"]
    modes = art["automaton"]["modes"]
    keys = [d["key"] for d in art["ds"]]
    dt = policy.dt
    x = np.array(x0, dtype=np.float64)
    tr = Trace()
    sensors.reset(x.copy())
    rd = _reading_set(sensors.read(x), inputs)
    policy.reset(x, rd)
    cpol.reset(x, mask(rd, inputs))
    planned_pushes = dict(pushes)
    for t in range(1, steps + 1):
        perturbed = False
        if t in planned_pushes:
            x = x + planned_pushes[t]
            perturbed = True
        elif push_prob and rng.random() < push_prob:
            x = x + rng.normal(scale=push_scale, size=x.size)
            perturbed = True
        rd = _reading_set(sensors.read(x), inputs)
        n_events = len(policy.events)
        v_py = policy.step(x, rd, perturbed=perturbed)
        info = cpol.decide(x, mask(rd, inputs), perturbed)
        new = policy.events[n_events:]
        if any(isinstance(e, InvarianceFailure) for e in new):
            tr.failures_py.append(t)
        if info.flags & F_FAILURE:
            tr.failures_c.append(t)
        try:
            for e in new:
                if isinstance(e, CutAdded):
                    cpol.add_cut(modes.index(e.mode), e.cut.normal, e.cut.point)
                    tr.cuts_added += 1
        except CError as exc:  # the fixed storage is full: the C side refuses, parity ends
            tr.refused = exc.code
            break
        v_c = cpol.velocity()
        tr.modes_py.append(policy.mode)
        tr.modes_c.append(modes[info.mode])
        tr.keys_py.append(policy.key if not policy.holding else "")
        tr.keys_c.append(keys[info.ds] if info.ds >= 0 else "")
        tr.v_py.append(np.array(v_py))
        tr.v_c.append(v_c)
        cut = bool(policy.key and policy.model.modes[policy.key].cuts)
        tr.cut_steps.append(cut)
        tr.modulated_steps += int(cut)
        x = x + dt * np.asarray(v_py)
        if policy.done:
            break
    return tr


def _reading_set(reading: Any, inputs: Sequence[str]) -> frozenset[str]:
    if isinstance(reading, frozenset | set):
        return frozenset(reading)
    if isinstance(reading, dict):
        return frozenset(k for k, v in reading.items() if v)
    arr = np.asarray(reading, dtype=bool).reshape(-1)
    return frozenset(v for v, b in zip(inputs, arr, strict=True) if b)
