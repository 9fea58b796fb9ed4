"""Headless rendering of a trial and its short MP4 (``tli sim franka --video``).

MuJoCo fixes its OpenGL backend when it is imported (``MUJOCO_GL``: ``egl``, ``osmesa``,
``glfw``, ...), so the backend is chosen *before* the import, by probing each candidate in a
short subprocess (:func:`probe_backend`: import MuJoCo with that ``MUJOCO_GL``, open an 8x8
:class:`mujoco.Renderer`, render one frame):

1. ``MUJOCO_GL`` set by the user: that backend only (probed, so that an unusable value is a
   one-line error, not a traceback);
2. otherwise ``egl`` (GPU, or Mesa's llvmpipe without one), then ``osmesa`` (pure software);
3. none opens a context: :class:`~tli_verify.errors.TliError` (exit 2) naming what was tried
   and the system packages to install (``libegl1`` + ``libegl-mesa0``, or ``libosmesa6``).

:class:`Recorder` then renders the trial's control steps from a fixed camera
(:data:`PANDA_VIEW`: the whole arm, its base on the table and both bowls; :data:`TOOL_VIEW`: a
close-up of the bowls for the free tool) and streams them to an H.264 MP4 (imageio-ffmpeg) in
a private temporary directory; :meth:`Recorder.save` moves it to the output atomically, so a
failed rendering leaves no partial file. An exception while a frame is recorded (Ctrl-C, or
SIGTERM, which ``tli`` turns into Ctrl-C) closes the recorder and removes the temporary
directory at once; one between frames leaves it to :meth:`Recorder.close` (also a context
manager's exit, and run at the interpreter's exit).
"""

from __future__ import annotations

import atexit
import ctypes.util
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tli_verify.errors import TliError
from tli_verify.io import atomic_write_bytes

__all__ = [
    "BACKENDS",
    "INSTALL_HINT",
    "PANDA_VIEW",
    "TOOL_VIEW",
    "Probe",
    "Recorder",
    "View",
    "backend_in_effect",
    "choose_backend",
    "probe_backend",
    "select_backend",
    "view_for",
]

BACKENDS = ("egl", "osmesa")
"""Headless ``MUJOCO_GL`` backends tried in order when the user set none."""
INSTALL_HINT = ("install libegl1 and libegl-mesa0 (EGL) or libosmesa6 (OSMesa), "
                "or run without --video")
_LIBRARIES = {"egl": "EGL", "osmesa": "OSMesa"}
"""The shared library each backend loads (named in the error when it is missing)."""
PROBE_TIMEOUT = 60.0
"""Seconds a probe subprocess may take (importing MuJoCo and opening a context: ~1 s)."""
CONTROL_DT = 0.02
"""The control period (s) at which :meth:`Recorder.frame` is called (``sim.demos``)."""


@dataclass(frozen=True, slots=True)
class View:
    """A fixed free camera (MuJoCo's ``mjvCamera``): it looks at ``lookat`` from
    ``distance`` metres away, ``azimuth`` degrees about world z (180: from +x, towards -x) and
    ``elevation`` degrees (negative: from above).

    Attributes
    ----------
    lookat : tuple of float, shape (3,)
    distance : float
    azimuth : float
    elevation : float
    """

    lookat: tuple[float, float, float]
    distance: float
    azimuth: float
    elevation: float


PANDA_VIEW = View((0.35, 0.0, 0.28), 1.5, 165.0, -24.0)
"""The Panda rig's camera: from beyond the table's far edge (+x), 15 degrees towards the soup
bowl (-y), facing the robot: the whole arm (also stretched out over the target bowl), its base
standing on the table (:func:`tli_verify.sim.scene.add_stand`), both bowls and the ladle; the
soup bowl on the left, the target bowl on the right."""
TOOL_VIEW = View((0.5, 0.0, 0.06), 0.9, 180.0, -30.0)
"""The free tool's camera: a close-up of the ladle over the tray and the bowls (no arm)."""
FORCE_SCALE = 0.006
"""Length (m) per newton of the arrow drawn for a person's force on the ladle."""
FORCE_WIDTH = 0.012
"""Width (m) of that arrow."""
FORCE_RGBA = (0.9, 0.1, 0.1, 1.0)
BASE_BODY = "link0"
"""The Panda's base body: a model with it is rendered from :data:`PANDA_VIEW`."""


def view_for(model: Any) -> View:
    """The camera for a compiled model: :data:`PANDA_VIEW` when it has the Panda's base
    (:data:`BASE_BODY`), else :data:`TOOL_VIEW`."""
    import mujoco

    has_arm = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, BASE_BODY) >= 0
    return PANDA_VIEW if has_arm else TOOL_VIEW


_PROBE = """\
import mujoco
m = mujoco.MjModel.from_xml_string(
    '<mujoco><worldbody><light pos="0 0 1"/><geom size=".1"/></worldbody></mujoco>')
d = mujoco.MjData(m)
mujoco.mj_forward(m, d)
r = mujoco.Renderer(m, 8, 8)
r.update_scene(d)
r.render()
r.close()
"""


@dataclass(frozen=True, slots=True)
class Probe:
    """The outcome of opening one OpenGL backend in a subprocess.

    Attributes
    ----------
    backend : str
        The ``MUJOCO_GL`` value tried.
    ok : bool
        A frame was rendered.
    detail : str
        Why not (the last line of the subprocess's error output, shortened); ``""`` if ok.
    """

    backend: str
    ok: bool
    detail: str = ""


def _shorten(text: str, limit: int = 90) -> str:
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    last = lines[-1] if lines else "no output"
    return last if len(last) <= limit else last[:limit - 3] + "..."


def probe_backend(backend: str, *, timeout: float = PROBE_TIMEOUT) -> Probe:
    """Whether MuJoCo renders with ``MUJOCO_GL=backend`` here, tried in a fresh interpreter.

    Parameters
    ----------
    backend : str
        A ``MUJOCO_GL`` value (``"egl"``, ``"osmesa"``, ...).
    timeout : float, optional
        Seconds before the probe counts as failed.

    Returns
    -------
    Probe
    """
    env = dict(os.environ, MUJOCO_GL=backend)
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True,
                              text=True, timeout=timeout, stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        return Probe(backend, False, f"no frame within {timeout:g} s")
    except OSError as exc:
        return Probe(backend, False, f"cannot start {sys.executable}: {exc.strerror}")
    if done.returncode == 0:
        return Probe(backend, True)
    detail = _shorten(done.stderr)
    lib = _LIBRARIES.get(backend)
    if lib is not None and ctypes.util.find_library(lib) is None:
        detail = f"lib{lib} not found ({detail})"
    return Probe(backend, False, detail)


def choose_backend(env: Mapping[str, str],
                   probe: Callable[[str], Probe] | None = None) -> str:
    """The ``MUJOCO_GL`` backend to use (module doc: the user's, else egl, else osmesa).

    Parameters
    ----------
    env : mapping
        The environment (``MUJOCO_GL`` read from it).
    probe : callable, optional
        ``backend -> Probe`` (default :func:`probe_backend`).

    Returns
    -------
    str
        The first backend that rendered.

    Raises
    ------
    TliError
        (exit 2) The user's backend, or every one of :data:`BACKENDS`, failed: the message
        names each backend tried, why it failed and what to install.
    """
    if probe is None:
        probe = probe_backend
    user = env.get("MUJOCO_GL", "").strip()
    if user:
        res = probe(user)
        if res.ok:
            return user
        raise TliError(f"--video: MUJOCO_GL={user} (set in the environment) opens no OpenGL "
                       f"context: {res.detail}; unset MUJOCO_GL to let tli try "
                       f"{', then '.join(BACKENDS)}, or {INSTALL_HINT}")
    failed = []
    for backend in BACKENDS:
        res = probe(backend)
        if res.ok:
            return backend
        failed.append(f"MUJOCO_GL={backend}: {res.detail}")
    raise TliError(f"--video: no headless OpenGL context ({'; '.join(failed)}); {INSTALL_HINT}")


def backend_in_effect() -> str | None:
    """The OpenGL backend of the MuJoCo already imported in this process (``"egl"``,
    ``"osmesa"``, ``"glfw"``, ...), or ``None`` when MuJoCo is not imported (or has no
    rendering)."""
    mujoco = sys.modules.get("mujoco")
    ctx = getattr(mujoco, "GLContext", None) if mujoco is not None else None
    if ctx is None:
        return None
    return str(ctx.__module__).rsplit(".", 1)[-1]


def select_backend() -> str:
    """Choose the OpenGL backend (:func:`choose_backend`) and set ``MUJOCO_GL`` to it.

    Call before MuJoCo is imported: afterwards the backend is fixed, and the one in effect
    is returned without probing (:class:`Recorder` then reports it if it cannot render).

    Returns
    -------
    str
        The backend in effect, or the one MuJoCo will use when imported.

    Raises
    ------
    TliError
        (exit 2) No backend renders (:func:`choose_backend`).
    """
    fixed = backend_in_effect()
    if fixed is not None:
        return fixed
    backend = choose_backend(os.environ)
    os.environ["MUJOCO_GL"] = backend
    return backend


class Recorder:
    """Headless frames of a trial, streamed to a short MP4 (``--video``).

    Call :func:`select_backend` before MuJoCo is imported. Frames are rendered from a fixed
    camera (``view``, default :func:`view_for` the rig's model) and encoded as they come
    (H.264, imageio-ffmpeg, ``1 / (CONTROL_DT * every)`` frames per second) into a private
    temporary file; :meth:`save` moves it to the output atomically.

    Parameters
    ----------
    every : int, optional
        Keep one control step in ``every`` (default 2: 25 frames/s at 20 ms).
    size : tuple of int, optional
        ``(height, width)`` in pixels, multiples of 8 (H.264 blocks), at most 480 x
        640 (MuJoCo's default offscreen buffer).
    shadow_size : int, optional
        Side of the shadow map in pixels (default 1024, at most the model's): the scene's
        4096 made a software-rendered (llvmpipe) frame take ~0.13 s instead of ~0.07 s.
    view : View, optional
        The camera (default: :func:`view_for` the model of the first rig rendered).

    Attributes
    ----------
    count : int
        Frames rendered so far.
    """

    def __init__(self, every: int = 2, size: tuple[int, int] = (360, 480),
                 shadow_size: int = 1024, view: View | None = None) -> None:
        if int(every) < 1:
            raise TliError(f"--video: every must be >= 1, got {every}")
        h, w = (int(v) for v in size)
        if h < 16 or w < 16 or h % 8 or w % 8:
            raise TliError(f"--video: frame size {h}x{w}: both must be multiples of 8, >= 16")
        self.every = int(every)
        self.shadow_size = max(64, int(shadow_size))
        self.size = (h, w)
        self.view = view
        self.count = 0
        self._calls = 0
        self._renderer: Any = None
        self._camera: Any = None
        self._writer: Any = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None

    @property
    def fps(self) -> int:
        """Frames per second of the MP4 (real time)."""
        return max(1, round(1.0 / (CONTROL_DT * self.every)))

    def _open(self, model: Any) -> None:
        import imageio.v2 as imageio
        import mujoco

        quality = model.vis.quality
        saved = int(quality.shadowsize)
        quality.shadowsize = min(saved, self.shadow_size)  # read once, by the context
        try:
            renderer = mujoco.Renderer(model, *self.size)
        except Exception as exc:
            raise TliError(
                f"--video: MuJoCo's {backend_in_effect() or 'OpenGL'} backend opens no "
                f"context ({_shorten(str(exc))}); set MUJOCO_GL=egl or osmesa before MuJoCo is "
                f"imported, or {INSTALL_HINT}") from None
        finally:
            quality.shadowsize = saved
        self._renderer = renderer
        atexit.register(self.close)  # before MuJoCo's own exit handlers tear the context down
        if self.view is None:
            self.view = view_for(model)
        cam = mujoco.MjvCamera()
        cam.lookat[:] = self.view.lookat
        cam.distance, cam.azimuth = self.view.distance, self.view.azimuth
        cam.elevation = self.view.elevation
        self._camera = cam
        self._tmp = tempfile.TemporaryDirectory(prefix="tli-video-")
        self._writer = imageio.get_writer(
            Path(self._tmp.name) / "video.mp4", format="FFMPEG", mode="I", fps=self.fps,
            codec="libx264", macro_block_size=8, ffmpeg_log_level="error")

    def frame(self, rig: Any) -> None:
        """Render the current state of ``rig`` (its ``model`` and ``data``), every
        ``every``-th call (the first call included).

        Any exception (:class:`KeyboardInterrupt` included) closes the recorder first: the
        partial video is deleted, and a later :meth:`save` raises.
        """
        self._calls += 1
        if (self._calls - 1) % self.every:
            return
        try:
            if self._renderer is None:
                self._open(rig.model)
            self._renderer.update_scene(rig.data, self._camera)
            self._draw_person(rig)
            self._writer.append_data(self._renderer.render())
        except BaseException:
            self.close()
            raise
        self.count += 1

    def _draw_person(self, rig: Any) -> None:
        """An arrow for the force of a person's hand on the ladle (the rig's ``person_wrench``,
        if it has one: the Panda's), ending at the ladle's centre of mass where the hand
        pushes, :data:`FORCE_SCALE` metres per newton; nothing without a perturbation."""
        import mujoco
        import numpy as np

        wrench = getattr(rig, "person_wrench", None)
        scene = self._renderer.scene
        if wrench is None or scene.ngeom >= scene.maxgeom:
            return
        force = np.asarray(wrench, dtype=np.float64)[:3]
        if float(np.linalg.norm(force)) < 0.5:  # N: below, no arrow (a hand just letting go)
            return
        end = np.array(rig.data.xipos[rig.carrier], dtype=np.float64)
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3),
                            np.eye(3).ravel(), np.array(FORCE_RGBA, dtype=np.float32))
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, FORCE_WIDTH,
                             end - FORCE_SCALE * force, end)
        scene.ngeom += 1

    def close(self) -> None:
        """Release the OpenGL context and the encoder, and delete the temporary file
        (idempotent; :meth:`save` calls it). The file is deleted even when releasing the
        others fails (e.g. the encoder was killed by the same Ctrl-C)."""
        atexit.unregister(self.close)
        renderer, writer, tmp = self._renderer, self._writer, self._tmp
        self._renderer = self._writer = self._tmp = None
        try:
            try:
                if renderer is not None:
                    renderer.close()
            finally:
                if writer is not None:
                    writer.close()
        finally:
            if tmp is not None:
                tmp.cleanup()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def save(self, path: str | os.PathLike[str]) -> None:
        """Finish the MP4 and write it to ``path`` atomically, then :meth:`close`.

        Raises
        ------
        TliError
            (exit 2) No frame was rendered.
        OutputError
            (exit 2) ``path`` cannot be written (nothing is left behind).
        """
        try:
            if self._writer is None or self._tmp is None or not self.count:
                raise TliError(f"--video {path}: no frames were rendered")
            self._writer.close()
            self._writer = None
            atomic_write_bytes(path, (Path(self._tmp.name) / "video.mp4").read_bytes())
        finally:
            self.close()
