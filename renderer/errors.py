"""The one exception type for bad scene descriptions.

Every problem found while loading or validating a scene is reported as a SceneError whose
message starts with the field path (e.g. `meshes[2].vertices`), so a user can find the
offending value in scene.json or in the Blender scene without reading a traceback.
"""

from __future__ import annotations


class SceneError(ValueError):
    """A scene value is malformed; `path` locates it, `problem` says what is wrong."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = path
        self.problem = problem

    def __reduce__(self):
        # Keep the two-argument constructor working across pickling (e.g. multiprocessing).
        return (type(self), (self.path, self.problem))
