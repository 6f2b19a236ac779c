"""A texture a material reads: an image of RGBA8 texels and how it is sampled (glTF's sampler).

The pixels are kept as the file decoded them, row 0 at the top (glTF's and PNG's order: UV (0, 0) is
the image's top-left corner). ``srgb`` says the colour channels are sRGB-encoded (base colour and
emissive textures) and are decoded to linear when sampled; the data textures (metallic-roughness,
normal, occlusion, transmission) are linear. The GPU keeps every texture with its mip levels
(docs/SHADING.md, "Textures"); the scene JSON carries each as a PNG in base64."""

from __future__ import annotations

import base64
import binascii
import io
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import limits
from ..errors import SceneError, json_object

WRAPS = ("repeat", "clamp", "mirror")  # glTF's REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT
FILTERS = ("linear", "nearest")  # within a mip level; between levels always linear


@dataclass(frozen=True)
class Texture:
    """``pixels`` uint8 (H, W, 4) RGBA, row 0 the image's top; ``srgb``: colour channels
    sRGB-encoded; ``wrap_s`` / ``wrap_t``: how U / V outside [0, 1] repeat (:data:`WRAPS`);
    ``filter``: :data:`FILTERS`; ``name``: the file's name for the image (messages, scene info)."""

    pixels: np.ndarray
    srgb: bool = False
    wrap_s: str = "repeat"
    wrap_t: str = "repeat"
    filter: str = "linear"
    name: str = ""

    def __post_init__(self) -> None:
        p = self.pixels
        if not isinstance(p, np.ndarray) or p.dtype != np.uint8 or p.ndim != 3 or p.shape[2] != 4:
            raise SceneError("pixels", "expected uint8 RGBA pixels of shape (height, width, 4)")
        h, w = p.shape[:2]
        if not (1 <= w <= limits.MAX_TEXTURE_SIDE and 1 <= h <= limits.MAX_TEXTURE_SIDE):
            raise SceneError(
                "pixels", f"a texture is 1 … {limits.MAX_TEXTURE_SIDE} pixels a side (MAX_TEXTURE_SIDE), got {w} × {h}"
            )
        for name, value, allowed in (("wrap_s", self.wrap_s, WRAPS), ("wrap_t", self.wrap_t, WRAPS)):
            if value not in allowed:
                raise SceneError(name, f"expected one of {', '.join(allowed)}, got {value!r}")
        if self.filter not in FILTERS:
            raise SceneError("filter", f"expected one of {', '.join(FILTERS)}, got {self.filter!r}")
        if not isinstance(self.srgb, bool):
            raise SceneError("srgb", "expected true or false")
        if not isinstance(self.name, str) or len(self.name) > limits.MAX_TEXTURE_NAME:
            raise SceneError("name", f"expected a string of at most {limits.MAX_TEXTURE_NAME} characters")
        p = np.ascontiguousarray(p)
        p.setflags(write=False)
        object.__setattr__(self, "pixels", p)

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes of the texels as stored (level 0, RGBA8)."""
        return int(self.pixels.nbytes)

    def to_json(self) -> dict:
        from PIL import Image

        buf = io.BytesIO()
        Image.fromarray(np.asarray(self.pixels), "RGBA").save(buf, format="PNG")
        out: dict[str, Any] = {"png": base64.b64encode(buf.getvalue()).decode("ascii")}
        if self.srgb:
            out["srgb"] = True
        for k, default in (("wrap_s", "repeat"), ("wrap_t", "repeat"), ("filter", "linear"), ("name", "")):
            if getattr(self, k) != default:
                out[k] = getattr(self, k)
        return out

    @classmethod
    def from_json(cls, d: Any, where: str) -> Texture:
        d = json_object(d, where, {"png", "srgb", "wrap_s", "wrap_t", "filter", "name"})
        if "png" not in d:
            raise SceneError(f"{where}.png", "field required (the image as a base64 PNG or JPEG)")
        try:
            pixels = decode_image(d["png"], f"{where}.png")
            return cls(pixels, **{k: d[k] for k in ("srgb", "wrap_s", "wrap_t", "filter", "name") if k in d})
        except SceneError as e:
            inner = e.field if e.field.startswith(where) else f"{where}.{e.field}"
            raise SceneError(inner, e.message) from None


def decode_image(data: str | bytes, where: str) -> np.ndarray:
    """uint8 (H, W, 4): a PNG or JPEG (bytes, or base64 text) decoded to RGBA; its declared size is
    checked against MAX_TEXTURE_SIDE before a pixel is decoded."""
    from PIL import Image, UnidentifiedImageError

    if isinstance(data, str):
        try:
            data = base64.b64decode(data, validate=True)
        except (binascii.Error, ValueError):
            raise SceneError(where, "expected base64 text") from None
    if not isinstance(data, (bytes, bytearray)):
        raise SceneError(where, "expected base64 text")
    try:
        with Image.open(io.BytesIO(data)) as im:
            w, h = im.size
            if max(w, h) > limits.MAX_TEXTURE_SIDE:
                raise SceneError(
                    where,
                    f"the image declares {w:,} × {h:,} pixels; at most {limits.MAX_TEXTURE_SIDE:,} a side "
                    "(MAX_TEXTURE_SIDE)",
                )
            if im.format not in ("PNG", "JPEG"):
                raise SceneError(where, f"expected a PNG or JPEG image, got {im.format}")
            return np.asarray(im.convert("RGBA"), dtype=np.uint8).copy()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise SceneError(where, f"not a readable PNG or JPEG image ({e})") from None
