"""Subcommand groups of the ``tli`` CLI; each module exposes ``register(subparsers)``."""
