"""tli-verify: Temporal Logic Imitation (LTL-DS) with certificates anyone can re-check.

The package follows the data flow of ``docs/design.md``::

    spec -> automaton, demos -> modes -> DS -> certificate -> cuts/modulation -> policy -> gate

Heavy dependencies (Spot, CUDD, cvxpy) are imported lazily so ``tli --help`` stays fast.
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

__all__ = ["__version__", "load_model"]


def load_model(path: Any) -> Any:
    """Load a model file (see :func:`tli_verify.model.load_model`)."""
    from tli_verify.model import load_model as _load

    return _load(path)
