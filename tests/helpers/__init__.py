"""The tests' shared helpers, each once (imported as `helpers`: pytest puts tests/ on
sys.path, and so does bench.blender.run_blender for the Blender scripts):

* `films`: films rendered through renderer.render, and `assert_same_bits` over every field.
* `blender_runs`: `blender_fixture`, the module fixture of a test file's Blender run.
* The Blender side (enabling Haze, Cycles and Haze settings, scene builders, renders to
  EXR) is examples/bpy_helpers.py, beside the example scenes it builds on, since the
  benchmarks use it too and nothing outside tests/ imports from tests/.
* `pass_stage` (the pass tests' stage, both sides) and `block_stats` (t-tests of block means).

Nothing here is imported by renderer/ or addon/ (tests/test_package_imports.py).
"""
