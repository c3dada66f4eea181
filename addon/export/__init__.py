"""Blender scene export: the evaluated depsgraph to a renderer.scene.Scene.

Submodules import the renderer's scene description, so they are imported only when a
render or export starts (see engine.py); `messages` and `validate` are safe to import any time.
"""
