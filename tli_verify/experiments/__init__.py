"""Reproductions of the paper's experiments (single-mode study: :mod:`.single_mode`)."""
