"""Haze's renderer: a volumetric wavefront path tracer (see docs/architecture.md)."""

__version__ = "0.1.0"  # equals pyproject.toml's and blender_manifest.toml's (tests/test_cli_terminal.py)
