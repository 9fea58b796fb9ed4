"""LTL-DS executive and the one rollout engine (DESIGN: ``runtime/``).

- :mod:`tli_verify.runtime.rollout` -- vectorised Euler rollouts of a state-based policy in one
  region (the single-mode study, batched episodes) and failure extraction;
- :mod:`tli_verify.runtime.online` -- cut learning from invariance failures (paper Sec. 5.2,
  appendix E.3), shared by the study and the executive;
- :mod:`tli_verify.runtime.executive` -- :class:`LTLDSPolicy`, the task automaton running the
  modes' certified, modulated DS (paper eq. 6, Sec. 5, Fig. 7), with online cuts, replanning
  and an assumption monitor, and :func:`run_episode`, the closed loop around it.
"""
