"""Image I/O: EXR round trips bit for bit, PNG bytes decode to the expected sRGB values."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

from renderer.imageio import encode_png, linear_to_srgb8, read_exr, write_exr, write_png


def _decode_png(data: bytes) -> tuple[dict[bytes, bytes], np.ndarray]:
    """Minimal decoder for what write_png emits: checks CRCs, returns chunks and the pixels."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    chunks: dict[bytes, bytes] = {}
    idat = b""
    pos = 8
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert crc == zlib.crc32(kind + body), kind
        if kind == b"IDAT":
            idat += body
        chunks[kind] = body
        pos += 12 + length
    assert list(chunks)[0] == b"IHDR" and list(chunks)[-1] == b"IEND"
    width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", chunks[b"IHDR"])
    assert (depth, colour, interlace) == (8, 2, 0)
    rows = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(height, 1 + width * 3)
    assert np.all(rows[:, 0] == 0), "only filter type 0 is expected"
    return chunks, rows[:, 1:].reshape(height, width, 3)


def _srgb_reference(v: float) -> int:
    """sRGB byte for one linear value, written out from the standard's formula."""
    v = min(max(v, 0.0), 1.0)
    encoded = 12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(np.floor(encoded * 255.0 + 0.5))


def test_exr_round_trip_is_bitwise(tmp_path: Path, rng: np.random.Generator) -> None:
    rgb = (rng.standard_normal((13, 21, 3)) * 10.0 ** rng.uniform(-30, 30, (13, 21, 3))).astype(np.float32)
    rgb[0, 0] = [np.finfo(np.float32).max, np.finfo(np.float32).tiny, 1e-45]  # 1e-45: a denormal
    rgb[1, 2] = [0.0, -0.0, np.inf]
    path = tmp_path / "deep" / "er" / "image.exr"
    write_exr(path, rgb)
    back = read_exr(path)
    assert back.dtype == np.float32 and back.shape == rgb.shape
    assert np.array_equal(back.view(np.uint32), rgb.view(np.uint32))


def test_exr_keeps_row_and_channel_order(tmp_path: Path) -> None:
    rgb = np.zeros((2, 3, 3), np.float32)
    rgb[0, 2] = [1.0, 2.0, 3.0]  # top-right pixel
    write_exr(tmp_path / "o.exr", rgb)
    back = read_exr(tmp_path / "o.exr")
    assert back[0, 2].tolist() == [1.0, 2.0, 3.0]
    assert np.count_nonzero(back) == 3


def test_exr_accepts_non_contiguous_input(tmp_path: Path, rng: np.random.Generator) -> None:
    rgb = rng.random((8, 6, 3), dtype=np.float32)[::-1, ::2]
    write_exr(tmp_path / "v.exr", rgb)
    assert np.array_equal(read_exr(tmp_path / "v.exr"), rgb)


def test_srgb_values_of_known_inputs(tmp_path: Path) -> None:
    linear = [0.0, 0.0031308, 0.5, 1.0, 2.0, -1.0]
    rgb = np.array([[[v, v, v] for v in linear]], np.float32)
    path = tmp_path / "sub" / "ramp.png"
    write_png(path, rgb)
    chunks, pixels = _decode_png(path.read_bytes())
    assert chunks[b"sRGB"] == b"\x00"
    assert pixels.shape == (1, 6, 3)
    assert pixels[0, :, 0].tolist() == [0, 10, 188, 255, 255, 0]
    assert pixels[0, :, 0].tolist() == [_srgb_reference(float(np.float32(v))) for v in linear]
    assert np.array_equal(pixels[..., 0], pixels[..., 2])


def test_png_rows_channels_and_size(tmp_path: Path, rng: np.random.Generator) -> None:
    rgb = rng.random((5, 7, 3))
    rgb[0, 0] = [1.0, 0.0, 0.0]  # top-left is red
    write_png(tmp_path / "p.png", rgb)
    _, pixels = _decode_png((tmp_path / "p.png").read_bytes())
    assert pixels.shape == (5, 7, 3)
    assert pixels[0, 0].tolist() == [255, 0, 0]
    assert np.array_equal(pixels, linear_to_srgb8(rgb))


def test_exposure_is_in_stops() -> None:
    rgb = np.full((1, 1, 3), 0.25, np.float32)
    assert np.array_equal(linear_to_srgb8(rgb, exposure=2.0), linear_to_srgb8(rgb * 4.0))
    assert linear_to_srgb8(rgb, exposure=-1.0)[0, 0, 0] == _srgb_reference(0.125)


def test_srgb_is_monotonic_and_continuous_at_the_knee() -> None:
    ramp = np.linspace(0.0, 1.0, 4097).reshape(1, -1, 1).repeat(3, axis=2)
    codes = linear_to_srgb8(ramp)[0, :, 0].astype(int)
    steps = np.diff(codes)
    assert steps.min() >= 0 and steps.max() <= 8  # no jump anywhere, including the linear/power seam
    assert codes[0] == 0 and codes[-1] == 255


@pytest.mark.parametrize(
    ("rgb", "message"),
    [
        (np.zeros((4, 4), np.float32), r"shape \(H, W, 3\)"),
        (np.zeros((4, 4, 4), np.float32), r"shape \(H, W, 3\)"),
        (np.zeros((0, 4, 3), np.float32), "empty"),
        (np.zeros((4, 4, 3), np.uint8), "floating-point"),
        ([[[0.0, 0.0, 0.0]]], "numpy array"),
    ],
)
def test_bad_images_are_rejected(tmp_path: Path, rgb: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        write_exr(tmp_path / "x.exr", rgb)
    with pytest.raises(ValueError, match=message):
        write_png(tmp_path / "x.png", rgb)
    assert not (tmp_path / "x.exr").exists() and not (tmp_path / "x.png").exists()


def test_write_exr_wants_float32(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="float32"):
        write_exr(tmp_path / "x.exr", np.zeros((2, 2, 3), np.float64))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_png_refuses_non_finite(tmp_path: Path, bad: float) -> None:
    rgb = np.zeros((3, 4, 3), np.float32)
    rgb[2, 1, 0] = bad
    with pytest.raises(ValueError, match="row 2, column 1, channel 0"):
        write_png(tmp_path / "x.png", rgb)
    assert not (tmp_path / "x.png").exists()


def test_non_finite_exposure_is_rejected() -> None:
    with pytest.raises(ValueError, match="exposure"):
        linear_to_srgb8(np.zeros((1, 1, 3)), exposure=float("nan"))


def test_encode_png_wants_uint8() -> None:
    with pytest.raises(ValueError, match="uint8"):
        encode_png(np.zeros((1, 1, 3), np.float32))


def test_read_exr_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="missing.exr"):
        read_exr(tmp_path / "missing.exr")
    junk = tmp_path / "junk.exr"
    junk.write_bytes(b"not an exr at all")
    with pytest.raises(ValueError, match="junk.exr"):
        read_exr(junk)


def test_read_exr_names_missing_channels(tmp_path: Path) -> None:
    path = str(tmp_path / "luma.exr")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"Y": np.zeros((2, 2), np.float32)}).write(path)
    with pytest.raises(ValueError, match=r"no channel\(s\) R, G, B"):
        read_exr(path)


def test_read_exr_widens_half(tmp_path: Path) -> None:
    path = str(tmp_path / "half.exr")
    planes = {name: np.full((2, 3), value, np.float16) for name, value in zip("RGB", (0.5, 2.0, 65504.0))}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, planes).write(path)
    back = read_exr(path)
    assert back.dtype == np.float32 and back.shape == (2, 3, 3)
    assert back[1, 2].tolist() == [0.5, 2.0, 65504.0]
