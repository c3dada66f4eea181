"""Open Image Denoise through its C API (ctypes), using the library Blender ships.

OIDN 2's "RT" filter takes the noisy HDR colour and, as auxiliary images, the albedo and
normal features Cycles defines (Haze writes them: renderer.passes, Denoising Albedo and
Normal); the images are shared with OIDN (no copies), float32 RGB, row order irrelevant as
long as all match. No bpy import: the command line uses it too. The library is found next
to the bpy module (bpy/lib/libOpenImageDenoise.so.2 in the pip wheel), next to the Blender
executable (its lib/ folder), or at HAZE_OIDN_LIBRARY.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib.util
import os
import sys
from functools import cache
from pathlib import Path

import numpy as np

OIDN_DEVICE_TYPE_CPU = 1
OIDN_FORMAT_FLOAT3 = 3
NAMES = ("libOpenImageDenoise.so.2", "libOpenImageDenoise.2.dylib", "OpenImageDenoise.dll",
         "libOpenImageDenoise.so")


class DenoiseError(RuntimeError):
    pass


def candidate_paths() -> list[Path]:
    """Where the OIDN library may be, most specific first."""
    folders: list[Path] = []
    override = os.environ.get("HAZE_OIDN_LIBRARY")
    if override:
        return [Path(override)]
    spec = importlib.util.find_spec("bpy") if "bpy" not in sys.modules else sys.modules["bpy"].__spec__
    for location in (getattr(spec, "submodule_search_locations", None) or []):
        folders.append(Path(location) / "lib")
    if spec is not None and spec.origin and spec.origin not in ("built-in", "frozen"):
        folders.append(Path(spec.origin).parent / "lib")
    folders.append(Path(sys.executable).resolve().parent / "lib")
    paths = [folder / name for folder in folders for name in NAMES]
    found = ctypes.util.find_library("OpenImageDenoise")
    if found:
        paths.append(Path(found))
    return paths


@cache
def library() -> ctypes.CDLL:
    """The loaded OIDN library with the signatures this module calls."""
    for path in candidate_paths():
        if path.exists() or not path.is_absolute():
            try:
                lib = ctypes.CDLL(str(path))
            except OSError:
                continue
            _declare(lib)
            return lib
    raise DenoiseError("Open Image Denoise was not found (looked next to bpy and Blender; "
                       "set HAZE_OIDN_LIBRARY to its path)")


def _declare(lib: ctypes.CDLL) -> None:
    p, c, i, sz = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_size_t
    lib.oidnNewDevice.restype = p
    lib.oidnNewDevice.argtypes = [i]
    lib.oidnCommitDevice.argtypes = [p]
    lib.oidnReleaseDevice.argtypes = [p]
    lib.oidnGetDeviceError.restype = i
    lib.oidnGetDeviceError.argtypes = [p, ctypes.POINTER(c)]
    lib.oidnNewFilter.restype = p
    lib.oidnNewFilter.argtypes = [p, c]
    lib.oidnSetSharedFilterImage.argtypes = [p, c, p, i, sz, sz, sz, sz, sz]
    lib.oidnSetFilterBool.argtypes = [p, c, ctypes.c_bool]
    lib.oidnCommitFilter.argtypes = [p]
    lib.oidnExecuteFilter.argtypes = [p]
    lib.oidnReleaseFilter.argtypes = [p]


def available() -> bool:
    try:
        library()
    except DenoiseError:
        return False
    return True


def _check(lib: ctypes.CDLL, device: int, what: str) -> None:
    message = ctypes.c_char_p()
    code = lib.oidnGetDeviceError(device, ctypes.byref(message))
    if code != 0:
        text = message.value.decode(errors="replace") if message.value else "no message"
        raise DenoiseError(f"Open Image Denoise failed at {what} (error {code}): {text}")


def _rgb32(image: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    out = np.ascontiguousarray(image[..., :3], dtype=np.float32)
    if out.shape != (*shape, 3):
        raise ValueError(f"an image of shape {image.shape} for a {shape[1]}x{shape[0]} denoise")
    return out


def denoise(color: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None
            ) -> np.ndarray:
    """Denoise an (H, W, 3) linear HDR image with OIDN's RT filter, guided by the (H, W, 3)
    albedo and normal features when given (the normal only together with the albedo, as
    OIDN requires). Returns a new float32 (H, W, 3) image."""
    lib = library()
    h, w = color.shape[:2]
    images = {"color": _rgb32(color, (h, w))}
    if albedo is not None:
        images["albedo"] = _rgb32(albedo, (h, w))
        if normal is not None:
            images["normal"] = _rgb32(normal, (h, w))
    output = np.zeros((h, w, 3), np.float32)
    images["output"] = output
    device = lib.oidnNewDevice(OIDN_DEVICE_TYPE_CPU)
    if not device:
        raise DenoiseError("Open Image Denoise could not create a CPU device")
    try:
        lib.oidnCommitDevice(device)
        _check(lib, device, "device creation")
        filt = lib.oidnNewFilter(device, b"RT")
        try:
            for name, array in images.items():
                lib.oidnSetSharedFilterImage(filt, name.encode(), array.ctypes.data, OIDN_FORMAT_FLOAT3,
                                             w, h, 0, 0, 0)  # 0 strides: tightly packed
            lib.oidnSetFilterBool(filt, b"hdr", True)
            lib.oidnCommitFilter(filt)
            _check(lib, device, "filter set-up")
            lib.oidnExecuteFilter(filt)
            _check(lib, device, "filtering")
        finally:
            lib.oidnReleaseFilter(filt)
    finally:
        lib.oidnReleaseDevice(device)
    return output
