"""How the scene reaches the worker processes (renderer.workers) and the cluster's.

The scene is pickled once per render to a temporary file named by a hash of its contents;
a task carries that (key, path), and a worker loads the scene and builds its tracer only
for a key it has not got (it keeps one tracer). The scene's arrays (grids, meshes) go into
that file raw, beside the pickle (protocol 5, out of band), and workers map them
copy-on-write instead of reading them: all workers' arrays are views of the same pages, so
a grid takes memory once per machine, not once per worker (issue 18, item 3). Arrays that
already view a file of renderer.mapped (a large grid's bricks) are not copied: the shipment
names the file (by its contents' digest, with a table of paths), and workers map that file.
A Dask cluster's workers get the plain pickle instead (scene_payload).

This module imports only the standard library (renderer.mapped, which imports numpy, only
once an array is pickled), so renderer.workers can start workers before numba is imported.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import mmap
import os
import pickle
import struct
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:
    from .compile import CompiledScene
    from .scene import IntegratorSettings


class Shipment(NamedTuple):
    key: str  # hash of the pickle: a worker that holds this key already has the tracer
    path: str


def tracer_settings(settings: IntegratorSettings) -> IntegratorSettings:
    """The settings with the fields a tracer does not read normalised, so another seed, spp
    or time limit of the same scene does not make the workers rebuild their tracers."""
    return dataclasses.replace(settings, seed=0, spp=1, time_limit=0.0)


def scene_payload(cs: CompiledScene, settings: IntegratorSettings) -> tuple[str, bytes]:
    """(hash, pickle) of what a cluster worker needs to build the tracer (renderer.cluster):
    the same key, the same tracer. The local pool ships the arrays out of band (shipped)."""
    data = pickle.dumps((cs, tracer_settings(settings)), protocol=pickle.HIGHEST_PROTOCOL)
    return hashlib.blake2b(data, digest_size=16).hexdigest(), data


# Shipment file: header (pickle length, buffer count, file table length), then (offset, size)
# per buffer, the pickle, the table of mapped files (a pickled {digest: path}), and the
# buffers, each at a multiple of ALIGN bytes (numba types an array by its alignment too: a
# misaligned view would compile every kernel again).
_HEADER = struct.Struct("<QQQ")
_ENTRY = struct.Struct("<QQ")
ALIGN = 64
# Shipment files a worker still mapped when the render ended (Windows cannot delete them).
_leftovers: list[str] = []


class _ShipmentPickler(pickle.Pickler):
    """Protocol 5 with the arrays out of band, except those viewing a renderer.mapped file:
    they pickle as (digest, offset, shape, dtype), and `files` collects digest -> path."""

    def __init__(self, file, buffers: list[pickle.PickleBuffer]) -> None:
        super().__init__(file, protocol=5, buffer_callback=buffers.append)
        self.files: dict[str, str] = {}
        self.mapped = None  # renderer.mapped, once an array shows up (it imports numpy)

    def reducer_override(self, obj):
        if type(obj).__name__ != "ndarray" or type(obj).__module__ != "numpy":
            return NotImplemented
        if self.mapped is None:
            from . import mapped

            self.mapped = mapped
        found = self.mapped.reference(obj)
        if found is None:
            return NotImplemented
        digest, path, offset = found
        self.files[digest] = path
        return self.mapped.resolve, (digest, offset, obj.shape, obj.dtype.str)


@contextmanager
def shipped(cs: CompiledScene, settings: IntegratorSettings) -> Iterator[Shipment]:
    """The scene written once to a temporary file for the workers, removed after the render."""
    buffers: list[pickle.PickleBuffer] = []
    stream = io.BytesIO()
    pickler = _ShipmentPickler(stream, buffers)
    pickler.dump((cs, tracer_settings(settings)))
    data = stream.getvalue()
    raws = [b.raw() for b in buffers]
    digest = hashlib.blake2b(data, digest_size=16)  # mapped files are in it by their digests
    for raw in raws:
        digest.update(raw)
    key = digest.hexdigest()
    remove_leftovers()
    remove_orphans()
    try:
        fd, path = tempfile.mkstemp(prefix=f"{PREFIX}{os.getpid()}-{key[:8]}-", suffix=".pkl")
    except OSError as error:
        raise OSError(f"could not create the scene file for the workers in {tempfile.gettempdir()}: "
                      f"{error.strerror or error} (TMPDIR chooses the folder)") from None
    try:
        try:
            with os.fdopen(fd, "wb") as f:
                _write_shipment(f, data, raws, pickle.dumps(pickler.files))
        except OSError as error:
            raise OSError(f"could not write the scene file for the workers {path}: {error.strerror or error}"
                          " (TMPDIR chooses the folder)") from None
        yield Shipment(key, path)
    finally:
        _remove(path)


# Shipment files are named PREFIX<owner pid>-<key>-<random>.pkl: a file whose owner is gone
# (a parent killed with SIGKILL never removes its own) is removed by the next render.
PREFIX = "haze-scene-"


def remove_orphans(folder: str | None = None) -> None:
    """Remove this user's shipment files whose owning process no longer runs (POSIX only:
    os.kill(pid, 0) would end the process on Windows)."""
    if sys.platform == "win32":
        return
    folder = folder or tempfile.gettempdir()
    try:
        names = [n for n in os.listdir(folder) if n.startswith(PREFIX) and n.endswith(".pkl")]
    except OSError:
        return
    for name in names:
        owner = name[len(PREFIX):].split("-", 1)[0]
        if not owner.isdigit() or int(owner) == os.getpid() or _running(int(owner)):
            continue
        path = os.path.join(folder, name)
        try:
            if os.stat(path).st_uid == os.getuid():  # only this user's (a shared /tmp)
                os.unlink(path)
        except (OSError, AttributeError):  # gone already, or not ours; Windows: no getuid
            pass


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):  # another user's process, or a platform without signals
        return True
    return True


def _write_shipment(f, data: bytes, raws: list[memoryview], files: bytes) -> None:
    offsets, at = [], _aligned(_HEADER.size + _ENTRY.size * len(raws) + len(data) + len(files))
    for raw in raws:
        offsets.append(at)
        at = _aligned(at + raw.nbytes)
    f.write(_HEADER.pack(len(data), len(raws), len(files)))
    for offset, raw in zip(offsets, raws):
        f.write(_ENTRY.pack(offset, raw.nbytes))
    f.write(data)
    f.write(files)
    for offset, raw in zip(offsets, raws):
        f.seek(offset)
        f.write(raw)
    f.truncate(at)


def _aligned(n: int) -> int:
    return -(-n // ALIGN) * ALIGN


def load_shipment(path: str):
    """What shipped() pickled, its arrays viewing a copy-on-write map of the file (pages
    shared with every other process that maps it, until one writes to them)."""
    with open(path, "rb") as f:
        mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_COPY)
    view = memoryview(mm)
    size, count, table = _HEADER.unpack_from(view, 0)
    entries = [_ENTRY.unpack_from(view, _HEADER.size + _ENTRY.size * i) for i in range(count)]
    start = _HEADER.size + _ENTRY.size * count
    files = pickle.loads(view[start + size:start + size + table])
    buffers = [view[o:o + n] for o, n in entries]
    if not files:
        return pickle.loads(view[start:start + size], buffers=buffers)
    from .mapped import resolving

    with resolving(files):
        return pickle.loads(view[start:start + size], buffers=buffers)


def _remove(path: str) -> None:
    try:
        Path(path).unlink(missing_ok=True)
    except OSError:  # still mapped by a worker (Windows): removed later
        _leftovers.append(path)


def remove_leftovers() -> None:
    paths = list(_leftovers)
    _leftovers.clear()
    for path in paths:
        _remove(path)
