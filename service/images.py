"""A camera's luminance image as files: OpenEXR (HDR, cd/m², with its standard error) and a tone-mapped PNG.

OpenEXR, written and read by the OpenEXR project's own Python bindings (``openexr`` on PyPI, ASWF; wheels with
the C++ library inside): the reference implementation, so every viewer and compositor reads what it writes, with
ZIP compression. Channels: ``Y`` — the luminance, cd/m² (EXR's name for a luminance-only image, so a viewer shows
it as grey), and ``stderr.Y`` — its standard error, cd/m², in the layer ``stderr`` (EXR's layers are channel-name
prefixes), both 32-bit float; the standard attribute ``whiteLuminance`` 1 says that a value of 1 is 1 cd/m². Row 0
is the top of the image, as in the JSON answer.

PNG. `tone_mapped_png`: Reinhard's global operator on luminance (Reinhard et al. 2002, "Photographic tone
reproduction for digital images", eq. 1–3): the log-average luminance L̄ = exp(mean(ln(δ + L))) over the pixels
that see light (L > 0: a black background or border must not set the exposure of the rest), the scaled
luminance Lm = a·L/L̄ with key a = 0.18, the display value Ld = Lm / (1 + Lm), then sRGB encoding (IEC 61966-2-1)
to 8-bit grey, one PNG pixel per image pixel.
"""

from __future__ import annotations

import io
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

REINHARD_KEY = 0.18       # the "middle grey" key of Reinhard's operator
REINHARD_DELTA = 1e-6     # cd/m²: Reinhard's δ (keeps ln() finite; black pixels are left out of the average)
CHANNELS = ("Y", "stderr.Y")


def write_exr(luminance: Any, stderr: Any, comments: str = "") -> bytes:
    """An OpenEXR file (bytes) of an image of `luminance` and its `stderr`, (height, width) cd/m², top row first."""
    import OpenEXR

    layers = {"Y": np.ascontiguousarray(luminance, dtype=np.float32),
              "stderr.Y": np.ascontiguousarray(stderr, dtype=np.float32)}
    h, w = layers["Y"].shape if layers["Y"].ndim == 2 else (0, 0)
    if layers["stderr.Y"].shape != (h, w) or h < 1 or w < 1:
        raise ValueError(f"luminance {layers['Y'].shape} and stderr {layers['stderr.Y'].shape} must be one "
                         f"(height, width) shape")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, "whiteLuminance": 1.0,
              **({"comments": comments} if comments else {})}
    with tempfile.TemporaryDirectory(prefix="lumenlink-exr-") as tmp:
        path = Path(tmp) / "image.exr"
        with OpenEXR.File(header, layers) as f:
            f.write(str(path))
        return path.read_bytes()


def read_exr(data: bytes) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Any single-part OpenEXR file (bytes): its header ({name: value}) and channels ({name: (h, w) array}), through
    the same bindings; ValueError where the bytes are not one."""
    import OpenEXR

    with tempfile.TemporaryDirectory(prefix="lumenlink-exr-") as tmp:
        path = Path(tmp) / "image.exr"
        path.write_bytes(data)
        try:
            with OpenEXR.File(str(path)) as f:
                return dict(f.header()), {name: np.array(c.pixels) for name, c in f.channels().items()}
        except Exception as exc:   # the bindings raise RuntimeError with the library's message
            raise ValueError(f"not an OpenEXR file: {exc}") from exc


def reinhard(luminance: Any) -> np.ndarray:
    """Reinhard's global operator (module docstring): (h, w) cd/m² → display values in [0, 1). The key is set by
    the log-average of the pixels that see light: black pixels (a background, a border) would pull a log-average
    taken over all of them towards δ and turn the rest white. An image with no light at all stays black."""
    lum = np.clip(np.asarray(luminance, dtype=float), 0.0, None)
    lit = lum[lum > 0.0]
    if lit.size == 0:
        return np.zeros_like(lum)
    log_average = float(np.exp(np.mean(np.log(REINHARD_DELTA + lit))))
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
