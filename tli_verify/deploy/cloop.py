"""The C evaluator in a Python control loop (``tli sim franka --c-evaluator``).

:func:`compile_evaluator` builds ``tli_verify/deploy/c/tli_policy.c`` with the system C compiler
into a shared library; :class:`CEvaluator` loads an exported artifact's text form through
``ctypes``; :class:`CInTheLoop` runs it as the executive of a closed loop: **the velocity the
robot gets is the C evaluator's**. Beside it the Python executive
(:class:`~tli_verify.runtime.executive.LTLDSPolicy`) plays the supervisor a real deployment
has outside its real-time thread: it sees the same states, readings and perturbations, and
solves the cut QCQP (appendix E.3, not ported to C) on each invariance failure; the cut is
handed to the evaluator's fixed storage (:c:func:`tli_policy_add_cut`) before the step's
velocity. The stall rule (:mod:`tli_verify.runtime.stall`) runs in C when the artifact carries
one (its ``stall`` section, from the evidence it was exported with), and the supervisor runs the
same rule. Each step checks that both agree on the automaton state, mode and DS and that the
rule fired (or its re-entry ended) in both or neither; a disagreement (or a full cut storage)
stops the run with a :class:`~tli_verify.errors.ExportError`.
"""

from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.deploy.artifact import check_artifact, text_path_for
from tli_verify.errors import ExportError
from tli_verify.io import package_file, sha256_file
from tli_verify.runtime.events import CutAdded, Reentered, Stall
from tli_verify.runtime.stall import STALL_PARAMETERS, StallRule

__all__ = ["CEvaluator", "CInTheLoop", "compile_evaluator", "describe_stall", "in_the_loop"]

FloatArray = npt.NDArray[np.float64]
_MAX_DIM = 32
_F_FAILURE = 4
_F_STALL = 128
_F_REENTERED = 256
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fPIC", "-shared")


def compile_evaluator(out_dir: str | os.PathLike[str]) -> Path:
    """Build the evaluator with the system C compiler (``cc``, else ``gcc``).

    Returns
    -------
    Path
        ``out_dir/libtli_policy.so``.

    Raises
    ------
    ExportError
        No C compiler, or the build failed (exit 2).
    """
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise ExportError("the C evaluator needs a C compiler (cc or gcc) on PATH")
    src = package_file("deploy", "c", "tli_policy.c")
    lib = Path(out_dir) / "libtli_policy.so"
    proc = subprocess.run([cc, *CFLAGS, "-o", str(lib), str(src), "-lm"], capture_output=True,
                          text=True, check=False)
    if proc.returncode != 0:
        first = (proc.stderr.strip().splitlines() or ["?"])[0]
        raise ExportError(f"{src}: the C build failed: {first}")
    return lib


class _Info(ctypes.Structure):
    _fields_ = [("state", ctypes.c_int), ("mode", ctypes.c_int), ("planned", ctypes.c_int),
                ("ds", ctypes.c_int), ("flags", ctypes.c_uint), ("steps", ctypes.c_long),
                ("failed_mode", ctypes.c_int), ("failed_ds", ctypes.c_int),
                ("entry", ctypes.c_double * _MAX_DIM),
                ("last_inside", ctypes.c_double * _MAX_DIM),
                ("outside", ctypes.c_double * _MAX_DIM)]


def _ptr(a: FloatArray) -> Any:
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


class CEvaluator:
    """One artifact loaded by the C evaluator.

    Parameters
    ----------
    library : path-like
        From :func:`compile_evaluator`.
    text_path : path-like
        The artifact's text form (``NAME.tli.txt``).

    Raises
    ------
    ExportError
        The loader refused the file (its status and message).
    """

    def __init__(self, library: str | os.PathLike[str], text_path: str | os.PathLike[str]
                 ) -> None:
        try:
            lib = ctypes.CDLL(str(library))
        except OSError as exc:  # e.g. a noexec temporary directory, a foreign compiler
            raise ExportError(f"{library}: the C evaluator's library does not load: "
                              f"{exc}") from None
        vp, dp = ctypes.c_void_p, ctypes.POINTER(ctypes.c_double)
        lib.tli_policy_load.argtypes = [ctypes.c_char_p, ctypes.POINTER(vp), ctypes.c_char_p,
                                        ctypes.c_size_t]
        lib.tli_policy_free.argtypes = [vp]
        lib.tli_policy_dim.argtypes = [vp]
        lib.tli_policy_sha256.argtypes = [vp]
        lib.tli_policy_sha256.restype = ctypes.c_char_p
        lib.tli_policy_reset.argtypes = [vp, dp, ctypes.c_uint64, ctypes.POINTER(_Info)]
        lib.tli_policy_decide.argtypes = [vp, dp, ctypes.c_uint64, ctypes.c_int,
                                          ctypes.POINTER(_Info)]
        lib.tli_policy_velocity.argtypes = [vp, dp]
        lib.tli_policy_add_cut.argtypes = [vp, ctypes.c_int, dp, dp, ctypes.c_char_p,
                                           ctypes.c_size_t]
        self._lib = lib
        self._handle = vp()
        err = ctypes.create_string_buffer(512)
        code = lib.tli_policy_load(str(text_path).encode(), ctypes.byref(self._handle), err,
                                   512)
        if code != 0:
            raise ExportError(f"{text_path}: refused by the C loader (status {code}): "
                              f"{err.value.decode(errors='replace')}")
        self.dim = int(lib.tli_policy_dim(self._handle))
        self.info = _Info()

    def __del__(self) -> None:
        if getattr(self, "_handle", None):
            self._lib.tli_policy_free(self._handle)
            self._handle = ctypes.c_void_p()

    @property
    def sha256(self) -> str:
        """The artifact's content hash, as the C loader verified it."""
        return str(self._lib.tli_policy_sha256(self._handle).decode())

    def _x(self, x: npt.ArrayLike) -> FloatArray:
        return np.ascontiguousarray(np.asarray(x, dtype=np.float64).reshape(self.dim))

    def reset(self, x: npt.ArrayLike, reading: int) -> _Info:
        """``tli_policy_reset``."""
        xa = self._x(x)
        if self._lib.tli_policy_reset(self._handle, _ptr(xa), reading, ctypes.byref(self.info)):
            raise ExportError("C evaluator: reset refused (non-finite state or unknown sensor)")
        return self.info

    def decide(self, x: npt.ArrayLike, reading: int, perturbed: bool) -> _Info:
        """``tli_policy_decide``."""
        xa = self._x(x)
        if self._lib.tli_policy_decide(self._handle, _ptr(xa), reading, int(perturbed),
                                       ctypes.byref(self.info)):
            raise ExportError("C evaluator: step refused (non-finite state or unknown sensor)")
        return self.info

    def velocity(self) -> FloatArray:
        """``tli_policy_velocity``."""
        out = np.zeros(self.dim)
        self._lib.tli_policy_velocity(self._handle, _ptr(out))
        return out

    def add_cut(self, mode: int, normal: npt.ArrayLike, point: npt.ArrayLike) -> None:
        """``tli_policy_add_cut``; a refusal (full storage, bad plane) raises."""
        w, p = self._x(normal), self._x(point)
        err = ctypes.create_string_buffer(512)
        code = self._lib.tli_policy_add_cut(self._handle, mode, _ptr(w), _ptr(p), err, 512)
        if code:
            raise ExportError(f"C evaluator: cut refused (status {code}): "
                              f"{err.value.decode(errors='replace')}")


class CInTheLoop:
    """The C evaluator as a closed loop's executive, the Python executive as its supervisor.

    Parameters
    ----------
    supervisor : LTLDSPolicy
        Built from the same model, spec and certificate as the artifact.
    evaluator : CEvaluator
    artifact : dict
        The JSON artifact (:func:`~tli_verify.deploy.export.check_artifact`): its inputs, modes
        and DS keys give the bit and index orders.

    Attributes
    ----------
    max_rel_diff : float
        Largest ``|v_c - v_py|_inf / max(1, |v_py|_inf)`` seen, against the supervisor's own
        velocity at the same state.
    steps : int
    """

    def __init__(self, supervisor: Any, evaluator: CEvaluator, artifact: dict[str, Any]) -> None:
        self.supervisor = supervisor
        self.evaluator = evaluator
        aut = artifact["automaton"]
        self._inputs = list(aut["inputs"])
        self._modes = list(aut["modes"])
        self._keys = [d["key"] for d in artifact["ds"]]
        stall = artifact.get("stall")
        self._stall = None if stall is None else \
            StallRule(**{k: float(stall[k]) for k in STALL_PARAMETERS})
        self.sha256 = evaluator.sha256
        self.max_rel_diff = 0.0
        self.steps = 0

    def __getattr__(self, name: str) -> Any:
        # mode, done, events, model, automaton, goal_modes, ...: the supervisor's (checked
        # equal to the evaluator's every step)
        return getattr(self.supervisor, name)

    @property
    def stall_rule(self) -> StallRule | None:
        """The stall rule the artifact runs (its ``stall`` section; None: none)."""
        return self._stall

    @stall_rule.setter
    def stall_rule(self, rule: StallRule | None) -> None:
        """The artifact's own rule (or None when it has none) only: the C executive runs the
        rule the artifact was exported with, and the supervisor must run the same one, else
        their modes disagree and the trial would record a rule the robot did not run."""
        if rule != self._stall:
            raise ExportError(f"the artifact runs {describe_stall(self._stall)}; the run asks "
                              f"for {describe_stall(rule)}: export from evidence made with the "
                              "same rule (tli sim franka --no-stall-rule switches it off)")
        self.supervisor.stall_rule = rule

    def _mask(self, sensors: Any) -> int:
        if isinstance(sensors, dict):
            on = {k for k, v in sensors.items() if v}
        else:
            on = set(sensors)
        return sum(1 << i for i, v in enumerate(self._inputs) if v in on)

    def reset(self, x0: npt.ArrayLike, sensors: Any) -> None:
        """Start an episode on both."""
        self.supervisor.reset(x0, sensors)
        info = self.evaluator.reset(x0, self._mask(sensors))
        self._check(info, 0)

    def _check(self, info: _Info, t: int) -> None:
        sup = self.supervisor
        mode = self._modes[info.mode]
        key = self._keys[info.ds] if info.ds >= 0 else ""
        want = "" if sup.holding else sup.key
        if mode != sup.mode or key != want or info.state != sup.state:
            raise ExportError(f"C evaluator and runtime disagree at step {t}: C in state "
                              f"{info.state} mode {mode!r} DS {key!r}, the runtime in state "
                              f"{sup.state} mode {sup.mode!r} DS {want!r}")

    def step(self, x: npt.ArrayLike, sensors: Any, *, perturbed: bool = False) -> FloatArray:
        """One control step: the evaluator's velocity (the supervisor decides alongside and
        supplies the cuts)."""
        sup = self.supervisor
        n_events = len(sup.events)
        key = sup.monitor(sup.decide(x, sensors, perturbed=perturbed))
        info = self.evaluator.decide(x, self._mask(sensors), perturbed)
        self.steps += 1
        self._check(info, self.steps)
        new = sup.events[n_events:]
        for kind, flag in ((Stall, _F_STALL), (Reentered, _F_REENTERED)):
            if any(isinstance(e, kind) for e in new) != bool(info.flags & flag):
                raise ExportError(f"C evaluator and runtime disagree at step {self.steps}: "
                                  f"{kind.__name__} in one only (the stall rule)")
        for e in new:
            if isinstance(e, CutAdded):
                self.evaluator.add_cut(self._modes.index(e.mode), e.cut.normal, e.cut.point)
        v = self.evaluator.velocity()
        if key:
            ref = sup.model.modes[key].velocity(np.asarray(x, dtype=np.float64), dt=sup.dt)
            diff = float(np.max(np.abs(v - ref))) / max(1.0, float(np.max(np.abs(ref))))
            self.max_rel_diff = max(self.max_rel_diff, diff)
        return v


def describe_stall(rule: StallRule | None) -> str:
    """``"the stall rule (radius 0.3, ...)"`` or ``"no stall rule"``, for messages."""
    if rule is None:
        return "no stall rule"
    return "the stall rule (" + ", ".join(f"{k} {v:g}" for k, v in rule.to_dict().items()) + ")"


def in_the_loop(supervisor: Any, artifact_json: str | os.PathLike[str],
                build_dir: str | os.PathLike[str]) -> CInTheLoop:
    """Check an artifact against the supervisor's model and wrap both.

    Raises
    ------
    ExportError
        The artifact does not check, was not made from the supervisor's model file (SHA-256),
        or the C loader refuses its text form.
    """
    art = check_artifact(artifact_json)
    model_path = getattr(supervisor.model, "path", None)
    src = art["sources"].get("model")
    if model_path is None or src is None or src["sha256"] != sha256_file(model_path):
        raise ExportError(f"{artifact_json}: not exported from the model being run "
                          f"({model_path}): its model SHA-256 differs")
    ev = CEvaluator(compile_evaluator(build_dir), text_path_for(artifact_json))
    if ev.sha256 != art["content_sha256"]:
        raise ExportError(f"{artifact_json}: its text form ({ev.sha256}) is not the JSON's "
                          f"content ({art['content_sha256']})")
    return CInTheLoop(supervisor, ev, art)
