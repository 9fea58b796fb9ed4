"""Demonstrations: the CSV format, its validation, and the bundled soup-scooping demos.

Format (one file per demonstration, UTF-8 CSV with a header row)::

    time,x0,x1,dx0,dx1,r,s,t
    0.0,1.02,8.11,0.0,0.0,0,0,0
    0.05,1.02,8.10,0.01,-0.03,0,0,0
    ...

* ``t`` -- time stamps, strictly increasing (seconds). The column may be called ``time``
  instead; it must be when a sensor is called ``t`` (the scooping task's "at the target"
  sensor): when a ``time`` column exists, a ``t`` column is a sensor;
* ``x0 .. x{n-1}`` -- the robot state (``1 <= n <= 32``, consecutive indices);
* ``dx0 .. dx{n-1}`` -- optional velocities; when absent they are computed by second-order finite
  differences on the (possibly non-uniform) time grid: central differences inside, second-order
  one-sided differences at both ends (``numpy.gradient(x, t, edge_order=2)``);
* every other column is a sensor input (an atomic proposition of the spec, paper Sec. 3), with
  values ``0`` or ``1``. With a spec the sensor columns must be exactly the spec's ``inputs``.

At least 3 data rows. Lines starting with ``#`` are comments; blank lines are skipped; a UTF-8
byte-order mark (as spreadsheets write) is accepted. States and velocities lie within
``|v| <= 1e6`` and ``n <= 32`` (:mod:`tli_verify.limits`). Every error names the file, the line
(1-based, counting the header and comments) and the column.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tli_verify.errors import DemoError
from tli_verify.io import read_text
from tli_verify.limits import MAX_ABS_VALUE, MAX_DEMO_SAMPLES, MAX_STATE_DIM

__all__ = [
    "Demonstration",
    "PoseDemonstration",
    "demo_to_csv",
    "finite_difference_velocities",
    "load_demo",
    "load_demos",
    "load_pose_demo",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

_STATE = re.compile(r"^x(\d+)$")
_VEL = re.compile(r"^dx(\d+)$")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
MIN_ROWS = 3


@dataclass(frozen=True, slots=True, eq=False)
class Demonstration:
    """One validated demonstration.

    Attributes
    ----------
    path : str
        Where it came from (used in messages).
    t : ndarray, shape (T,)
        Strictly increasing time stamps.
    x : ndarray, shape (T, n)
        States.
    dx : ndarray, shape (T, n)
        Velocities (from the file, or finite differences).
    sensor_names : tuple of str
        Sensor inputs, in column order.
    sensors : ndarray of bool, shape (T, m)
        Sensor readings.
    velocities_from_file : bool
        Whether ``dx`` came from ``dx*`` columns.
    lines : ndarray of int, shape (T,) or None
        File line number (1-based) of each row, for messages; None for synthetic data.
    """

    path: str
    t: FloatArray
    x: FloatArray
    dx: FloatArray
    sensor_names: tuple[str, ...]
    sensors: BoolArray
    velocities_from_file: bool = False
    lines: npt.NDArray[np.int64] | None = None

    @property
    def dim(self) -> int:
        """State dimension n."""
        return int(self.x.shape[1])

    @property
    def n_samples(self) -> int:
        """Number of rows T."""
        return int(self.t.size)

    def where(self, i: int) -> str:
        """``"<file>: line <L>"`` (or ``row <i>`` without line numbers) of row ``i``."""
        if self.lines is not None:
            return f"{self.path}: line {int(self.lines[i])}"
        return f"{self.path}: row {i + 1}"

    def sensor_reading(self, i: int) -> dict[str, bool]:
        """The sensor values of row ``i`` as a mapping."""
        return {name: bool(v) for name, v in zip(self.sensor_names, self.sensors[i], strict=True)}


def _header(fields: list[str], where: str, sensor_names: Sequence[str] | None
            ) -> tuple[int, list[int], list[int], list[int], list[str]]:
    """Column indices of time, x, dx and sensors; validates the header."""
    names = [f.strip() for f in fields]
    seen: set[str] = set()
    for name in names:
        if not name:
            raise DemoError(f"{where}: empty column name in the header")
        if name in seen:
            raise DemoError(f"{where}: duplicate column {name!r}")
        seen.add(name)
    time_name = "time" if "time" in names else "t"
    if time_name not in names:
        raise DemoError(f"{where}: missing column 't' (time)")
    xs: dict[int, int] = {}
    dxs: dict[int, int] = {}
    sensors: list[tuple[int, str]] = []
    for col, name in enumerate(names):
        if name == time_name:
            continue
        if m := _STATE.match(name):
            xs[int(m.group(1))] = col
        elif m := _VEL.match(name):
            dxs[int(m.group(1))] = col
        else:
            if not _NAME.match(name):
                raise DemoError(f"{where}: column {name!r} is not a valid sensor name "
                                "(letters, digits and '_', not starting with a digit)")
            sensors.append((col, name))
    orphan = sorted(set(dxs) - set(xs))
    if orphan:
        raise DemoError(f"{where}: missing state column 'x{orphan[0]}' (the header has its "
                        f"velocity column 'dx{orphan[0]}'; state columns must be x0..x{{n-1}})")
    if not xs:
        raise DemoError(f"{where}: missing state columns x0, x1, ...")
    n = len(xs)
    if sorted(xs) != list(range(n)):
        missing = min(set(range(max(xs) + 1)) - set(xs))
        raise DemoError(f"{where}: missing column 'x{missing}' (state columns must be "
                        "x0..x{n-1})")
    if n > MAX_STATE_DIM:
        raise DemoError(f"{where}: {n} state columns, more than the limit of {MAX_STATE_DIM} "
                        "(MAX_STATE_DIM)")
    if dxs and sorted(dxs) != list(range(n)):
        missing_dx = sorted(set(range(n)) ^ set(dxs))[0]
        raise DemoError(f"{where}: velocity columns must be dx0..dx{n - 1} to match the state "
                        f"(problem at 'dx{missing_dx}')")
    sensor_list = [s for _, s in sensors]
    if sensor_names is not None:
        missing_s = [s for s in sensor_names if s not in sensor_list]
        if missing_s:
            raise DemoError(f"{where}: missing sensor column {missing_s[0]!r} required by the "
                            "spec's inputs")
        extra = [s for s in sensor_list if s not in sensor_names]
        if extra:
            raise DemoError(f"{where}: unknown column {extra[0]!r} (not a spec input, not "
                            "time, x<i> or dx<i>)")
    return (names.index(time_name), [xs[i] for i in range(n)],
            [dxs[i] for i in range(n)] if dxs else [], [c for c, _ in sensors], sensor_list)


def _numeric_rows(rows: list[tuple[int, list[str]]], names: list[str], cols: list[int],
                  where: str, *, nonfinite: str = "") -> FloatArray:
    """The numeric columns ``cols`` of a demonstration's data rows, checked: at least
    ``MIN_ROWS`` rows, each with the header's field count; each value a finite number, within
    ``MAX_ABS_VALUE`` (the first column, the time, excepted); the time strictly increasing.

    Returns
    -------
    ndarray, shape (len(rows), len(cols))

    Raises
    ------
    DemoError
        Naming the file, the line and the column.
    """
    if len(rows) < MIN_ROWS:
        raise DemoError(f"{where}: {len(rows)} data row(s), a demonstration needs at least "
                        f"{MIN_ROWS}")
    values = np.empty((len(rows), len(cols)), dtype=np.float64)
    for r, (lineno, fields) in enumerate(rows):
        if len(fields) != len(names):
            raise DemoError(f"{where}: line {lineno}: {len(fields)} fields, the header has "
                            f"{len(names)}")
        for j, col in enumerate(cols):
            raw = fields[col].strip()
            try:
                v = float(raw)
            except ValueError:
                raise DemoError(f"{where}: line {lineno}: column {names[col]!r}: not a number "
                                f"({raw!r})") from None
            if not math.isfinite(v):
                raise DemoError(f"{where}: line {lineno}: column {names[col]!r}: {raw!r} is not "
                                f"finite (NaN/Inf){nonfinite}")
            if j > 0 and not abs(v) <= MAX_ABS_VALUE:
                raise DemoError(f"{where}: line {lineno}: column {names[col]!r}: {raw!r} is "
                                f"outside the range |v| <= {MAX_ABS_VALUE:g} (MAX_ABS_VALUE)")
            values[r, j] = v
    t = values[:, 0]
    steps = np.diff(t)
    if np.any(steps <= 0):
        r = int(np.flatnonzero(steps <= 0)[0]) + 1
        raise DemoError(f"{where}: line {rows[r][0]}: t = {float(t[r])!r} does not increase "
                        f"(previous row has t = {float(t[r - 1])!r})")
    return values


def load_demo(path: str | os.PathLike[str], *,
              sensor_names: Sequence[str] | None = None) -> Demonstration:
    """Read and validate one demonstration CSV (format in the module docstring).

    Parameters
    ----------
    path : path-like
        The CSV file.
    sensor_names : sequence of str, optional
        The sensor inputs the columns must be exactly (a spec's ``inputs``).

    Returns
    -------
    Demonstration

    Raises
    ------
    DemoError
        Naming the file, line and column: unreadable file, bad header, wrong field count,
        non-numeric / NaN / Inf value, a state or velocity outside ``|v| <= MAX_ABS_VALUE``,
        more than ``MAX_STATE_DIM`` state columns, sensor value other than 0/1,
        non-increasing ``t``, fewer than 3 rows.
    """
    where = str(path)
    text = read_text(path, what="demonstration", error=DemoError)
    header: list[str] | None = None
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(io.StringIO(text), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            fields = next(csv.reader([line]))
        except csv.Error as exc:
            raise DemoError(f"{where}: line {lineno}: malformed CSV: {exc}") from None
        if header is None:
            header = fields
        else:
            rows.append((lineno, fields))
    if header is None:
        raise DemoError(f"{where}: empty file (expected a header row: t,x0,...)")
    t_col, x_cols, dx_cols, s_cols, s_names = _header(header, where, sensor_names)
    names = [h.strip() for h in header]
    if len(rows) > MAX_DEMO_SAMPLES:
        raise DemoError(f"{where}: {len(rows):,} data rows, more than the limit of "
                        f"{MAX_DEMO_SAMPLES:,} (MAX_DEMO_SAMPLES)")
    values = _numeric_rows(rows, names, [t_col, *x_cols, *dx_cols], where)
    sensors = np.zeros((len(rows), len(s_cols)), dtype=bool)
    for r, (lineno, fields) in enumerate(rows):
        for j, col in enumerate(s_cols):
            raw = fields[col].strip()
            if raw not in ("0", "1"):
                raise DemoError(f"{where}: line {lineno}: sensor {s_names[j]!r}: value {raw!r} "
                                "is not 0 or 1")
            sensors[r, j] = raw == "1"
    t = values[:, 0]
    n = len(x_cols)
    x = values[:, 1:1 + n].copy()
    if dx_cols:
        dx = values[:, 1 + n:1 + 2 * n].copy()
    lines = np.array([lineno for lineno, _ in rows], dtype=np.int64)
    if not dx_cols:
        dx = finite_difference_velocities(t, x, where=where, lines=lines)
    for arr in (t, x, dx, sensors, lines):
        arr.setflags(write=False)
    return Demonstration(path=where, t=t, x=x, dx=dx, sensor_names=tuple(s_names),
                         sensors=sensors, velocities_from_file=bool(dx_cols), lines=lines)


def finite_difference_velocities(t: FloatArray, x: FloatArray, *, where: str,
                                 lines: npt.NDArray[np.int64]) -> FloatArray:
    """Velocities of a demonstration without ``dx`` columns: ``numpy.gradient(x, t,
    edge_order=2)`` (second-order central differences, one-sided at both ends).

    Parameters
    ----------
    t : ndarray, shape (T,)
        Strictly increasing times.
    x : ndarray, shape (T, n)
    where : str
        The file, for messages.
    lines : ndarray of int, shape (T,)
        Each sample's file line.

    Returns
    -------
    ndarray, shape (T, n)

    Raises
    ------
    DemoError
        A velocity beyond :data:`~tli_verify.limits.MAX_ABS_VALUE` (time steps too small for
        the state values), naming the line and column.
    """
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        dx = np.asarray(np.gradient(x, t, axis=0, edge_order=2), dtype=np.float64)
    bad = np.argwhere(~(np.abs(dx) <= MAX_ABS_VALUE))
    if bad.size:
        r, j = (int(v) for v in bad[0])
        raise DemoError(f"{where}: line {int(lines[r])}: column 'dx{j}' (finite difference): "
                        f"{float(dx[r, j]):.6g} is outside the range |v| <= "
                        f"{MAX_ABS_VALUE:g} (MAX_ABS_VALUE): time steps too small for the "
                        "state values")
    return dx


def load_demos(paths: Iterable[str | os.PathLike[str]], *,
               sensor_names: Sequence[str] | None = None) -> list[Demonstration]:
    """Load several demonstrations and check they agree on dimension and sensors.

    Parameters
    ----------
    paths : iterable of path-like
    sensor_names : sequence of str, optional
        Required sensor columns (a spec's inputs).

    Returns
    -------
    list of Demonstration

    Raises
    ------
    DemoError
        On any per-file problem, no files, or files with a different state dimension or a
        different set of sensor columns than the first one.
    """
    demos = [load_demo(p, sensor_names=sensor_names) for p in paths]
    if not demos:
        raise DemoError("no demonstration files given")
    first = demos[0]
    for d in demos[1:]:
        if d.dim != first.dim:
            raise DemoError(f"{d.path}: state dimension {d.dim} differs from {first.path} "
                            f"({first.dim})")
        if set(d.sensor_names) != set(first.sensor_names):
            raise DemoError(f"{d.path}: sensor columns {sorted(d.sensor_names)} differ from "
                            f"{first.path} ({sorted(first.sensor_names)})")
    return demos


def _format(v: float) -> str:
    return repr(float(v))


def demo_to_csv(demo: Demonstration, *, velocities: bool = True) -> str:
    """Serialise a demonstration in the CSV format (floats round-trip exactly).

    Parameters
    ----------
    demo : Demonstration
    velocities : bool, optional
        Write the ``dx*`` columns.

    Returns
    -------
    str
    """
    n = demo.dim
    header = ["time", *(f"x{i}" for i in range(n))]
    if velocities:
        header += [f"dx{i}" for i in range(n)]
    header += list(demo.sensor_names)
    out = io.StringIO()
    out.write(",".join(header) + "\n")
    for i in range(demo.n_samples):
        row = [_format(demo.t[i]), *(_format(v) for v in demo.x[i])]
        if velocities:
            row += [_format(v) for v in demo.dx[i]]
        row += ["1" if v else "0" for v in demo.sensors[i]]
        out.write(",".join(row) + "\n")
    return out.getvalue()


# --------------------------------------------------------------------------------------------
# Pose demonstrations: position and a unit quaternion per sample (issue 35)
# --------------------------------------------------------------------------------------------

_QUAT_DIRECTIVE = re.compile(r"^#\s*quaternion\s*:\s*(\S+)\s*$", re.IGNORECASE)
QUATERNION_CONVENTIONS = {"scalar-first": (0, 1, 2, 3), "wxyz": (0, 1, 2, 3),
                          "scalar-last": (3, 0, 1, 2), "xyzw": (3, 0, 1, 2)}
"""Declared conventions: the file's ``q0..q3`` order, as indices giving (w, x, y, z)."""
UNIT_TOLERANCE = 1e-6
"""A quaternion whose norm differs from 1 by more than this is normalised (with a note)."""
MIN_QUAT_NORM = 1e-3
"""Below this norm a quaternion carries no orientation: refused."""


@dataclass(frozen=True, slots=True, eq=False)
class PoseDemonstration:
    """One validated pose demonstration.

    Attributes
    ----------
    path : str
        Where it came from.
    t : ndarray, shape (T,)
        Strictly increasing time stamps.
    x : ndarray, shape (T, n)
        Positions.
    q : ndarray, shape (T, 4)
        Unit quaternions, scalar-first ``(w, x, y, z)`` whatever the file declared, signs
        made continuous along the demonstration (no hemisphere flips between samples).
    convention : str
        The convention the file declared (``"scalar-first"`` or ``"scalar-last"``).
    notes : tuple of str
        What cleaning changed (normalised quaternions, sign flips fixed), one line each.
    lines : ndarray of int, shape (T,)
        File line of each sample.
    """

    path: str
    t: FloatArray
    x: FloatArray
    q: FloatArray
    convention: str
    notes: tuple[str, ...]
    lines: npt.NDArray[np.int64]

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return int(self.t.size)


def load_pose_demo(path: str | os.PathLike[str]) -> PoseDemonstration:
    """Read, validate and clean one pose demonstration CSV.

    Format::

        # quaternion: scalar-first        (or scalar-last; also wxyz / xyzw)
        time,x0,x1,x2,q0,q1,q2,q3
        0.0,0.41,0.02,0.30,1.0,0.0,0.0,0.0
        ...

    The ``# quaternion:`` comment must come before the header and declares the order of
    ``q0..q3``: scalar-first ``(w, x, y, z)`` or scalar-last ``(x, y, z, w)``. Positions
    ``x0..x{n-1}`` as in :func:`load_demo` (``t`` may be called ``time``). Cleaning, each
    reported in :attr:`PoseDemonstration.notes`: a quaternion whose norm is off 1 by more
    than :data:`UNIT_TOLERANCE` is normalised; a sample whose quaternion has the opposite sign
    of the previous one (a hemisphere flip: same rotation, ``<q_i, q_{i-1}> < 0``) is negated.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    PoseDemonstration

    Raises
    ------
    DemoError
        Naming the file and line (and column): no or unknown convention declared, bad header,
        a non-numeric, NaN or Inf value, a quaternion of norm below :data:`MIN_QUAT_NORM`,
        non-increasing time, fewer than 3 rows.
    """
    where = str(path)
    text = read_text(path, what="pose demonstration", error=DemoError)
    convention: str | None = None
    header: list[str] | None = None
    rows: list[tuple[int, list[str]]] = []
    for lineno, line in enumerate(io.StringIO(text), start=1):
        stripped = line.strip().lstrip("\ufeff")
        if not stripped:
            continue
        if stripped.startswith("#"):
            m = _QUAT_DIRECTIVE.match(stripped)
            if m and header is None:
                name = m.group(1).lower()
                if name not in QUATERNION_CONVENTIONS:
                    raise DemoError(f"{where}: line {lineno}: unknown quaternion convention "
                                    f"{m.group(1)!r} (scalar-first, scalar-last, wxyz or xyzw)")
                declared = {"wxyz": "scalar-first", "xyzw": "scalar-last"}.get(name, name)
                if convention is not None and declared != convention:
                    raise DemoError(f"{where}: line {lineno}: a second quaternion convention "
                                    f"({declared}) after {convention}: declare one")
                convention = declared
            continue
        try:
            fields = next(csv.reader([stripped]))
        except csv.Error as exc:
            raise DemoError(f"{where}: line {lineno}: malformed CSV: {exc}") from None
        if header is None:
            header = [f.strip() for f in fields]
        else:
            rows.append((lineno, fields))
    if header is None:
        raise DemoError(f"{where}: empty file (expected '# quaternion: scalar-first' and a "
                        "header row time,x0,...,q0,q1,q2,q3)")
    if convention is None:
        raise DemoError(f"{where}: no quaternion convention declared: add the line "
                        "'# quaternion: scalar-first' (or scalar-last) before the header")
    time_names = [h for h in header if h in ("t", "time")]
    if len(time_names) != 1:
        raise DemoError(f"{where}: header needs exactly one time column 't' or 'time', "
                        f"got {header}")
    xs = sorted((int(m.group(1)), i) for i, h in enumerate(header) if (m := _STATE.match(h)))
    if not xs or [k for k, _ in xs] != list(range(len(xs))):
        raise DemoError(f"{where}: header needs position columns x0..x(n-1), got {header}")
    if len(xs) > MAX_STATE_DIM:
        raise DemoError(f"{where}: {len(xs)} position columns, more than {MAX_STATE_DIM}")
    q_cols = []
    for k in range(4):
        if f"q{k}" not in header:
            raise DemoError(f"{where}: header has no quaternion column 'q{k}' (q0..q3 needed)")
        q_cols.append(header.index(f"q{k}"))
    known = {header.index(time_names[0]), *(i for _, i in xs), *q_cols}
    extra = [h for i, h in enumerate(header) if i not in known]
    if extra:
        raise DemoError(f"{where}: unknown column(s) {extra} in a pose demonstration")
    if len(rows) > MAX_DEMO_SAMPLES:
        raise DemoError(f"{where}: {len(rows):,} data rows, more than the limit of "
                        f"{MAX_DEMO_SAMPLES:,} (MAX_DEMO_SAMPLES)")
    values = _numeric_rows(rows, header, [header.index(time_names[0]), *(i for _, i in xs),
                                          *q_cols], where,
                           nonfinite=": refused, a pose sample needs a full orientation")
    lines = np.array([lineno for lineno, _ in rows], dtype=np.int64)
    t = values[:, 0]
    n = len(xs)
    x = values[:, 1:1 + n].copy()
    q = values[:, 1 + n:][:, list(QUATERNION_CONVENTIONS[convention])]
    notes: list[str] = []
    norms = np.linalg.norm(q, axis=1)
    tiny = np.flatnonzero(norms < MIN_QUAT_NORM)
    if tiny.size:
        r = int(tiny[0])
        raise DemoError(f"{where}: line {lines[r]}: quaternion norm {float(norms[r]):.3g} is "
                        "(nearly) zero: no orientation; refused")
    off = np.flatnonzero(np.abs(norms - 1.0) > UNIT_TOLERANCE)
    if off.size:
        notes.append(f"{where}: {off.size} quaternion(s) not of unit norm (norms "
                     f"{float(norms[off].min()):.6g}..{float(norms[off].max()):.6g}, first at "
                     f"line {lines[int(off[0])]}) normalised")
    q = q / norms[:, None]
    turn = np.einsum("ij,ij->i", q[1:], q[:-1]) < 0.0  # sign flips between neighbours
    flips = (np.flatnonzero(turn) + 1).tolist()
    q = q * np.concatenate([[1.0], np.cumprod(np.where(turn, -1.0, 1.0))])[:, None]
    if flips:
        notes.append(f"{where}: {len(flips)} hemisphere flip(s) fixed (q and -q are the same "
                     f"rotation; first at line {lines[flips[0]]}): signs made continuous")
    for arr in (t, x, q, lines):
        arr.setflags(write=False)
    return PoseDemonstration(path=where, t=t, x=x, q=q, convention=convention,
                             notes=tuple(notes), lines=lines)
