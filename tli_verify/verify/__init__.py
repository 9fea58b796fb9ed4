"""Bisimulation campaigns (issue 12)."""
