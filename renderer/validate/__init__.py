"""The scene validator: everything any Scene can get wrong, in-memory or loaded from a file.

`validate_scene(scene)` is the one entry: it conforms every field to its annotation and
checks what types cannot say: value ranges, the vocabulary of renderer.scene, unique names
and the references between objects, array shapes and index ranges, invertible transforms.
The compilers downstream rely on it. Every problem is a SceneError whose message starts
with the field path, e.g. `meshes[2].vertices`.

By concern:
- renderer.validate.scene: the Scene and its parts (camera, film, integrator, materials,
  meshes, lights, environment, names and references, path growth);
- renderer.validate.media: a medium (coefficients, grids, box and transform);
- renderer.validate.checks: the small checks every part shares (choices, colours,
  magnitudes, coordinates, directions, names, transforms);
- renderer.validate.conform: a value conformed to its annotation (types, finiteness,
  dtypes), shared with the loader (renderer.scenefile).

The table builders check the one part they build on its own (`validate_material` for
renderer.bsdfs.table, `validate_medium` for renderer.media.compile): the same rules, one copy.
"""

from __future__ import annotations

from renderer.validate.media import validate_medium
from renderer.validate.scene import validate_material, validate_scene

__all__ = ["validate_scene", "validate_material", "validate_medium"]
