"""Lights: emitting triangles, point, spot and sun lights and a constant environment."""
