"""The tests' shared helpers, each once (imported as `helpers`: pytest puts tests/ on
sys.path, and so does bench.blender.run_blender for the Blender scripts):

* `films`: films rendered through renderer.render, and `assert_same_bits` over every field.
* `blender_runs`: `blender_fixture`, the module fixture of a test file's Blender run.
* `bpy_helpers`: the Blender side (bpy imported inside its functions): enabling Haze, Cycles
  and Haze settings, scene builders, renders to EXR.
* `pass_stage` (the pass tests' stage, both sides) and `block_stats` (t-tests of block means).

Nothing here is imported by renderer/ or addon/ (tests/test_package_imports.py).
"""
