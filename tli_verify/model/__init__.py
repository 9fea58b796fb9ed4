"""The model file: one LPV-DS (and its cuts) per mode or mode transition.

Format (JSON, validated against the published schema ``tli_verify/schemas/model.schema.json``
and then semantically: dimensions, symmetry, every number within ``|v| <= 1e6``, covariances
positive definite with bounded eigenvalues and condition number, priors summing to 1, unit cut
normals; the limits are in :mod:`tli_verify.limits` and :func:`numeric_limits`)::

    {
      "schema_version": 1,
      "state_names": ["x0", "x1"],
      "spec": "../specs/scoop.toml",          # relative to the model file, or null
      "source": {"tool": "tli-verify 0.1.0", "demos": [{"path": "...", "sha256": "..."}]},
      "modes": {
        "a": {
          "mode": "a", "next_mode": "b",      # optional for plain keys
          "attractor": [x*_0, x*_1],
          "P": [[..], [..]],                  # V(x) = (x - x*)^T P (x - x*)
          "components": [{"prior": pi_k, "mean": [..], "cov": [[..]], "A": [[..]]}, ...],
          "cuts": [{"normal": [..], "point": [..]}],
          "fit": {"clustering": "pc-gmm", "lyapunov": "p-qlf", "eps": 0.001, ...}
        },
        "b->c": {"mode": "b", "next_mode": "c", ...}   # a per-transition DS (appendix G)
      }
    }

The DS of a key is ``f(x) = sum_k gamma_k(x) A_k (x - x*)`` (paper eq. 4) and the policy of the
mode is the modulated ``M(x) f(x)`` (paper eq. 7, Sec. 5.2) once the mode has cuts.
Floats are written with ``repr`` precision, so a saved model reloads bit-for-bit -- which the
certificate's exact check relies on.

Modules, one job each:

* :mod:`tli_verify.model.types` -- the values: :class:`~tli_verify.model.types.ModeModel`,
  :class:`~tli_verify.model.types.Model` (validated on construction), the numeric limits;
* :mod:`tli_verify.model.serialize` -- the file: parse (schema, then semantics), serialize
  (``repr`` floats, canonical JSON), load, save, relocate;
* :mod:`tli_verify.model.learn` -- learning a model from demonstrations (paper Sec. 4.3).
"""

from __future__ import annotations

__all__: list[str] = []
