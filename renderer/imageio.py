"""Image files: linear float RGB as OpenEXR, display-referred sRGB as 8-bit PNG.

All images are (H, W, 3) arrays whose row 0 is the TOP row of the picture, the order both
file formats store scanlines in, so no flipping happens here. Callers that build images
bottom-up (as Blender's render result does) flip before calling.
"""

from __future__ import annotations

import os
import struct
import tempfile
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import OpenEXR

PathLike = str | os.PathLike[str]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# Every PNG Haze writes says so in a tEXt chunk; the command line replaces an existing PNG
# preview only if it carries this mark (see is_haze_png), so it never overwrites other files.
_PNG_SOFTWARE = b"Software\x00Haze"


def _check_rgb(rgb: object, what: str) -> np.ndarray:
    """Returns `rgb` as an array after checking it is a non-empty (H, W, 3) float image."""
    if not isinstance(rgb, np.ndarray):
        raise ValueError(f"{what} must be a numpy array, got {type(rgb).__name__}")
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"{what} must have shape (H, W, 3), got {rgb.shape}")
    if rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise ValueError(f"{what} must not be empty, got shape {rgb.shape}")
    if not np.issubdtype(rgb.dtype, np.floating):
        raise ValueError(f"{what} must have a floating-point dtype, got {rgb.dtype}")
    return rgb


def _make_parent(path: PathLike) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _umask() -> int:
    mask = os.umask(0o022)  # reading the umask means setting it; put it straight back
    os.umask(mask)
    return mask


def _write_atomically(path: PathLike, write: Callable[[Path], None]) -> None:
    """Have `write` fill a temporary file beside `path`, then rename it into place.

    A crash or an interrupt never leaves a half-written image, and renaming replaces a
    symbolic link at `path` itself rather than writing through it into the file it names.
    """
    path = _make_parent(path)
    handle, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(handle)
    temporary = Path(name)
    try:
        os.chmod(temporary, 0o666 & ~_umask())  # mkstemp makes it private; images are not
        write(temporary)
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_exr(path: PathLike, rgb: np.ndarray) -> None:
    """Writes a float32 (H, W, 3) linear RGB image as a ZIP-compressed scanline EXR.

    Values are stored bit for bit (32-bit float channels), including inf and NaN.
    """
    rgb = _check_rgb(rgb, "write_exr: rgb")
    if rgb.dtype != np.float32:
        # Refuse rather than convert: a silent float64 -> float32 cast would hide precision loss.
        raise ValueError(f"write_exr: rgb must be float32, got {rgb.dtype} (use rgb.astype(np.float32))")
    channels = {name: np.ascontiguousarray(rgb[:, :, i]) for i, name in enumerate("RGB")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    _write_atomically(path, lambda temporary: _write_exr_file(header, channels, temporary))


def _write_exr_file(header: dict, channels: dict, file: Path) -> None:
    try:
        OpenEXR.File(header, channels).write(str(file))
    except Exception as err:  # the binding raises bare RuntimeErrors (e.g. a full disk)
        raise OSError(f"write_exr: cannot write {file}: {err}") from err


def read_exr(path: PathLike) -> np.ndarray:
    """Reads the R, G, B channels of an EXR file as a float32 (H, W, 3) array.

    Half-float files are widened to float32; other channels (such as A) are ignored.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"read_exr: no such file: {path}")
    try:
        channels = OpenEXR.File(str(path), separate_channels=True).channels()
    except Exception as err:  # the binding raises bare RuntimeErrors; name the file instead
        raise ValueError(f"read_exr: {path} is not a readable EXR file ({err})") from err
    missing = [name for name in "RGB" if name not in channels]
    if missing:
        raise ValueError(f"read_exr: {path} has no channel(s) {', '.join(missing)}; found {sorted(channels)}")
    planes = [np.asarray(channels[name].pixels, dtype=np.float32) for name in "RGB"]
    return np.stack(planes, axis=-1)


def _srgb_oetf(linear: np.ndarray) -> np.ndarray:
    """The exact piecewise sRGB encoding (IEC 61966-2-1) of values already clamped to [0, 1]."""
    low = linear * 12.92
    high = 1.055 * np.power(linear, 1.0 / 2.4) - 0.055
    return np.where(linear <= 0.0031308, low, high)


def linear_to_srgb8(rgb: np.ndarray, exposure: float = 0.0) -> np.ndarray:
    """Converts linear RGB to 8-bit sRGB: scale by 2**exposure (stops), clamp to [0, 1], encode.

    Raises ValueError on NaN or infinite input, which would otherwise turn into arbitrary bytes.
    """
    rgb = _check_rgb(rgb, "linear_to_srgb8: rgb")
    if not np.isfinite(exposure):
        raise ValueError(f"linear_to_srgb8: exposure must be finite, got {exposure}")
    bad = ~np.isfinite(rgb)
    if bad.any():
        y, x, c = np.argwhere(bad)[0]
        raise ValueError(
            f"linear_to_srgb8: rgb has {int(bad.sum())} non-finite value(s), "
            f"first at row {y}, column {x}, channel {c}: {rgb[y, x, c]}"
        )
    # float64 so the encoding and rounding do not depend on the input precision.
    scaled = np.clip(rgb.astype(np.float64) * 2.0 ** float(exposure), 0.0, 1.0)
    return np.rint(_srgb_oetf(scaled) * 255.0).astype(np.uint8)


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    """One PNG chunk: length, type, data, and the CRC-32 of type + data."""
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def encode_png(srgb8: np.ndarray) -> bytes:
    """Encodes a uint8 (H, W, 3) sRGB image as PNG bytes (8-bit RGB, no filtering)."""
    if not isinstance(srgb8, np.ndarray) or srgb8.dtype != np.uint8:
        raise ValueError("encode_png: srgb8 must be a uint8 numpy array")
    if srgb8.ndim != 3 or srgb8.shape[2] != 3 or 0 in srgb8.shape:
        raise ValueError(f"encode_png: srgb8 must have shape (H, W, 3) and not be empty, got {srgb8.shape}")
    height, width = srgb8.shape[:2]
    # bit depth 8, colour type 2 (truecolour), default compression, filter and no interlace.
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    # Each scanline starts with its filter type byte; 0 = none.
    rows = np.zeros((height, 1 + width * 3), dtype=np.uint8)
    rows[:, 1:] = srgb8.reshape(height, width * 3)
    return b"".join(
        [
            _PNG_SIGNATURE,
            _png_chunk(b"IHDR", ihdr),
            _png_chunk(b"sRGB", b"\x00"),  # tells viewers the bytes are sRGB (perceptual intent)
            _png_chunk(b"tEXt", _PNG_SOFTWARE),
            _png_chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)),
            _png_chunk(b"IEND", b""),
        ]
    )


def write_png(path: PathLike, rgb_linear: np.ndarray, exposure: float = 0.0) -> None:
    """Writes linear RGB as an 8-bit sRGB PNG after `linear_to_srgb8` (exposure in stops)."""
    data = encode_png(linear_to_srgb8(rgb_linear, exposure))
    _write_atomically(path, lambda temporary: temporary.write_bytes(data))


def is_haze_png(path: PathLike) -> bool:
    """Whether `path` is a PNG that Haze wrote (it carries Haze's Software text chunk).

    Reads chunk headers only up to the image data, so a large or foreign file costs little.
    A symbolic link is never Haze's: replacing it could be mistaken for writing through it.
    """
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    try:
        with open(path, "rb") as stream:
            if stream.read(8) != _PNG_SIGNATURE:
                return False
            return _has_software_chunk(stream)
    except OSError:
        return False


def _has_software_chunk(stream) -> bool:
    while True:
        head = stream.read(8)
        if len(head) < 8:
            return False
        length, kind = struct.unpack(">I", head[:4])[0], head[4:]
        if kind in (b"IDAT", b"IEND") or length > 1 << 16:
            return False
        body = stream.read(length)
        if kind == b"tEXt" and body == _PNG_SOFTWARE:
            return True
        stream.read(4)  # CRC
