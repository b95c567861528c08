"""A camera's luminance image as files: OpenEXR (HDR, cd/m², with its standard error) and a tone-mapped PNG.

OpenEXR. No library the service keeps writes EXR (OpenEXR's own Python bindings are not among its dependencies, and
imageio needs a plugin for it), and an uncompressed single-part scanline file is small enough to write by hand
from the specification ("The OpenEXR File Layout", openexr.com): the magic number and version 2, a header of
attributes (``channels``, ``compression`` NO_COMPRESSION, ``dataWindow``, ``displayWindow``, ``lineOrder``
INCREASING_Y, ``pixelAspectRatio``, ``screenWindowCenter``, ``screenWindowWidth``, and ``whiteLuminance`` 1: a
value of 1 is 1 cd/m²), the offset table (one 8-byte offset per scanline), then each scanline: its y, its byte
count, and each channel's FLOAT (32-bit) values in the channels' alphabetical order. Channels: ``Y`` — the
luminance, cd/m² (EXR's name for a luminance-only image, so a viewer shows it as grey), and ``stderr.Y`` — its
standard error, cd/m², in the layer ``stderr`` (EXR's layers are channel-name prefixes). Row 0 is the top of the
image, as in the JSON answer. `read_exr` reads back what `write_exr` writes (and any uncompressed FLOAT scanline
file).

PNG. `tone_mapped_png`: Reinhard's global operator on luminance (Reinhard et al. 2002, "Photographic tone
reproduction for digital images", eq. 1–3): the log-average luminance L̄ = exp(mean(ln(δ + L))), the scaled
luminance Lm = a·L/L̄ with key a = 0.18, the display value Ld = Lm / (1 + Lm), then sRGB encoding (IEC 61966-2-1)
to 8-bit grey, one PNG pixel per image pixel.
"""

from __future__ import annotations

import io
import struct
from typing import Any

import numpy as np

EXR_MAGIC = 20000630
EXR_VERSION = 2           # single-part scanline, no long names
FLOAT = 2                 # EXR pixel type: 32-bit float
REINHARD_KEY = 0.18       # the "middle grey" key of Reinhard's operator
REINHARD_DELTA = 1e-6     # cd/m²: keeps ln() finite on black pixels
CHANNELS = ("Y", "stderr.Y")


def _attr(name: str, kind: str, value: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value


def write_exr(luminance: Any, stderr: Any, comments: str = "") -> bytes:
    """An OpenEXR file (bytes) of an image of `luminance` and its `stderr`, (height, width) cd/m², top row first."""
    layers = {"Y": np.asarray(luminance, dtype="<f4"), "stderr.Y": np.asarray(stderr, dtype="<f4")}
    h, w = layers["Y"].shape
    if layers["stderr.Y"].shape != (h, w) or h < 1 or w < 1:
        raise ValueError(f"luminance {layers['Y'].shape} and stderr {layers['stderr.Y'].shape} must be one "
                         f"(height, width) shape")
    names = sorted(layers)
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", FLOAT, 0, 1, 1) for n in names) + b"\0"
    window = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = b"".join([
        _attr("channels", "chlist", chlist),
        _attr("compression", "compression", b"\0"),
        _attr("dataWindow", "box2i", window),
        _attr("displayWindow", "box2i", window),
        _attr("lineOrder", "lineOrder", b"\0"),
        _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        _attr("whiteLuminance", "float", struct.pack("<f", 1.0)),
        *([_attr("comments", "string", comments.encode())] if comments else []),
    ]) + b"\0"
    start = 8 + len(header) + 8 * h
    line = 8 + 4 * w * len(names)
    offsets = struct.pack(f"<{h}Q", *(start + y * line for y in range(h)))
    lines = b"".join(struct.pack("<ii", y, 4 * w * len(names)) + b"".join(layers[n][y].tobytes() for n in names)
                     for y in range(h))
    return struct.pack("<ii", EXR_MAGIC, EXR_VERSION) + header + offsets + lines


def read_exr(data: bytes) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """An uncompressed FLOAT scanline OpenEXR file: its header ({name: raw bytes}) and channels ({name: (h, w)
    float32}); ValueError for anything else."""
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != EXR_MAGIC or version & 0xFF != 2 or version & 0x1E00:   # tiled, long names, deep, multipart
        raise ValueError("not a single-part scanline OpenEXR file")
    pos, header = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        kind_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, kind_end + 1)
        header[data[pos:name_end].decode()] = data[kind_end + 5:kind_end + 5 + size]
        pos = kind_end + 5 + size
    pos += 1
    if header["compression"] != b"\0":
        raise ValueError("only uncompressed OpenEXR files are read here")
    names, p, raw = [], 0, header["channels"]
    while raw[p] != 0:
        end = raw.index(b"\0", p)
        pixel_type, = struct.unpack_from("<i", raw, end + 1)
        if pixel_type != FLOAT:
            raise ValueError("only FLOAT channels are read here")
        names.append(raw[p:end].decode())
        p = end + 17
    x0, y0, x1, y1 = struct.unpack("<iiii", header["dataWindow"])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    offsets = struct.unpack_from(f"<{h}Q", data, pos)
    out = {n: np.empty((h, w), np.float32) for n in names}
    for off in offsets:
        y, size = struct.unpack_from("<ii", data, off)
        row = np.frombuffer(data, "<f4", size // 4, off + 8).reshape(len(names), w)
        for k, n in enumerate(names):
            out[n][y - y0] = row[k]
    return header, out


def reinhard(luminance: Any) -> np.ndarray:
    """Reinhard's global operator (module docstring): (h, w) cd/m² → display values in [0, 1)."""
    lum = np.clip(np.asarray(luminance, dtype=float), 0.0, None)
    log_average = float(np.exp(np.mean(np.log(REINHARD_DELTA + lum))))
    scaled = REINHARD_KEY * lum / log_average
    return scaled / (1.0 + scaled)


def tone_mapped_png(luminance: Any) -> bytes:
    """An 8-bit grey PNG of an image (h, w) cd/m², one pixel per pixel: Reinhard on luminance, sRGB-encoded."""
    from PIL import Image

    d = reinhard(luminance)
    srgb = np.where(d <= 0.0031308, 12.92 * d, 1.055 * np.power(d, 1 / 2.4) - 0.055)
    buf = io.BytesIO()
    Image.fromarray(np.round(255.0 * srgb).astype(np.uint8)).save(buf, format="PNG")
    return buf.getvalue()
