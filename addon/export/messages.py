"""Errors and warnings of the export, phrased for the Blender user.

Every message names the Blender datablock it is about (object, material, node, light...)
so the user can find what to fix without reading a traceback.
"""

from __future__ import annotations


class ExportError(ValueError):
    """The Blender scene cannot be rendered by Haze. `subject` names the datablock."""

    def __init__(self, subject: str, problem: str) -> None:
        super().__init__(f"{subject}: {problem}")
        self.subject = subject
        self.problem = problem


class Messages:
    """Warnings collected during one export; each distinct warning is kept once."""

    def __init__(self) -> None:
        self.warnings: list[str] = []
        self._seen: set[str] = set()

    def warn(self, subject: str, problem: str) -> None:
        text = f"{subject}: {problem}"
        if text not in self._seen:
            self._seen.add(text)
            self.warnings.append(text)


def object_subject(name: str) -> str:
    return f"Object '{name}'"


def material_subject(name: str) -> str:
    return f"Material '{name}'"


def node_subject(owner: str, node_name: str) -> str:
    return f"{owner}, node '{node_name}'"
