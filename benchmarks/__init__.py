"""Benchmarks run by ``make bench``: side-by-side comparisons against named baselines."""
