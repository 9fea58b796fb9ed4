"""The multi-modal soup-scooping experiment (paper Sec. 7.2, Fig. 7, appendix "Multi-modal
Experiments") and the closed-loop episodes behind ``tli run``.

Pieces:

* :class:`Setup` -- a spec's automaton, a certified model, its certificate and the world
  (:func:`bundled_setup`: the shipped ``models/scoop.model.json``, certified at ``dt = 1/100``;
  :func:`learn_setup`: learn and certify from seeded demonstrations of
  :class:`~tli_verify.worlds.ScoopWorld`);
* perturbations: ``{step: displacement}`` tables, :func:`random_perturbations` (uniformly random
  directions, magnitudes uniform up to the workspace size, states kept in the workspace box);
* the four policies compared (:data:`VARIANTS`):

  - ``LTL-DS``: the executive (:class:`~tli_verify.runtime.executive.LTLDSPolicy`): replanning
    and cuts learned online;
  - ``no-modulation``: the executive without cuts (``learn_cuts=False``): replanning only;
  - ``no-replan``: :class:`SequencePolicy`, the demonstrated mode sequence run open loop
    (a mode's DS runs until the reading shows the planned next mode; an unexpected reading
    does not change the DS run), cuts learned as in LTL-DS;
  - ``BC``: the paper's MLP (:mod:`tli_verify.ds.bc`) per mode under the automaton, with
    replanning and the cuts the executive learns (a BC policy has no certificate, so the
    executive runs the certified DS model for its bookkeeping and the BC nets move the state);

* :func:`run_experiment` (one learned model, many perturbed episodes per variant, batched with
  :func:`~tli_verify.runtime.executive.run_episodes`), :func:`run_all` (a process pool over
  experiments), :func:`fig7_search` / :func:`find_loop` (paper Fig. 7: the unmodulated system
  loops a -> b -> a ... until its budget, LTL-DS ends it with one cut; :func:`fig7_record`,
  :func:`plot_fig7`), the Markdown report and figures.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from tli_verify.errors import TliError
from tli_verify.logic.automaton import TaskAutomaton
from tli_verify.model import Model
from tli_verify.runtime.events import CutAdded, InvarianceFailure, Perturbation
from tli_verify.runtime.executive import (
    EpisodeResult,
    LTLDSPolicy,
    batch_results,
    run_episode,
    run_episodes,
)
from tli_verify.runtime.worlds import WorldSensors
from tli_verify.worlds.scoop import ScoopWorld

__all__ = [
    "FIG7_MIN_ROUNDS",
    "NOMINAL_START",
    "VARIANTS",
    "ExperimentConfig",
    "SequencePolicy",
    "Setup",
    "animate_episode",
    "b_to_a_failures",
    "bundled_setup",
    "episode_json",
    "fig7_record",
    "fig7_search",
    "find_loop",
    "is_fig7_loop",
    "is_fig7_rescue",
    "learn_setup",
    "make_policy",
    "mode_runs",
    "plot_episode",
    "plot_fig7",
    "random_perturbations",
    "random_start",
    "run_all",
    "run_experiment",
    "run_variant",
    "write_report",
]

FloatArray = npt.NDArray[np.float64]
VARIANTS: tuple[str, ...] = ("LTL-DS", "no-modulation", "no-replan", "BC")
CERT_DT = "1/100"
"""Control period the scoop models are certified for (and the loops run at)."""


@dataclass(frozen=True, slots=True, eq=False)
class Setup:
    """What a closed-loop scoop episode runs.

    Attributes
    ----------
    automaton : TaskAutomaton
    model : Model
        Loaded from ``model.path``.
    certificate : str
        Certificate file covering the model.
    world : ScoopWorld
    bc : mapping of str to BCPolicy, optional
        Per-DS-key MLPs (the BC variant).
    """

    automaton: TaskAutomaton
    model: Model
    certificate: str
    world: ScoopWorld
    bc: Mapping[str, Any] = field(default_factory=dict)


def bundled_setup(*, model: str | os.PathLike[str] | None = None,
                  certificate: str | os.PathLike[str] | None = None,
                  spec: str | os.PathLike[str] | None = None, lag: int = 0) -> Setup:
    """The shipped scoop spec, model and certificate (or the given files).

    Raises
    ------
    SpecError, ModelError
        (exit 2) Unreadable or invalid files.
    """
    from tli_verify.io import bundled_dir
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import load_spec
    from tli_verify.model import load_model

    model_path = Path(model) if model is not None else bundled_dir("models") / "scoop.model.json"
    cert_path = (Path(certificate) if certificate is not None
                 else bundled_dir("certificates") / "scoop.cert.json")
    loaded = load_model(model_path)
    named = loaded.spec_path  # the spec the certificate binds (check_certificate hashes it)
    if spec is not None and named is not None \
            and Path(os.path.realpath(spec)) != Path(os.path.realpath(named)):
        raise TliError(f"--spec {spec}: not the spec the model names ({named}); the "
                       "certificate binds that one, so the automaton must come from it",
                       exit_code=2)
    spec_path = Path(spec) if spec is not None else (
        named if named is not None else bundled_dir("specs") / "scoop.toml")
    return Setup(automaton=synthesize(load_spec(spec_path)), model=loaded,
                 certificate=str(cert_path), world=ScoopWorld(lag=lag))


def learn_setup(seed: int, n_demos: int, directory: str | os.PathLike[str], *,
                lag: int = 0, bc_epochs: int = 0) -> Setup:
    """Learn and certify a scoop model from ``n_demos`` seeded demonstrations.

    Writes ``scoop_<i>.csv``, ``scoop.model.json`` and ``scoop.cert.json`` (at ``dt = 1/100``)
    under ``directory``; with ``bc_epochs > 0`` also trains one BC net per DS key on the raw
    (unshifted) segments of its mode.
    """
    from tli_verify.certify.certificate import issue_certificate, write_certificate
    from tli_verify.io import bundled_dir
    from tli_verify.logic.check import synthesize
    from tli_verify.logic.spec import load_spec
    from tli_verify.model import learn_model, load_model, save_model
    from tli_verify.worlds import write_demos

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    world = ScoopWorld(lag=lag)
    spec_path = bundled_dir("specs") / "scoop.toml"
    demos = write_demos(ScoopWorld(), d, seed=seed, n_demos=n_demos)
    mpath, cpath = d / "scoop.model.json", d / "scoop.cert.json"
    model = learn_model(demos, out_path=mpath, spec_path=spec_path, seed=seed,
                        control_dt=0.01)
    save_model(model, mpath)
    write_certificate(issue_certificate(mpath, cert_path=cpath, dt=CERT_DT), cpath)
    spec = load_spec(spec_path)
    bc: dict[str, Any] = {}
    if bc_epochs > 0:
        from tli_verify.demos import load_demo
        from tli_verify.ds.bc import train_bc
        from tli_verify.segmentation import segment_demos, spec_labeler

        labeler, modes, labels = spec_labeler(spec)
        seg = segment_demos([load_demo(p) for p in demos], labeler=labeler, modes=modes,
                            labels=labels, shift=False)
        for key, data in seg.data.items():
            bc[key] = train_bc(data.x, data.dx, seed=seed, max_epochs=bc_epochs)
    return Setup(automaton=synthesize(spec), model=load_model(mpath), certificate=str(cpath),
                 world=world, bc=bc)


# ----------------------------------------------------------------------------- policies
class SequencePolicy(LTLDSPolicy):
    """The ``no-replan`` ablation: the demonstrated mode sequence, run open loop.

    The executive's automaton, monitor and cuts run as in LTL-DS (events, ``mode``, ``done``
    follow the readings), but the DS run is the plan's: mode ``k`` of the sequence
    ``a -> b -> c -> d`` (each mode's ``next_mode`` from the initial mode) until the reading
    shows mode ``k + 1``. An unexpected reading (a spill, a knock) changes nothing.
    """

    __slots__ = ("_idx", "_seq")

    def __init__(self, automaton: TaskAutomaton, model: Model,
                 certificate: str | os.PathLike[str], **kwargs: Any) -> None:
        super().__init__(automaton, model, certificate, **kwargs)
        state: int | None = automaton.initial[0]
        seq = [automaton.states[automaton.initial[0]].mode]
        while len(seq) <= len(model.modes) and state is not None:
            mm = model.modes.get(seq[-1])
            # a mode with per-transition DS only (cooking's w1 -> y): the automaton's plan
            nxt = mm.next_mode if mm is not None else self._plan(state)
            if nxt is None:
                break
            seq.append(nxt)
            state = next((t.target for t in automaton.transitions if t.source == state
                          and automaton.states[t.target].mode == nxt), None)
        self._seq: tuple[str, ...] = tuple(seq)
        self._idx = 0

    def reset(self, x0: npt.ArrayLike, sensors: Any) -> None:
        """Start at ``x0``; the sequence starts at the mode the reading shows (if in it)."""
        super().reset(x0, sensors)
        self._idx = self._seq.index(self.mode) if self.mode in self._seq else 0

    def fork(self) -> SequencePolicy:
        """A copy for another episode (see :meth:`LTLDSPolicy.fork`)."""
        new = object.__new__(SequencePolicy)
        for name in LTLDSPolicy.__slots__:
            setattr(new, name, getattr(self, name))
        new.events = list(self.events)
        new._entries = {k: list(v) for k, v in self._entries.items()}
        new._plan_cache = dict(self._plan_cache)
        new._seq = self._seq
        new._idx = self._idx
        return new

    def decide(self, x: npt.ArrayLike, sensors: Any, *, perturbed: bool = False) -> str:
        """Advance the automaton on the reading; return the sequence's DS key."""
        key = super().decide(x, sensors, perturbed=perturbed)
        if not key:
            return key
        if self._idx + 1 < len(self._seq) and self.mode == self._seq[self._idx + 1]:
            self._idx += 1
        mode = self._seq[self._idx]
        nxt = self._seq[self._idx + 1] if self._idx + 1 < len(self._seq) else None
        return self.model.key(mode, nxt)


def make_policy(setup: Setup, variant: str) -> LTLDSPolicy:
    """The executive of one variant (``BC`` runs the executive's bookkeeping with cuts).

    Raises
    ------
    CertificateError
        (exit 1) The certificate does not cover the model.
    """
    if variant not in VARIANTS:
        raise TliError(f"unknown variant {variant!r} (one of {', '.join(VARIANTS)})")
    if variant == "no-replan":
        return SequencePolicy(setup.automaton, setup.model, setup.certificate)
    return LTLDSPolicy(setup.automaton, setup.model, setup.certificate,
                       learn_cuts=variant != "no-modulation")


# ----------------------------------------------------------------------------- perturbations
def random_start(world: ScoopWorld, rng: np.random.Generator) -> FloatArray:
    """A uniform random start that reads mode ``a`` (anywhere but yellow), shape (2,)."""
    lo, hi = np.array(world.lo), np.array(world.hi)
    while True:
        x = rng.uniform(lo, hi)
        if world.region_index(x[None])[0] != 1:
            return x


def random_perturbations(rng: np.random.Generator, count: int, world: ScoopWorld, *,
                         first: int = 1, last: int = 700) -> dict[int, FloatArray]:
    """``count`` perturbations at distinct random steps in ``[first, last]``.

    Directions uniform on the circle, magnitudes uniform in ``[0, D]`` with ``D`` the
    workspace size (its side, 16 for scoop): the paper's "uniformly sampled in all directions
    of any magnitudes up to the dimension of the entire workspace".

    Returns
    -------
    dict of int to ndarray, shape (2,)
        Step (1-based) -> displacement.
    """
    size = float(np.max(np.array(world.hi) - np.array(world.lo)))
    steps = rng.choice(np.arange(first, last + 1), size=min(count, last - first + 1),
                       replace=False)
    out = {}
    for t in sorted(int(s) for s in steps):
        ang = rng.uniform(0.0, 2.0 * np.pi)
        out[t] = rng.uniform(0.0, size) * np.array([np.cos(ang), np.sin(ang)])
    return out


def _pusher(world: ScoopWorld, table: Mapping[int, npt.ArrayLike]
            ) -> Callable[[int, FloatArray], FloatArray | None]:
    lo, hi = np.array(world.lo), np.array(world.hi)

    def push(t: int, x: FloatArray) -> FloatArray | None:
        d = table.get(t)
        if d is None:
            return None
        return np.asarray(np.clip(x + np.asarray(d, dtype=np.float64), lo, hi))

    return push


# ----------------------------------------------------------------------------- episodes
def run_variant(setup: Setup, variant: str, x0: npt.ArrayLike,
                perturbations: Mapping[int, npt.ArrayLike] | None = None, *,
                steps: int = 3000, policy: LTLDSPolicy | None = None) -> EpisodeResult:
    """One closed-loop episode of a variant (:func:`run_variant_batch` for many)."""
    if variant == "BC":
        return run_variant_batch(setup, variant, np.atleast_2d(np.asarray(x0, float)),
                                 [dict(perturbations or {})], steps=steps, policy=policy)[0]
    pol = policy if policy is not None else make_policy(setup, variant)
    return run_episode(pol, WorldSensors(setup.world), x0, steps=steps,
                       perturb=_pusher(setup.world, perturbations or {}))


def run_variant_batch(setup: Setup, variant: str, starts: npt.ArrayLike,
                      perturbations: Sequence[Mapping[int, npt.ArrayLike]], *,
                      steps: int = 3000, policy: LTLDSPolicy | None = None
                      ) -> list[EpisodeResult]:
    """Episodes from many starts at once, each with its own perturbation table.

    Every episode starts from the same (fresh) policy: cuts learned in one episode do not carry
    to the others (each episode is an independent trial).
    """
    X = np.asarray(starts, dtype=np.float64)
    base = policy if policy is not None else make_policy(setup, variant)
    policies = [base.fork() for _ in range(len(X))]
    memo: dict[Any, Any] = {}
    sensors = [WorldSensors(setup.world, cache=memo) for _ in range(len(X))]
    pushers = [_pusher(setup.world, p) for p in perturbations]

    def perturb(i: int, t: int, x: FloatArray) -> FloatArray | None:
        return pushers[i](t, x)

    if variant != "BC":
        return run_episodes(policies, sensors, X, steps=steps, perturb=perturb)
    return _run_bc(setup, policies, sensors, X, steps=steps, perturb=perturb)


def _run_bc(setup: Setup, policies: Sequence[LTLDSPolicy], sensors: Sequence[WorldSensors],
            X: FloatArray, *, steps: int,
            perturb: Callable[[int, int, FloatArray], FloatArray | None]
            ) -> list[EpisodeResult]:
    """:func:`run_episodes` with the BC nets moving the state (modulated by the cuts the
    executive learns for the mode's region, :func:`tli_verify.boundary.modulation.modulated`)."""
    from tli_verify.boundary.modulation import modulated

    if not setup.bc:
        raise TliError("the BC variant needs BC nets (learn_setup(..., bc_epochs=...))")
    X = X.copy()
    N = len(X)
    for i, (pol, sen) in enumerate(zip(policies, sensors, strict=True)):
        sen.reset(X[i].copy())
        pol.reset(X[i], sen.read(X[i]))
    dt = policies[0].dt
    cache: dict[tuple[str, int], Any] = {}
    hist = [X.copy()]
    modes = [[p.mode for p in policies]]
    astates = [[-1 if p.state is None else p.state for p in policies]]
    active = np.ones(N, dtype=bool)
    taken = np.zeros(N, dtype=np.int64)
    for _ in range(steps):
        groups: dict[tuple[str, int, int], list[int]] = {}
        for i in np.flatnonzero(active).tolist():
            pol = policies[i]
            if pol.done and not pol.holding:
                active[i] = False
                continue
            pushed = perturb(i, int(taken[i]) + 1, X[i].copy())
            if pushed is not None:
                X[i] = pushed
            key = pol.decide(X[i], sensors[i].read(X[i]), perturbed=pushed is not None)
            taken[i] += 1
            if key:
                groups.setdefault((key, id(pol.model), i if pol.model.modes[key].cuts else -1),
                                  []).append(i)
        if not active.any():
            break
        V = np.zeros_like(X)
        for (key, _, _), rows in groups.items():
            mm = policies[rows[0]].model.modes[key]
            net = setup.bc.get(key) or setup.bc[mm.mode]
            if not mm.cuts:
                V[rows] = net.velocity(X[rows])
                continue
            ck = (key, id(mm))
            if ck not in cache:
                cache[ck] = modulated(net, mm.cuts, mm.ds.attractor, dt=dt)
            V[rows] = cache[ck].velocity(X[rows])
        X += dt * V
        hist.append(X.copy())
        modes.append([p.mode for p in policies])
        astates.append([-1 if p.state is None else p.state for p in policies])
    return batch_results(policies, hist, modes, astates, taken)


def mode_runs(seq: Sequence[Any]) -> list[list[Any]]:
    """Run-length form ``[[value, first_step], ...]`` of a per-step sequence."""
    out: list[list[Any]] = []
    for t, v in enumerate(seq):
        if not out or out[-1][0] != v:
            out.append([v, t])
    return out


def mode_string(res: EpisodeResult) -> str:
    """The modes visited, in order (``"abcd"``, ``"ababab..."``)."""
    return "".join(str(v) for v, _ in mode_runs(res.modes))


def episode_json(res: EpisodeResult, *, world: str, variant: str, seconds: float,
                 x0: FloatArray, perturbations: Mapping[int, npt.ArrayLike],
                 dt: float) -> dict[str, Any]:
    """The ``tli run --json`` record of one episode."""
    from tli_verify.runtime.events import event_to_json

    return {
        "world": world,
        "variant": variant,
        "success": bool(res.success),
        "steps": int(res.steps),
        "dt": dt,
        "sim_time": res.steps * dt,
        "seconds": seconds,
        "start": [float(v) for v in x0],
        "final_state": [float(v) for v in res.states[-1]],
        "perturbations": [{"step": int(t),
                           "displacement": np.asarray(d, dtype=np.float64).tolist()}
                          for t, d in sorted(perturbations.items())],
        "mode_sequence": mode_string(res),
        "mode_trace": mode_runs(res.modes),
        "automaton_states": mode_runs(res.automaton_states),
        "cuts_added": int(res.cuts_added),
        "cuts": {m: [c.to_dict() for c in res.model.region_cuts(m)]
                 for m in sorted({mm.mode for mm in res.model.modes.values()})
                 if res.model.region_cuts(m)},
        "events": [event_to_json(e) for e in res.events],
    }


# ----------------------------------------------------------------------------- figure
def plot_episode(world: ScoopWorld, res: EpisodeResult, path: str | os.PathLike[str], *,
                 nominal: EpisodeResult | None = None, title: str | None = None,
                 others: Sequence[tuple[str, EpisodeResult]] = (), label: str = "",
                 zoom_first: bool = False) -> None:
    """A Fig. 7-style picture: regions, cuts, nominal and perturbed trajectory, mode sequence.

    One panel per episode (``res`` first, then ``others``): the true regions, the trajectory
    in black with perturbation jumps in red (dashed), the nominal (unperturbed) run in grey,
    the cuts learned (blue lines), each invariance failure's last in-mode state (yellow
    circle) and failure state (red cross); the mode sequence in the panel title (after
    ``label`` for ``res``, the given labels for ``others``). With ``zoom_first`` the first
    panel is followed by a panel zoomed on the last 400 states of ``res`` (a loop at a
    boundary), drawn by mode (a black, b orange).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.plotting import save_figure

    panels = [(label, res), *others]
    lo, hi = np.array(world.lo), np.array(world.hi)
    ncols = len(panels) + int(zoom_first)
    fig, grid = plt.subplots(1, ncols, figsize=(4.2 * ncols, 4.6), squeeze=False)
    axes = list(grid[0])
    zoom_ax = axes.pop(1) if zoom_first else None
    idx = _region_grid(world)
    for ax, (label, r) in zip(axes, panels, strict=True):
        _draw_regions(ax, world, idx)
        if nominal is not None:
            ax.plot(nominal.states[:, 0], nominal.states[:, 1], color="0.55", lw=1.0,
                    ls="--", label="nominal")
        pushes = {e.step for e in r.events if isinstance(e, Perturbation)}
        S = r.states
        start = 0
        for t in sorted(pushes):  # the push lands between states[t-1] and states[t]
            ax.plot(S[start:t, 0], S[start:t, 1], color="k", lw=1.2)
            if t < len(S):
                ax.plot(S[t - 1:t + 1, 0], S[t - 1:t + 1, 1], color="tab:red", lw=1.2, ls="--")
            start = t
        ax.plot(S[start:, 0], S[start:, 1], color="k", lw=1.2)
        ax.plot(S[0, 0], S[0, 1], "ko", ms=4)
        for mode in sorted({mm.mode for mm in r.model.modes.values()}):
            for c in r.model.region_cuts(mode):
                _draw_cut(ax, c)
        for e in r.events:
            if isinstance(e, InvarianceFailure):
                ax.plot(*e.last_inside, "o", mfc="gold", mec="k", ms=6)
                ax.plot(*e.outside, "x", color="tab:red", ms=7, mew=2)
        seq = mode_string(r)
        if len(seq) > 14:
            seq = seq[:12] + "..."
        goal = "d" if world.name == "scoop" else "the goal"
        verdict = f"reaches {goal}" if r.success else f"no {goal} in {r.steps} steps"
        cuts = f"{r.cuts_added} cut{'' if r.cuts_added == 1 else 's'}"
        ax.set_title(f"{label + ': ' if label else ''}{seq} ({verdict}, {cuts})", fontsize=9)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        scoop = world.name == "scoop"
        ax.set_xlabel("x1 (spoon orientation)" if scoop else "x1", fontsize=8)
        ax.set_ylabel("x2 (distance to soup)" if scoop else "x2", fontsize=8)
    if zoom_ax is not None:
        _zoom_panel(zoom_ax, world, res, idx)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)


def _region_grid(world: ScoopWorld) -> npt.NDArray[np.int64]:
    """The true region index on a 300 x 300 grid of the workspace, shape (300, 300)."""
    lo, hi = np.array(world.lo), np.array(world.hi)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 300), np.linspace(lo[1], hi[1], 300))
    return world.region_index(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)


def _draw_regions(ax: Any, world: ScoopWorld, idx: npt.NDArray[np.int64]) -> None:
    """The world's true regions in their colours (the background of the episode pictures)."""
    from matplotlib.colors import ListedColormap

    lo, hi = np.array(world.lo), np.array(world.hi)
    ax.imshow(idx, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]),
              cmap=ListedColormap(list(world.region_colors)), vmin=-0.5,
              vmax=len(world.region_names) - 0.5, interpolation="nearest")


def _draw_cut(ax: Any, cut: Any) -> None:
    """A learned cut's line (2-D), in blue."""
    w, p = np.asarray(cut.normal), np.asarray(cut.point)
    d = np.array([-w[1], w[0]])
    s = np.linspace(-40, 40, 2)
    ax.plot(p[0] + s * d[0], p[1] + s * d[1], color="tab:blue", lw=1.5)


def animate_episode(world: ScoopWorld, res: EpisodeResult, path: str | os.PathLike[str], *,
                    frames: int = 120, fps: int = 20, title: str = "") -> int:
    """An animated GIF of one episode (Fig. 7 style), written atomically.

    Each frame shows the true regions, the path so far (black; perturbation jumps are not
    joined), the current state (red), the cuts learned so far (blue, from each
    :class:`~tli_verify.runtime.events.CutAdded`'s step) and the step and mode in the title.

    Parameters
    ----------
    world : World
    res : EpisodeResult
    path : path-like
        The GIF file.
    frames : int, optional
        At most this many frames, evenly spaced over the episode's states.
    fps : int, optional
    title : str, optional
        Prefix of every frame's title.

    Returns
    -------
    int
        Frames written.
    """
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from tli_verify.io import atomic_write_bytes

    S = res.states
    pushes = sorted(e.step for e in res.events if isinstance(e, Perturbation))
    cuts = sorted(((e.step, e.cut) for e in res.events if isinstance(e, CutAdded)),
                  key=lambda sc: sc[0])
    shown = np.unique(np.linspace(0, len(S) - 1, max(1, min(frames, len(S)))).astype(int))
    lo, hi = np.array(world.lo), np.array(world.hi)
    fig, ax = plt.subplots(figsize=(4.4, 4.6))
    _draw_regions(ax, world, _region_grid(world))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    (path_line,) = ax.plot([], [], color="k", lw=1.2)
    (dot,) = ax.plot([], [], "o", color="tab:red", ms=6)
    drawn = 0
    images = []
    for t in shown:
        P = S[: t + 1]
        breaks = [k for k in pushes if k <= t]  # a push lands between states[k-1] and [k]
        P = np.insert(P, breaks, np.nan, axis=0) if breaks else P
        path_line.set_data(P[:, 0], P[:, 1])
        dot.set_data([S[t, 0]], [S[t, 1]])
        while drawn < len(cuts) and cuts[drawn][0] <= t:
            _draw_cut(ax, cuts[drawn][1])
            drawn += 1
        ax.set_title(f"{title + ': ' if title else ''}step {t}, mode {res.modes[t]}, "
                     f"{drawn} cut{'' if drawn == 1 else 's'}", fontsize=9)
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())  # type: ignore[attr-defined]
        images.append(Image.fromarray(rgba[..., :3]).convert("P", palette=Image.Palette.ADAPTIVE))
    plt.close(fig)
    buffer = io.BytesIO()
    images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:],
                   duration=max(1, round(1000 / fps)), loop=0)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic_write_bytes(path, buffer.getvalue())
    return len(images)


def _zoom_panel(ins: Any, world: ScoopWorld, res: EpisodeResult,
                idx: npt.NDArray[np.int64]) -> None:
    """A panel around the last 400 states of ``res``, modes coloured (a black, b orange),
    the last failure states as red crosses."""
    S = res.states[-400:]
    c = S.mean(axis=0)
    half = max(0.3, 0.6 * float(np.max(S.max(axis=0) - S.min(axis=0))))
    _draw_regions(ins, world, idx)
    modes = res.modes[-400:]
    for i in range(len(S) - 1):
        ins.plot(S[i:i + 2, 0], S[i:i + 2, 1], lw=0.8,
                 color="tab:orange" if modes[i] == "b" else "k")
    outs = np.array([e.outside for e in res.events if isinstance(e, InvarianceFailure)][-60:])
    if len(outs):
        ins.plot(outs[:, 0], outs[:, 1], "x", color="tab:red", ms=3)
    ins.set_xlim(c[0] - half, c[0] + half)
    ins.set_ylim(c[1] - half, c[1] + half)
    ins.set_aspect("equal")
    ins.tick_params(labelsize=7)
    ins.set_title(f"zoom: its last {len(S)} steps (mode a black, b orange)", fontsize=9)
    ins.set_xlabel("x1", fontsize=8)
    ins.set_ylabel("x2", fontsize=8)


# ----------------------------------------------------------------------------- experiment
@dataclass(frozen=True, slots=True)
class ExperimentConfig:
    """The multi-modal experiment (paper appendix "Multi-modal Experiments").

    Attributes
    ----------
    experiments : int
        Learned models (10 in the paper), each from 1-3 demonstrations.
    episodes : int
        Perturbed episodes per experiment and variant (>= 100).
    max_perturbations : int
        Each episode gets 1..this many perturbations (paper Asm. 2: finitely many).
    steps : int
        Step budget per episode (at dt = 1/100 s).
    bc_epochs : int
        BC training epochs (paper: at most 5000).
    seed : int
    lag : int
        Sensor lag of the world (steps).
    """

    experiments: int = 10
    episodes: int = 100
    max_perturbations: int = 3
    steps: int = 3000
    bc_epochs: int = 300
    seed: int = 0
    lag: int = 0


def _episode_plan(cfg: ExperimentConfig, exp: int, world: ScoopWorld
                  ) -> tuple[FloatArray, list[dict[int, FloatArray]]]:
    rng = np.random.default_rng([cfg.seed, exp, 1])
    starts = np.array([random_start(world, rng) for _ in range(cfg.episodes)])
    perts = [random_perturbations(rng, int(rng.integers(1, cfg.max_perturbations + 1)), world)
             for _ in range(cfg.episodes)]
    return starts, perts


def run_experiment(cfg: ExperimentConfig, exp: int) -> dict[str, Any]:
    """One experiment: learn + certify from 1-3 seeded demonstrations, then every variant on
    the same perturbed episodes. Returns a JSON-ready record."""
    t0 = time.perf_counter()
    n_demos = 1 + (cfg.seed + exp) % 3
    with tempfile.TemporaryDirectory(prefix="tli-scoop-") as tmp:
        setup = learn_setup(cfg.seed * 1000 + exp, n_demos, tmp, lag=cfg.lag,
                            bc_epochs=cfg.bc_epochs)
        starts, perts = _episode_plan(cfg, exp, setup.world)
        out: dict[str, Any] = {"experiment": exp, "demos": n_demos, "variants": {}}
        for variant in VARIANTS:
            res = run_variant_batch(setup, variant, starts, perts, steps=cfg.steps)
            out["variants"][variant] = {
                "success": sum(r.success for r in res),
                "episodes": len(res),
                "cuts_mean": float(np.mean([r.cuts_added for r in res])),
                "steps": int(sum(r.steps for r in res)),
                "loops": sum(is_fig7_loop(r, cfg.steps) for r in res),
            }
    out["seconds"] = time.perf_counter() - t0
    return out


def _run_one(args: tuple[Any, ...]) -> dict[str, Any]:
    import threadpoolctl

    with threadpoolctl.threadpool_limits(1):
        if args[0] == "fig7":
            return fig7_search(*args[1:])
        return run_experiment(*args)


def run_all(cfg: ExperimentConfig, *, workers: int = 2, fig7_tries: int = 0
            ) -> dict[str, Any]:
    """Every experiment (a process pool of ``workers``) and the totals per variant.

    With ``fig7_tries > 0`` the Fig. 7 search (:func:`fig7_search`) runs as one more job of
    the pool; its result is under ``"fig7"`` (with the episodes, not JSON-ready).
    """
    t0 = time.perf_counter()
    jobs: list[tuple[Any, ...]] = [(cfg, e) for e in range(cfg.experiments)]
    if fig7_tries > 0:
        jobs.insert(0, ("fig7", cfg.seed, fig7_tries, cfg.steps, cfg.lag))
    if workers <= 1:
        done = [_run_one(j) for j in jobs]
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            done = list(pool.map(_run_one, jobs))
    fig7 = done.pop(0) if fig7_tries > 0 else None
    rows = done
    totals = {}
    for v in VARIANTS:
        ok = sum(r["variants"][v]["success"] for r in rows)
        n = sum(r["variants"][v]["episodes"] for r in rows)
        totals[v] = {"success": ok, "episodes": n, "percent": 100.0 * ok / max(n, 1),
                     "loops": sum(r["variants"][v]["loops"] for r in rows),
                     "per_experiment": [100.0 * r["variants"][v]["success"]
                                        / max(r["variants"][v]["episodes"], 1) for r in rows],
                     "policy_steps": sum(r["variants"][v]["steps"] for r in rows)}
    return {"config": {f: getattr(cfg, f) for f in cfg.__dataclass_fields__},
            "workers": workers, "seconds": time.perf_counter() - t0,
            "experiments": rows, "totals": totals, "fig7": fig7}


def fig7_search(seed: int, tries: int, steps: int, lag: int = 0) -> dict[str, Any]:
    """The Fig. 7 search on the shipped model (:func:`find_loop`), in two stages.

    1. Perturbations of the nominal run: from :data:`NOMINAL_START`, ``tries`` seeded single
       random perturbations (:func:`random_perturbations` within the nominal run's steps,
       displacements rounded to 0.01 so the case replays from the command line).
    2. If none loops: ``tries`` seeded random starts (reading ``a``), unperturbed.

    Returns
    -------
    dict
        ``{"lag", "stage", "tries", "seed", "found", "text"}``; ``found`` is :func:`find_loop`'s
        record (with the episodes, not JSON-ready; :func:`fig7_record` makes it so) or None.
    """
    setup = bundled_setup(lag=lag)
    tried = []
    for stage, start in (("perturbed nominal run", NOMINAL_START), ("random start", None)):
        f = find_loop(setup, seed=seed, tries=tries, steps=steps, start=start,
                      perturbations=1 if start is not None else 0)
        tried.append(f"{stage}: {tries} tries, " + ("none" if f is None else
                                                    f"found at try {f['index']}"))
        if f is not None:
            return {"lag": lag, "stage": stage, "tries": tries, "seed": seed, "found": f,
                    "text": _fig7_text(f, lag, stage, tries)}
    return {"lag": lag, "stage": None, "tries": tries, "seed": seed, "found": None,
            "text": f"Fig. 7 NOT found (seed {seed}, sensor lag {lag}): no try made the "
                    f"unmodulated system loop a -> b -> a ... (>= {FIG7_MIN_ROUNDS} b -> a "
                    "failures) until its step budget ran out while LTL-DS reached d after "
                    "exactly one cut (" + "; ".join(tried) + ")."}


def _replay_args(f: Mapping[str, Any]) -> str:
    """The ``tli run`` arguments that replay a Fig. 7 case (start, perturbations)."""
    x0 = ",".join(repr(float(v)) for v in f["start"])
    parts = [f"--start={x0}"]
    for t, d in sorted(f["perturbations"].items()):
        parts.append(f"--perturb {int(t)}:" + ",".join(repr(float(v)) for v in d))
    return " ".join(parts)


def _fig7_text(f: Mapping[str, Any], lag: int, stage: str, tries: int) -> str:
    p, r = f["no_modulation"], f["ltl_ds"]
    seq_p = mode_string(p)
    return (f"Fig. 7 reproduced ({stage}, try {f['index']} of {tries}, sensor lag {lag}): from "
            f"{np.round(f['start'], 2).tolist()} with {len(f['perturbations'])} "
            f"perturbation(s), without modulation the modes run {seq_p[:12]}... -- mode b's DS "
            "leaves the soup back into white (a b -> a invariance failure) and a's DS brings "
            f"the spoon straight back, {f['loops']} times, until the budget of {p.steps} "
            f"steps runs out; LTL-DS runs {mode_string(r)}: the first b -> a failure adds "
            f"{r.cuts_added} cut to mode b, which is never crossed again, and d is reached at "
            f"step {r.steps}. Replay: tli run --world scoop {_replay_args(f)} "
            "[--no-modulation].")


# ----------------------------------------------------------------------------- Fig. 7 search
NOMINAL_START = np.array([-5.0, 4.0])
"""The documented start of the nominal scoop run (white, upper left; reaches d unperturbed)."""
FIG7_MIN_ROUNDS = 5
"""A Fig. 7 loop: at least this many ``b -> a`` invariance failures without modulation."""


def b_to_a_failures(res: EpisodeResult) -> int:
    """Number of ``b -> a`` invariance failures (the scooping DS leaving the soup into white)."""
    return sum(1 for e in res.events
               if isinstance(e, InvarianceFailure) and (e.mode, e.to_mode) == ("b", "a"))


def is_fig7_loop(res: EpisodeResult, budget: int, *,
                 min_rounds: int = FIG7_MIN_ROUNDS) -> bool:
    """Fig. 7's top row: no ``d`` within the whole step budget, at least ``min_rounds``
    ``b -> a`` invariance failures, and still looping ``a -> b -> a ...`` at the end (the last
    ``2 * min_rounds`` modes of the run-length mode sequence are a and b, so they alternate)."""
    tail = mode_string(res)[-2 * min_rounds:]
    return (not res.success and res.steps == budget
            and b_to_a_failures(res) >= min_rounds
            and len(tail) == 2 * min_rounds and set(tail) == {"a", "b"})


def is_fig7_rescue(res: EpisodeResult) -> bool:
    """Fig. 7's LTL-DS rows: ``d`` reached after exactly one invariance failure, ``b -> a``,
    and the one cut it produced (for mode b)."""
    fails = [e for e in res.events if isinstance(e, InvarianceFailure)]
    cuts = [e for e in res.events if isinstance(e, CutAdded)]
    return (res.success and res.cuts_added == 1 and len(fails) == 1
            and (fails[0].mode, fails[0].to_mode) == ("b", "a")
            and len(cuts) == 1 and cuts[0].mode == "b")


def _rounded_perturbations(rng: np.random.Generator, count: int, world: ScoopWorld, *,
                           last: int) -> dict[int, FloatArray]:
    table = random_perturbations(rng, count, world, last=last)
    return {t: np.array([float(f"{v:.2f}") for v in d]) for t, d in table.items()}


def find_loop(setup: Setup, *, seed: int = 0, tries: int = 200, steps: int = 3000,
              start: npt.ArrayLike | None = None, perturbations: int = 1,
              verify: int = 20, min_rounds: int = FIG7_MIN_ROUNDS) -> dict[str, Any] | None:
    """Search seeded episodes for Fig. 7 (top row vs. second row).

    Fig. 7: without modulation the system loops ``a -> b -> a -> b ...`` (mode b's DS leaves
    the soup back into white, a's DS brings the spoon back, again and again) until its step
    budget runs out (:func:`is_fig7_loop`); LTL-DS reaches ``d`` after the one cut that the
    first ``b -> a`` failure produces (:func:`is_fig7_rescue`).

    Each try is ``start`` (default: a seeded random start reading ``a``) with ``perturbations``
    seeded random perturbations (within the unperturbed run's steps from a given ``start``,
    else within 700 steps; displacements rounded to 0.01), run without modulation (batched);
    LTL-DS runs on the first ``verify`` tries that loop, in order.

    Returns
    -------
    dict or None
        ``{"start", "perturbations", "index", "loops", "no_modulation", "ltl_ds"}`` of the
        first try that loops without modulation and is rescued by LTL-DS; None if none is.
    """
    rng = np.random.default_rng([seed, 7])
    if start is not None:
        x0 = np.asarray(start, dtype=np.float64)
        last = max(1, run_variant(setup, "no-modulation", x0, {}, steps=steps).steps)
        starts = np.tile(x0, (tries, 1))
    else:
        last = 700
        starts = np.array([random_start(setup.world, rng) for _ in range(tries)])
    perts = [_rounded_perturbations(rng, perturbations, setup.world, last=last)
             if perturbations else {} for _ in range(tries)]
    plain = run_variant_batch(setup, "no-modulation", starts, perts, steps=steps)
    order = [i for i in range(tries) if is_fig7_loop(plain[i], steps, min_rounds=min_rounds)]
    order = order[:verify]
    if not order:
        return None
    ours = run_variant_batch(setup, "LTL-DS", starts[order], [perts[i] for i in order],
                             steps=steps)
    for i, r in zip(order, ours, strict=True):
        if is_fig7_rescue(r):
            return {"start": starts[i], "perturbations": perts[i], "index": i,
                    "loops": b_to_a_failures(plain[i]), "no_modulation": plain[i],
                    "ltl_ds": r}
    return None


def fig7_record(search: Mapping[str, Any]) -> dict[str, Any]:
    """The JSON-ready Fig. 7 field of ``tli experiment scoop`` (from :func:`fig7_search`).

    ``found`` false: only the text. Otherwise the case (seed, stage, try, start,
    perturbations, the ``tli run`` replay arguments) and both episodes: the unmodulated one
    (mode sequence and run-length trace, ``b -> a`` failures, budget exhausted) and LTL-DS's
    (trace, its invariance failure and the cut it added).
    """
    from tli_verify.runtime.events import event_to_json

    out: dict[str, Any] = {"text": search["text"], "lag": search["lag"],
                           "found": search["found"] is not None, "seed": search["seed"],
                           "tries": search["tries"], "stage": search["stage"]}
    f = search["found"]
    if f is None:
        return out
    p, r = f["no_modulation"], f["ltl_ds"]
    out.update({
        "index": int(f["index"]),
        "start": [float(v) for v in f["start"]],
        "perturbations": [{"step": int(t), "displacement": [float(v) for v in d]}
                          for t, d in sorted(f["perturbations"].items())],
        "replay": f"tli run --world scoop {_replay_args(f)}",
        "no_modulation": {
            "success": bool(p.success), "steps": int(p.steps),
            "budget_exhausted": bool(not p.success),
            "b_to_a_failures": b_to_a_failures(p),
            "ab_rounds": mode_string(p).count("ab"),
            "mode_sequence": mode_string(p),
            "mode_trace": mode_runs(p.modes),
        },
        "ltl_ds": {
            "success": bool(r.success), "steps": int(r.steps),
            "cuts_added": int(r.cuts_added),
            "mode_sequence": mode_string(r),
            "mode_trace": mode_runs(r.modes),
            "events": [event_to_json(e) for e in r.events
                       if isinstance(e, InvarianceFailure | CutAdded)],
        },
    })
    return out


def plot_fig7(world: ScoopWorld, search: Mapping[str, Any],
              path: str | os.PathLike[str]) -> None:
    """Fig. 7-style picture of a case :func:`fig7_search` found (PNG, atomic).

    Three panels (:func:`plot_episode`): the unmodulated run looping until its budget, its
    last 400 steps zoomed on the loop at the soup's surface, and LTL-DS with the cut it added
    (blue); the unperturbed run from the same start is dashed grey.

    Raises
    ------
    TliError
        The search found no case.
    """
    f = search["found"]
    if f is None:
        raise TliError("no Fig. 7 case to draw (the search found none)")
    p, r = f["no_modulation"], f["ltl_ds"]
    nominal = None
    if f["perturbations"]:
        nominal = run_variant(bundled_setup(lag=search["lag"]), "no-modulation", f["start"],
                              {}, steps=p.steps)
    plot_episode(world, p, path, nominal=nominal, label="no modulation",
                 others=[("LTL-DS", r)], zoom_first=True,
                 title=f"Fig. 7: without modulation a -> b -> a ... until the budget "
                       f"({b_to_a_failures(p)} b -> a failures in {p.steps} steps); LTL-DS "
                       "cuts the first b -> a failure (blue) and reaches d")


# ----------------------------------------------------------------------------- report
def write_report(summary: Mapping[str, Any], out: Path, *, fig7: Mapping[str, Any] | None,
                 fig7_png: Path | None) -> list[Path]:
    """``scoop.json``, ``scoop.md`` and ``scoop_success.png`` under ``out`` (atomic)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tli_verify.io import atomic_write_text, canonical_json
    from tli_verify.plotting import save_figure

    out.mkdir(parents=True, exist_ok=True)
    cfg = summary["config"]
    tot = summary["totals"]
    lines = [
        "# Multi-modal soup-scooping experiment (paper Sec. 7.2, appendix \"Multi-modal "
        "Experiments\")", "",
        f"{cfg['experiments']} experiments (each: LPV-DS learned and certified at dt = 1/100 "
        f"from 1-3 seeded demonstrations of the scoop world), {cfg['episodes']} perturbed "
        f"episodes per experiment and variant, 1-{cfg['max_perturbations']} perturbations per "
        "episode in uniformly random directions with magnitudes uniform up to the workspace "
        f"size (16), step budget {cfg['steps']} (dt = 0.01 s), sensor lag {cfg['lag']}, "
        f"seed {cfg['seed']}. Wall time {summary['seconds']:.1f} s on {summary['workers']} "
        "worker(s).", "",
        "| variant | success | episodes | success % | per experiment (%) | Fig. 7 loops |",
        "|---|---:|---:|---:|---|---:|",
    ]
    for v in VARIANTS:
        t = tot[v]
        per = ", ".join(f"{p:.0f}" for p in t["per_experiment"])
        lines.append(f"| {v} | {t['success']} | {t['episodes']} | {t['percent']:.1f} | {per} "
                     f"| {t['loops']} |")
    lines += ["", "Variants: **LTL-DS** = task automaton + certified DS per mode + cuts "
              "learned online + replanning; **no-modulation** = the same without cuts; "
              "**no-replan** = the demonstrated mode sequence run open loop (cuts kept); "
              "**BC** = the paper's MLP per mode under the automaton (replanning, cuts). "
              f"**Fig. 7 loops**: episodes still looping a -> b -> a ... (>= {FIG7_MIN_ROUNDS} "
              "b -> a invariance failures) when the step budget ran out.", ""]
    if fig7 is not None:
        lines += ["## Fig. 7", "", fig7["text"], ""]
        if fig7_png is not None:
            lines += [f"![Fig. 7]({fig7_png.name})", ""]
    md = out / "scoop.md"
    js = out / "scoop.json"
    png = out / "scoop_success.png"
    atomic_write_text(md, "\n".join(lines) + "\n")
    atomic_write_text(js, canonical_json(dict(summary)))
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    vals = [tot[v]["percent"] for v in VARIANTS]
    ax.bar(VARIANTS, vals, color=["tab:blue", "tab:orange", "tab:green", "tab:red"])
    for i, v in enumerate(vals):
        ax.text(i, v + 1, f"{v:.0f}%", ha="center", fontsize=8)
    ax.set_ylim(0, 110)
    ax.set_ylabel("success %")
    ax.set_title("scoop: perturbed episodes reaching d", fontsize=9)
    fig.tight_layout()
    save_figure(fig, png, dpi=90)
    return [md, js, png]
