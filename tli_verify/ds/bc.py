"""Behaviour-cloning baseline: a state-based MLP policy (paper appendix E.2, "BC Policy").

The paper's network: two hidden layers of 100 ReLU units, a tanh output rescaled to
``[-50, 50]``, Adam with learning rate 1e-3 for at most 5000 epochs, state/velocity pairs
treated as i.i.d. We train scikit-learn's :class:`~sklearn.neural_network.MLPRegressor` (identity
output) on the targets ``artanh(xdot / 50)`` and evaluate ``50 tanh(net(x))``: the same network
with a tanh output layer, fitted by least squares in the pre-activation space (for velocities far
below the bound, ``artanh(y/50) ~ y/50``, i.e. ordinary least squares on scaled targets). Inputs
are standardised with the training mean and standard deviation. The trained weights are kept in
a frozen :class:`BCPolicy` whose forward pass is plain vectorised numpy.

Unlike an LPV-DS, this policy has no stability certificate: modulation keeps it inside the cuts
(:func:`tli_verify.boundary.modulation.modulated`) but cannot give it reachability (Thm. 1 needs
the Lyapunov function).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from tli_verify.errors import ModelError

__all__ = ["BCPolicy", "train_bc"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True, eq=False)
class BCPolicy:
    """A trained MLP velocity policy ``x -> bound * tanh(net((x - mean) / scale))``.

    Attributes
    ----------
    weights : tuple of ndarray
        Layer matrices, shapes (n, 100), (100, 100), (100, n).
    biases : tuple of ndarray
        Layer biases, shapes (100,), (100,), (n,).
    x_mean, x_scale : ndarray, shape (n,)
        Input standardisation.
    bound : float
        Output bound (50 in the paper).
    epochs : int
        Epochs the optimiser ran.
    converged : bool
        Whether training stopped before the epoch limit.
    """

    weights: tuple[FloatArray, ...]
    biases: tuple[FloatArray, ...]
    x_mean: FloatArray
    x_scale: FloatArray
    bound: float
    epochs: int
    converged: bool

    @property
    def dim(self) -> int:
        """State dimension ``n``."""
        return int(self.x_mean.size)

    def velocity(self, X: npt.ArrayLike) -> FloatArray:
        """Predicted velocities.

        Parameters
        ----------
        X : array_like, shape (N, n)

        Returns
        -------
        ndarray, shape (N, n)
            Each component in ``[-bound, bound]``.
        """
        Xa = np.asarray(X, dtype=np.float64)
        if Xa.ndim != 2 or Xa.shape[1] != self.dim:
            raise ModelError(f"states must have shape (N, {self.dim}), got {Xa.shape}")
        H = (Xa - self.x_mean) / self.x_scale
        last = len(self.weights) - 1
        for i, (Wm, b) in enumerate(zip(self.weights, self.biases, strict=True)):
            H = H @ Wm + b
            if i < last:
                np.maximum(H, 0.0, out=H)
        return np.asarray(self.bound * np.tanh(H))

    def __call__(self, X: npt.ArrayLike) -> FloatArray:
        """Same as :meth:`velocity`."""
        return self.velocity(X)


def train_bc(
    X: npt.ArrayLike,
    Xdot: npt.ArrayLike,
    *,
    seed: int,
    hidden: tuple[int, ...] = (100, 100),
    learning_rate: float = 1e-3,
    max_epochs: int = 5000,
    bound: float = 50.0,
    tol: float = 1e-8,
    patience: int = 50,
) -> BCPolicy:
    """Train the BC baseline (paper appendix E.2).

    Parameters
    ----------
    X : array_like, shape (N, n)
        Demonstrated states.
    Xdot : array_like, shape (N, n)
        Demonstrated velocities.
    seed : int
        Seed of the weight initialisation and the mini-batch order.
    hidden : tuple of int, optional
        Hidden layer widths (ReLU).
    learning_rate : float, optional
        Adam step size.
    max_epochs : int, optional
        Epoch limit (training also stops when the loss stalls, scikit-learn's ``tol``).
    bound : float, optional
        Output bound.
    tol, patience : float, int, optional
        Stop when the training loss (on the scaled targets) improved by less than ``tol`` for
        ``patience`` consecutive epochs (scikit-learn's ``tol`` / ``n_iter_no_change``).

    Returns
    -------
    BCPolicy

    Raises
    ------
    ModelError
        On malformed data.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor

    Xa = np.asarray(X, dtype=np.float64)
    Ya = np.asarray(Xdot, dtype=np.float64)
    if Xa.ndim != 2 or Ya.shape != Xa.shape or Xa.shape[0] < 2:
        raise ModelError(f"BC data must be two (N, n) arrays, got {Xa.shape} and {Ya.shape}")
    if not (np.all(np.isfinite(Xa)) and np.all(np.isfinite(Ya))):
        raise ModelError("BC data must be finite")
    if bound <= 0:
        raise ModelError("bound must be positive")
    mean = Xa.mean(axis=0)
    scale = Xa.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    target = np.arctanh(np.clip(Ya / bound, -1.0 + 1e-6, 1.0 - 1e-6))
    net = MLPRegressor(
        hidden_layer_sizes=hidden,
        activation="relu",
        solver="adam",
        learning_rate_init=learning_rate,
        max_iter=max_epochs,
        random_state=seed,
        shuffle=True,
        tol=tol,
        n_iter_no_change=patience,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        net.fit((Xa - mean) / scale, target)
    epochs = int(net.n_iter_)
    return BCPolicy(
        weights=tuple(np.array(w, dtype=np.float64) for w in net.coefs_),
        biases=tuple(np.array(b, dtype=np.float64) for b in net.intercepts_),
        x_mean=mean,
        x_scale=scale,
        bound=float(bound),
        epochs=epochs,
        converged=epochs < max_epochs,
    )
