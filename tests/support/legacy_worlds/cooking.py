"""The cooking world of the paper's generalization experiment (Sec. 7.2, appendix "Generalization").

Adding chicken and broccoli to a pot (paper Fig. "Reuse learned DS"): white (empty spoon),
yellow (chicken), green (broccoli) and dark (the pot). The paper gives no coordinates; ours
(workspace ``[0, 10]^2``) put the two ingredients on either side of the pot, so that every
sensor change the specs' assumptions allow is a shared boundary and no other is:

* **dark** (pot): ``3 <= x1 <= 7`` and ``x2 >= 7``;
* **yellow** (chicken): ``x1 < 3`` and ``x2 >= 5``;
* **green** (broccoli): ``x1 > 7`` and ``x2 >= 5``;
* **white**: the rest (the lower band ``x2 < 5`` and the middle ``3 <= x1 <= 7, x2 < 7``).

Chicken and broccoli each touch white and the pot, the pot touches white, and chicken and
broccoli do not touch (the assumptions ``white -> white|ch|br``, ``ch -> ch|white|pot``,
``br -> br|white|pot``, ``pot -> pot|white`` of ``specs/cooking-*.toml``). Sensors: ``ch`` and
``br`` are the memberships of yellow and green; ``pot`` means "food dropped in the pot": the
spoon is in the dark region and entered it carrying food (from yellow or green), a latent bit
that lasts while the spoon stays in the pot. An empty spoon over the pot reads white, so the
change ``white -> pot``, which the assumptions rule out, cannot happen even though white and
the pot share a boundary. The changes the assumptions still rule out are geometric ones the
nominal task never makes: from the pot straight into yellow or green (the spoon leaves the pot
to white first), and jumps between yellow and green; under a perturbation the executive
reports them as assumption violations.

Three scripted demonstrations: one per order (paper Fig. (a)), chicken first (white -> yellow ->
dark -> white -> green -> dark, ``specs/cooking-cb.toml``) and broccoli first (white -> green ->
dark -> white -> yellow -> dark, ``specs/cooking-bc.toml``), and a detour (white -> green ->
white -> yellow -> dark: the green -> white that ``specs/cooking-c.toml`` runs after a push into
the broccoli, demonstrated by no order). Learned once without a spec they give one DS per
demonstrated *sensor* transition, named by the readings (``tli learn`` without ``--spec``);
:func:`tli_verify.rebind.rebind_model` binds that one set of DS, bit for bit, to each of
the four automata of ``cooking-cb/bc/c/cc`` through their mode labels
(``scripts/make_models.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from tests.support.legacy_worlds.base import BoolArray, FloatArray, IntArray, WorldBase
from tli_verify.demos import Demonstration

__all__ = ["CookingWorld"]

POT = np.array([5.0, 8.5])
CHICKEN = np.array([1.5, 7.8])
BROCCOLI = np.array([8.5, 7.8])


@dataclass(frozen=True, slots=True)
class CookingWorld(WorldBase):
    """The chicken-and-broccoli cooking world (module docstring).

    Attributes
    ----------
    lag : int
        Sensor lag in steps (default 0).
    duration : float
        Seconds per demonstration.
    dt : float
        Sampling period (s).
    """

    duration: float = 16.0
    dt: float = 0.05

    name: ClassVar[str] = "cooking"
    specs: ClassVar[tuple[str, ...]] = ("cooking-cb.toml", "cooking-bc.toml", "cooking-c.toml",
                                        "cooking-cc.toml")
    sensor_names: ClassVar[tuple[str, ...]] = ("ch", "br", "pot")
    latent_names: ClassVar[tuple[str, ...]] = ("ch", "br", "pot")
    region_names: ClassVar[tuple[str, ...]] = ("white", "yellow", "green", "dark")
    region_colors: ClassVar[tuple[str, ...]] = ("#ffffff", "#f7e27a", "#9ed99b", "#555555")
    lo: ClassVar[tuple[float, ...]] = (0.0, 0.0)
    hi: ClassVar[tuple[float, ...]] = (10.0, 10.0)

    def region_index(self, X: npt.ArrayLike) -> IntArray:
        """0 white, 1 yellow (chicken), 2 green (broccoli), 3 dark (pot), shape (N,)."""
        Xa = np.asarray(X, dtype=np.float64)
        x1, x2 = Xa[..., 0], Xa[..., 1]
        idx = np.zeros(x1.shape, dtype=np.int64)
        idx[(x1 < 3.0) & (x2 >= 5.0)] = 1
        idx[(x1 > 7.0) & (x2 >= 5.0)] = 2
        idx[(x1 >= 3.0) & (x1 <= 7.0) & (x2 >= 7.0)] = 3
        return idx

    def read(self, x_prev: FloatArray, x: FloatArray, latent: BoolArray
             ) -> tuple[BoolArray, BoolArray]:
        """``(ch, br, pot)`` and the latent reading ``(ch, br, pot)`` (module docstring).

        ``ch``, ``br``: in yellow, in green; ``pot`` = in dark and (``pot`` or ``ch`` or ``br``
        at the previous reading).
        """
        idx = self.region_index(x)
        ch, br = idx == 1, idx == 2
        pot = (idx == 3) & np.any(latent, axis=1)
        reading = np.stack([ch, br, pot], axis=1)
        return reading, reading.copy()

    def demonstrate(self, seed: int, n_demos: int | None = None) -> list[Demonstration]:
        """Demonstrations cycling three scripts: chicken first, broccoli first, a detour.

        Default 3 (one per script). Waypoints (jittered with the seed):

        * chicken first / broccoli first: a start in the lower white band, the first
          ingredient, the pot, back out below the pot, the second ingredient, the pot
          (readings white -> yellow|green -> dark -> white -> green|yellow -> dark);
        * the detour (``specs/cooking-c.toml``: "a detour into the broccoli region returns to
          white"): a start, the broccoli region, back out to white below the pot, the chicken,
          the pot (white -> green -> white -> yellow -> dark). It is the only demonstration of
          green -> white, the ``g -> w`` that cooking-c's automaton plans after a push into
          the broccoli (paper Asm. 3: every DS the automaton can run needs demonstration data).
        """
        rng = np.random.default_rng(seed)
        out = []
        for i in range(3 if n_demos is None else int(n_demos)):
            kind = i % 3
            first, second = (CHICKEN, BROCCOLI) if kind == 0 else (BROCCOLI, CHICKEN)
            start = np.array([5.0, 1.5]) + rng.uniform(-1.0, 1.0, size=2)
            j = 0.2 * rng.normal(size=(5, 2))
            if kind == 2:
                waypoints = np.vstack([
                    start,
                    BROCCOLI + j[0],
                    np.array([5.0, 4.0]) + j[1],  # back to white, broccoli not taken
                    CHICKEN + j[3],
                    POT + 0.5 * j[4],
                ])
                out.append(self._demo(f"{i + 1} (detour)", waypoints, self.duration, self.dt))
                continue
            waypoints = np.vstack([
                start,
                first + j[0],
                POT + j[1],
                np.array([5.0, 4.5]) + j[2],  # out of the pot, empty spoon
                second + j[3],
                POT + 0.5 * j[4],
            ])
            order = "chicken-first" if kind == 0 else "broccoli-first"
            out.append(self._demo(f"{i + 1} ({order})", waypoints, self.duration, self.dt))
        return out
