"""Benchmarks that print figures (never timed tests): `python -m renderer.bench [speed|convergence]`."""
