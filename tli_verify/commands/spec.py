"""Subcommands of this group are registered here as their capability lands."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def register(sub: argparse._SubParsersAction[Any]) -> None:
    """Register this group's subcommands (none yet)."""
    del sub


def demo_stage(out: Path) -> list[str]:
    """Run this group's part of ``make demo``; return one summary line per result."""
    del out
    return []
