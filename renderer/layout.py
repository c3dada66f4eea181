"""Flat record layouts, declared once by field name and width.

The kernels keep tables as flat float or int arrays (a row per medium, lobe, light or
batched request) and read them at fixed offsets. Those offsets are computed here from the
field list instead of being numbered by hand, and each module binds the ones its kernels
read to module-level integers, which numba folds as compile-time constants:

    MEDIUM = Layout("medium", [("kind", 1), ("has_emission", 1), ("grid_offset", 3)])
    I_KIND = MEDIUM.offset("kind")            # 0
    I_GRID_OFFSET = MEDIUM.offset("grid_offset")  # 2
    I_SIZE = MEDIUM.size                      # 5

Builders (plain numpy) write fields by name: `row[MEDIUM.slice("grid_offset")] = ...`.
"""

from __future__ import annotations


class Layout:
    """A flat record: named fields of given widths, packed in declaration order."""

    def __init__(self, name: str, fields: list[tuple[str, int]]):
        self.name = name
        self.fields = tuple(fields)
        self._offsets: dict[str, int] = {}
        self._widths: dict[str, int] = {}
        offset = 0
        for field, width in self.fields:
            if field in self._offsets:
                raise ValueError(f"layout {name!r}: field {field!r} is declared twice")
            if int(width) != width or width < 1:
                raise ValueError(f"layout {name!r}: field {field!r} has width {width!r}; expected a positive "
                                 "integer")
            self._offsets[field] = offset
            self._widths[field] = int(width)
            offset += int(width)
        self.size = offset

    def offset(self, field: str) -> int:
        """Index of the field's first element within a record."""
        try:
            return self._offsets[field]
        except KeyError:
            fields = list(self._offsets)
            raise KeyError(f"layout {self.name!r} has no field {field!r}; it has {fields}") from None

    def width(self, field: str) -> int:
        self.offset(field)
        return self._widths[field]

    def slice(self, field: str) -> slice:
        """The field's elements within a record, for numpy builders."""
        start = self.offset(field)
        return slice(start, start + self._widths[field])

    def __repr__(self) -> str:
        body = ", ".join(f"{f}@{self._offsets[f]}:{w}" for f, w in self.fields)
        return f"Layout({self.name!r}: {body}; size {self.size})"
