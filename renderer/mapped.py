"""Large arrays written once to a temporary file and mapped by every process that reads them.

A sparse grid's bricks (renderer.media.bricks) are 100s of MB at 512^3. Held in the
process that builds them (Blender's) and copied into the worker shipment (renderer.shipment),
they took memory twice over: an anonymous copy in Blender's process for the whole render,
and the file the workers map. Written here instead, row by row as they are built, they
exist once, in a file: the builder maps it too, and its pages are the page cache's, which
release_pages() unmaps once the export is done with them (they stay in the file and the
page cache for the workers). The worker shipment then names the file instead of copying
it (shipment.shipped: `reference`, `resolve`).

Files are named by nothing the workers rely on: a shipment refers to one by the digest
of its contents (so two exports of the same grid ship the same key and the workers keep
their tracer), with a table digest -> path beside the pickle. A file is removed when its
array is garbage (weakref.finalize on the mapping); a worker that maps it keeps its pages.
"""

from __future__ import annotations

import atexit
import hashlib
import mmap
import os
import sys
import tempfile
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

# Arrays under this size stay in ordinary memory (files for small grids would only cost time).
MIN_BYTES = 8 << 20


class _Mapping:
    """A mapped file's bookkeeping: its path, first byte's address, size and content digest."""

    def __init__(self, path: str, address: int, size: int, digest: str) -> None:
        self.path, self.address, self.size, self.digest = path, address, size, digest


_mappings: dict[int, tuple[weakref.ref, _Mapping]] = {}  # id(mmap) -> (weak mmap, bookkeeping)
_leftovers: list[str] = []  # files a process still mapped when they were dropped (Windows)


class FileWriter:
    """Appends raw arrays to a new temporary file, hashing them; `array()` maps the result.

    Memory stays that of the array being appended: the bytes go to the page cache, which
    the system may write out or drop, and are counted in no process until mapped."""

    def __init__(self, prefix: str = "haze-grid-") -> None:
        fd, self.path = tempfile.mkstemp(prefix=prefix, suffix=".bin")
        self.file = os.fdopen(fd, "wb")
        self.digest = hashlib.blake2b(digest_size=16)
        self.size = 0
        # A writer dropped before array() (the read failed halfway) leaves no file behind.
        self._unused = weakref.finalize(self, _discard, self.file, self.path)

    def write(self, values: np.ndarray) -> None:
        raw = memoryview(np.ascontiguousarray(values)).cast("B")
        self.file.write(raw)
        self.digest.update(raw)
        self.size += raw.nbytes

    def array(self, shape: tuple[int, ...], dtype=np.float32) -> np.ndarray:
        """The file's contents as a (shape) array viewing a copy-on-write map of it (writes
        stay in this process; nothing here writes)."""
        self._unused.detach()
        self.file.close()
        expected = int(np.prod(shape)) * np.dtype(dtype).itemsize
        if expected != self.size:
            _remove(self.path)
            raise ValueError(f"{self.size} bytes written for an array of {expected}")
        return _map(self.path, self.digest.hexdigest(), shape, np.dtype(dtype))

def _discard(file, path: str) -> None:
    file.close()
    _remove(path)


def concatenate(parts: list[np.ndarray], dtype=np.float32) -> np.ndarray:
    """np.concatenate of 1-D arrays as `dtype`, into a mapped file when the result holds
    MIN_BYTES or more (so several large grids joined stay out of this process's memory)."""
    count = sum(int(part.size) for part in parts)
    if count * np.dtype(dtype).itemsize < MIN_BYTES:
        return np.ascontiguousarray(np.concatenate(parts), dtype)
    writer = FileWriter()
    for part in parts:
        writer.write(np.asarray(part, dtype))
    return writer.array((count,), dtype)


def _map(path: str, digest: str, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    if int(np.prod(shape)) == 0:
        _remove(path)
        return np.zeros(shape, dtype)
    with open(path, "rb") as f:
        mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
    values = np.ndarray(shape, dtype, buffer=mm)  # its base is mm: views keep the map alive
    _mappings[id(mm)] = (weakref.ref(mm), _Mapping(path, values.ctypes.data, mm.size(), digest))
    weakref.finalize(mm, _forget, id(mm), path)
    return values


def _forget(key: int, path: str) -> None:
    _mappings.pop(key, None)
    _remove(path)


def _remove(path: str) -> None:
    try:
        Path(path).unlink(missing_ok=True)
    except OSError:  # still mapped by a worker (Windows): removed at exit
        _leftovers.append(path)


@atexit.register
def _remove_leftovers() -> None:
    for path in list(_leftovers):
        try:
            Path(path).unlink(missing_ok=True)
        except OSError:
            pass


def _mapping_of(values: np.ndarray) -> tuple[mmap.mmap, _Mapping] | None:
    base = values
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, mmap.mmap) and id(base) in _mappings:
        ref, mapping = _mappings[id(base)]
        if ref() is base:
            return base, mapping
    return None


def reference(values: np.ndarray) -> tuple[str, str, int] | None:
    """(digest, path, byte offset) of a C-contiguous array that views a file of this
    module, or None (then the array must be copied to reach another process)."""
    if not values.flags.c_contiguous:
        return None
    found = _mapping_of(values)
    if found is None:
        return None
    _, mapping = found
    offset = values.ctypes.data - mapping.address
    if offset < 0 or offset + values.nbytes > mapping.size:
        return None
    return mapping.digest, mapping.path, offset


class Resolver:
    """Maps the files a shipment names (digest -> path), each once however many arrays view it."""

    def __init__(self, paths: dict[str, str]) -> None:
        self.paths = paths
        self.maps: dict[str, mmap.mmap] = {}

    def view(self, digest: str, offset: int, shape: tuple[int, ...], dtype: str) -> np.ndarray:
        if digest not in self.maps:
            with open(self.paths[digest], "rb") as f:
                self.maps[digest] = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
        return np.ndarray(shape, np.dtype(dtype), buffer=self.maps[digest], offset=offset)


_resolver: Resolver | None = None


@contextmanager
def resolving(paths: dict[str, str]) -> Iterator[None]:
    """The table `resolve` reads, while one shipment is unpickled."""
    global _resolver
    _resolver = Resolver(paths)
    try:
        yield
    finally:
        _resolver = None  # the arrays keep their maps; the next shipment opens its own


def resolve(digest: str, offset: int, shape: tuple[int, ...], dtype: str) -> np.ndarray:
    """The array `reference` described, in a process that unpickles a shipment (pickle calls it)."""
    if _resolver is None:
        raise RuntimeError("a mapped array was unpickled outside a shipment")
    return _resolver.view(digest, offset, shape, dtype)


def release_pages() -> None:
    """Unmap this process's resident pages of every mapped file (they stay in the file and
    the page cache, and come back on the next read): the export reads the bricks to build
    majorants and evaluate the material, then Blender's process has no more use for them."""
    if not hasattr(mmap, "MADV_DONTNEED") or not sys.platform.startswith("linux"):
        return
    for ref, _ in list(_mappings.values()):
        mm = ref()
        if mm is not None:
            # Copy-on-write pages this process wrote would be dropped too, but nothing
            # writes to these arrays: they are the file's contents, as the workers see them.
            mm.madvise(mmap.MADV_DONTNEED)
