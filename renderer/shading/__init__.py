"""Shader programs: a material's node tree compiled at export to a flat list of operations
(program.py), run per shading point by one numba interpreter (interpreter.py). The node
math lives in one file per family (math_ops.py, textures.py, image.py); the kernel tables
are built by table.py and the surface stage that applies them is stage.py."""
