"""Environment images: an equirectangular HDR image a ray that meets nothing sees (docs/FORMATS.md,
"Environment").

The convention is Mitsuba 3's ``envmap`` (so ``renderer/oracle/mitsuba_scene.py`` needs no transform
beyond the rotation): +y is up; a world direction d (unit) has

    u = atan2(d.x, −d.z) / 2π + rotation_deg / 360   (mod 1),    v = acos(d.y) / π

so (unrotated) u = 0 looks along −z, u = ¼ along +x, and row 0 of the image is the zenith, the
last row the nadir; ``rotation_deg`` turns the image about +y by the right-hand rule. Radiance
between texels is bilinear the way Mitsuba interpolates: column i sits at u = (i + ½) / W
(wrapping around), row j at v = j / (H − 1).

Importance sampling: the W × (H − 1) bilinear *patches* (between columns i, i + 1 and rows j,
j + 1) are picked with probability ∝ their corners' mean luminance × the solid angle of their
row band (cos θ_j − cos θ_j+1), then a point uniform in (u, v) inside the patch: a marginal CDF
over the patch rows and one conditional CDF per row (:meth:`EnvironmentMap.sampling_tables`). The
pdf in solid angle is P(patch) · W · (H − 1) / (2π² sin θ). Every patch with a lit corner has
P > 0, so the sampling reaches all the light there is.

Readers (``.hdr`` Radiance RGBE, ``.exr`` OpenEXR) check the size the file declares against
``renderer/limits.py`` before a texel is allocated, and every texel after: finite, ≥ 0, at most
MAX_EMISSION. A refused file raises :class:`~renderer.geometry.scene.SceneError` whose field is ``body``
(the file) or ``format``.
"""

from __future__ import annotations

import hashlib
import io
import math
import re
import struct
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from .. import limits
from ..errors import SceneError

ENV_FORMATS = ("hdr", "exr")
LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709 weights: what the sampling is proportional to
STORED_TEXEL_BYTES = 12  # float32 R, G, B: a texel as the service holds and stores it
SKY_REF = "sky"  # the procedural sky's reference (renderer/materials/sky.py): nothing stored, made again


def check_size(width: int, height: int) -> None:
    """SceneError (``body``) unless an image of ``width × height`` texels is within the limits."""
    lo, w_max, h_max = limits.MIN_ENV_SIDE, limits.MAX_ENV_WIDTH, limits.MAX_ENV_HEIGHT
    if not (lo <= width <= w_max and lo <= height <= h_max):
        raise SceneError(
            "body",
            f"the image declares {width} × {height} texels; accepted: {lo}–{w_max} wide, {lo}–{h_max} high",
        )


def check_texels(rgb: np.ndarray) -> np.ndarray:
    """``rgb`` (H, W, 3) as read-only float32 once every texel is finite, ≥ 0 and ≤ MAX_EMISSION
    (SceneError ``body`` naming the first that is not)."""
    a = np.asarray(rgb)
    if a.ndim != 3 or a.shape[2] != 3:
        raise SceneError("body", f"expected H × W × 3 texels, got shape {a.shape}")
    check_size(a.shape[1], a.shape[0])
    a = np.ascontiguousarray(a, dtype=np.float32)
    bad = ~(np.isfinite(a) & (a >= 0) & (a <= limits.MAX_EMISSION)).all(axis=2)
    if bad.any():
        j, i = (int(x) for x in np.argwhere(bad)[0])
        raise SceneError(
            "body",
            f"texel (row {j}, column {i}) is {a[j, i].tolist()}: radiance must be finite, "
            f"0–{limits.MAX_EMISSION:g} per channel",
        )
    a.setflags(write=False)
    return a


# ---- run-length scanlines ---------------------------------------------------------------------
# A run-length encoded scanline is four channels of W bytes each, as packets: a count byte c, then
# one byte repeated c − 128 times (c > 128), or c bytes as they are (1 ≤ c ≤ 128). Where a packet
# begins depends on every packet before it, so the packets are cut apart by one regular expression
# (the C loop of ``re``: one alternative per count, tried by its first byte): a stretch of two-byte
# packets (runs, literals of one) is one match, any other packet one; NumPy does the rest — where
# each packet lies, the checks, the bytes out — a few array operations per scanline, not a Python
# step per packet. The last alternative takes whatever is left when a packet is cut short by the
# end of the bytes searched, so the packets found always follow one another.
_PACKETS = re.compile(
    b"(?:[\\x01\\x81-\\xff].)+|\\x00|"
    + b"|".join(re.escape(bytes([c])) + b".{%d}" % c for c in range(2, 129))
    + b"|.+",
    re.DOTALL,
)


def _packets(data: bytes, d: np.ndarray, start: int, stop: int) -> np.ndarray:
    """The positions (int64) of the packets that follow one another from ``start``, up to ``stop``."""
    found = _PACKETS.findall(data, start, stop)
    size = np.fromiter(map(len, found), dtype=np.int64, count=len(found))
    del found
    at = start + np.cumsum(size) - size
    pairs = d[at] if len(at) else np.zeros(0, np.uint8)
    pairs = (pairs == 1) | (pairs > 128)  # a stretch of two-byte packets (or one cut short)
    per = np.where(pairs, (size + 1) // 2, 1)
    first = np.cumsum(per) - per  # each match's first packet
    step = np.full(int(per.sum()), 2, dtype=np.int64)  # a packet is 2 bytes after the one before it,
    if len(at):  # unless it begins a match
        step[first] = np.diff(at, prepend=0) - np.concatenate([[0], 2 * (per[:-1] - 1)])
    return np.cumsum(step, out=step)


def _rle_scanline(data: bytes, q: int, width: int, y: int, guess: int) -> tuple[np.ndarray, int]:
    """The positions of the packets of run-length scanline ``y`` whose data begin at ``q``, and the
    position after it (``guess``: how many bytes it likely spans); SceneError where a packet is
    empty, passes its channel's end or the file's, or the file ends first, as a packet-by-packet
    reader says it."""
    n = len(data)
    limit = min(n, q + 8 * width)  # each good packet gives ≥ 1 byte for ≤ 2: 4W bytes lie within 8W
    stop = min(limit, q + max(guess, 64))
    d = np.frombuffer(data, dtype=np.uint8)
    while True:
        pk = _packets(data, d, q, stop)
        c = d[pk].astype(np.int64)
        run = c > 128
        cnt = np.where(run, c - 128, c)
        length = np.where(run, 2, c + 1)
        end = pk + length
        done = np.cumsum(cnt)
        full = np.flatnonzero(done >= 4 * width)
        if full.size or stop >= limit:
            break
        stop = limit  # the scanline goes on past the bytes searched: search all it can span
    before = done - cnt
    bad = (cnt == 0) | (end > n) | (before // width != (done - 1) // width)
    last = int(full[0]) if full.size else len(c) - 1
    if bad[: last + 1].any():
        raise SceneError("body", f"scanline {y}: a run passes the end of the line")
    if not full.size:
        raise SceneError("body", f"the file ends inside scanline {y}")
    return pk[: last + 1], int(end[last])


def _rle_scanlines(data: bytes, pos: int, width: int, rows: int) -> tuple[np.ndarray, int]:
    """The packet positions of the whole, well-formed run-length scanlines from ``pos`` on (at most
    ``rows``), found in one pass over the rest of the file, and the position after them. A width that
    is a multiple of 256 makes each scanline header ``2 2 hi 0`` two packets of the search (a literal
    of two, an empty one), so the packets found stay those of the scanlines after it. Whatever is not
    plain (a flat scanline, a malformed packet, the file's end, another width) ends the pass before
    that scanline, for the scanline-by-scanline reader to read or refuse."""
    header = bytes([2, 2, width >> 8, width & 255])
    if width & 255 or data[pos : pos + 4] != header:
        return np.zeros(0, np.int64), pos
    n, line = len(data), 4 * width
    d = np.frombuffer(data, dtype=np.uint8)
    pk = _packets(data, d, pos + 4, n)
    c = d[pk].astype(np.int32)
    run = c > 128
    cnt = np.where(run, c - 128, c)
    length = np.where(run, 2, c + 1)
    del run, c
    end = pk + length
    done = np.cumsum(cnt, dtype=np.int64)
    firsts: list[int] = []
    lasts: list[int] = []
    s = 0
    while len(firsts) < rows:
        base = int(done[s - 1]) if s else 0
        e = int(np.searchsorted(done, base + line))
        if e >= len(done) or done[e] != base + line:
            break
        firsts.append(s)
        lasts.append(e)
        h = int(end[e])
        if data[h : h + 4] != header or e + 3 >= len(done):
            break
        s = e + 3  # past the header's two packets
    while firsts:  # these scanlines' packets checked: none empty, past the file or over a channel's end
        lo, hi = firsts[0], lasts[-1] + 1
        headers = np.array(lasts[:-1], dtype=np.int64)
        empty = lo + np.flatnonzero(cnt[lo:hi] == 0)  # only the headers' second packets may be
        wrong = empty[~np.isin(empty, headers + 2)]
        before = np.array([int(done[f - 1]) if f else 0 for f in firsts], dtype=np.int64)
        ends = (before[:, None] + width * np.arange(1, 5)).ravel()  # each channel ends at a packet's end
        at = np.minimum(np.searchsorted(done, ends), len(done) - 1)
        over = np.flatnonzero(done[at] != ends) // 4
        bad_rows = [len(firsts)] if int(end[hi - 1]) <= n else [len(firsts) - 1]
        if wrong.size:
            bad_rows.append(int(np.searchsorted(np.array(lasts), wrong[0])))
        if over.size:
            bad_rows.append(int(over[0]))
        keep = min(bad_rows)
        if keep == len(firsts):
            plain = np.ones(hi - lo, dtype=bool)
            plain[headers + 1 - lo] = False
            plain[headers + 2 - lo] = False
            return pk[lo:hi][plain], int(end[hi - 1])
        firsts, lasts = firsts[:keep], lasts[:keep]
    return np.zeros(0, np.int64), pos


def _rle_rows(d: np.ndarray, pk: np.ndarray, out: np.ndarray, rows_at_once: int = 64) -> int:
    """The packets at ``pk`` (whole scanlines, in order) decoded into the first rows of ``out``
    (H, W, 4), a few rows at a time (the source index of every byte is 8 bytes); how many rows."""
    line = 4 * out.shape[1]
    c = d[pk].astype(np.int64)
    done = np.cumsum(np.where(c > 128, c - 128, c))
    rows = int(done[-1]) // line if len(done) else 0
    cuts = np.searchsorted(done, np.arange(0, rows + rows_at_once, rows_at_once).clip(max=rows) * line, "right")
    for r0, a, b in zip(range(0, rows, rows_at_once), cuts[:-1], cuts[1:], strict=False):
        got = _rle_bytes(d, pk[a:b])
        out[r0 : r0 + len(got) // line] = got.reshape(-1, 4, out.shape[1]).transpose(0, 2, 1)
    return rows


def _rle_bytes(d: np.ndarray, pk: np.ndarray) -> np.ndarray:
    """The bytes packets at positions ``pk`` (in order) decode to: each packet's second byte
    repeated (a run's value), then the literals' bytes put in place."""
    c = d[pk].astype(np.int64)
    lit = c <= 128
    cnt = np.where(lit, c, c - 128)
    out = np.repeat(d[pk + 1], cnt)
    if lit.any():
        at, n = (np.cumsum(cnt) - cnt)[lit], cnt[lit]
        step = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        out[np.repeat(at, n) + step] = d[np.repeat(pk[lit] + 1, n) + step]
    return out


# ---- Radiance .hdr ---------------------------------------------------------------------------
def _hdr_header(data: bytes) -> tuple[float, int, int, int]:
    """(EXPOSURE, width, height, where the scanlines begin) of a Radiance file, its size checked."""
    if not (data.startswith(b"#?RADIANCE") or data.startswith(b"#?RGBE")):
        raise SceneError("body", "not a Radiance .hdr file: it must begin with #?RADIANCE")
    end = data.find(b"\n\n", 0, limits.MAX_ENV_HEADER_BYTES)
    if end < 0:
        raise SceneError(
            "body", f"no end of the .hdr header (an empty line) in its first {limits.MAX_ENV_HEADER_BYTES} bytes"
        )
    exposure = 1.0
    for line in data[:end].decode("latin-1").split("\n")[1:]:
        key, _, value = line.partition("=")
        if key.strip() == "FORMAT" and value.strip() != "32-bit_rle_rgbe":
            raise SceneError("body", f"FORMAT={value.strip()}: only 32-bit_rle_rgbe (RGB) is read")
        if key.strip() == "EXPOSURE":
            try:
                exposure *= float(value)
            except ValueError:
                raise SceneError("body", f"EXPOSURE={value.strip()} is not a number") from None
    if not (math.isfinite(exposure) and exposure > 0):
        raise SceneError("body", "EXPOSURE must be a finite number > 0")
    pos = end + 2
    nl = data.find(b"\n", pos, pos + 64)
    words = data[pos : nl if nl >= 0 else pos].decode("latin-1").split()
    if len(words) != 4 or words[0] != "-Y" or words[2] != "+X" or not (words[1].isdigit() and words[3].isdigit()):
        raise SceneError("body", "the resolution line must be '-Y <height> +X <width>' (the standard orientation)")
    height, width = int(words[1]), int(words[3])
    check_size(width, height)  # before anything of that size exists
    return exposure, width, height, nl + 1


def declared_size(data: bytes, fmt: str) -> tuple[int, int]:
    """(width, height) an image file declares, read from its header alone (SceneError as the
    readers: a file whose header is refused, a size past the limits)."""
    if fmt not in ENV_FORMATS:
        raise SceneError("format", f"unknown image format {fmt!r}; accepted: {', '.join(ENV_FORMATS)}")
    if not data:
        raise SceneError("body", "empty body: send the image file's bytes")
    if fmt == "hdr":
        return _hdr_header(data)[1:3]
    x0, y0, x1, y1 = exr_header(data)["dataWindow"]
    check_size(x1 - x0 + 1, y1 - y0 + 1)
    return x1 - x0 + 1, y1 - y0 + 1


def read_hdr(data: bytes) -> np.ndarray:
    """The texels of a Radiance RGBE file (``#?RADIANCE``, ``FORMAT=32-bit_rle_rgbe``, the standard
    orientation ``-Y H +X W``; flat or run-length encoded scanlines): float32 (H, W, 3), row 0 at
    the top, divided by the header's EXPOSURE."""
    exposure, width, height, pos = _hdr_header(data)
    n = len(data)
    d = np.frombuffer(data, dtype=np.uint8)
    out = np.empty((height, width, 4), dtype=np.uint8)
    span = width  # bytes of the last run-length scanline
    first = 0
    if 8 <= width < 32768:  # as many scanlines at once as are plain, then one by one
        pk, pos = _rle_scanlines(data, pos, width, height)
        first = _rle_rows(d, pk, out)
    for y in range(first, height):
        if 8 <= width < 32768 and data[pos : pos + 2] == b"\x02\x02" and pos + 4 <= n:
            if (data[pos + 2] << 8 | data[pos + 3]) != width:
                raise SceneError("body", f"scanline {y}: its run-length header says another width")
            pk, end = _rle_scanline(data, pos + 4, width, y, 2 * span)
            span, pos = end - pos, end
            out[y] = _rle_bytes(d, pk).reshape(4, width).T
        else:
            if data[pos : pos + 3] == b"\x01\x01\x01":
                raise SceneError("body", "old-style run-length encoding is not read: save the file again")
            if pos + 4 * width > n:
                raise SceneError("body", f"the file ends inside scanline {y}")
            out[y] = d[pos : pos + 4 * width].reshape(width, 4)
            pos += 4 * width
    e = out[..., 3].astype(np.int32)
    # m · 2^(e − 128 − 8), as Ward's reader; in float32 (2^−136 is a subnormal there, exact), so a
    # 4096 × 2048 image takes 100 MiB, not twice that
    f = np.where(e > 0, np.ldexp(np.float32(1.0), e - 136), np.float32(0.0)).astype(np.float32)
    del e
    rgb = out[..., :3].astype(np.float32)
    del out
    rgb *= f[..., None]
    if exposure != 1.0:
        rgb /= np.float32(exposure)
    return check_texels(rgb)


def write_hdr(rgb: np.ndarray) -> bytes:
    """A flat (not run-length encoded) Radiance file of ``rgb`` (H, W, 3) ≥ 0 (tests, tools)."""
    a = np.asarray(rgb, dtype=np.float64)
    h, w = a.shape[:2]
    top = a.max(axis=2)
    mant, exp = np.frexp(top)
    scale = np.where(top > 1e-32, mant * 256.0 / np.where(top > 0, top, 1.0), 0.0)
    px = np.zeros((h, w, 4), dtype=np.uint8)
    px[..., :3] = np.clip(a * scale[..., None], 0, 255).astype(np.uint8)
    px[..., 3] = np.where(top > 1e-32, exp + 128, 0).astype(np.uint8)
    return b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode() + px.tobytes()


# ---- OpenEXR ---------------------------------------------------------------------------------
def exr_header(data: bytes) -> dict[str, Any]:
    """The attributes of a single-part scan-line or tiled EXR file that say its size and channels
    (``dataWindow``: (xmin, ymin, xmax, ymax); ``channels``: name → pixel type), read from the
    bytes without the library, so the size is checked before it allocates anything."""
    if len(data) < 8 or data[:4] != b"\x76\x2f\x31\x01":
        raise SceneError("body", "not an OpenEXR file (its magic number is missing)")
    flags = struct.unpack_from("<I", data, 4)[0]
    if flags & 0xFF != 2:
        raise SceneError("body", f"EXR version {flags & 0xFF}: only version 2 is read")
    if flags & 0x1800:
        raise SceneError("body", "a multi-part or deep EXR file: only single-part flat images are read")
    pos = 8
    out: dict[str, Any] = {}
    limit = min(len(data), 8 + limits.MAX_ENV_HEADER_BYTES)
    while True:
        if pos >= limit:
            raise SceneError("body", "the EXR header does not end (or is too long)")
        if data[pos] == 0:
            break
        try:
            name_end = data.index(b"\0", pos, limit)
            type_end = data.index(b"\0", name_end + 1, limit)
        except ValueError:
            raise SceneError("body", "the EXR header is cut short") from None
        name = data[pos:name_end].decode("latin-1")
        if type_end + 5 > limit:
            raise SceneError("body", "the EXR header is cut short")
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        start = type_end + 5
        if size < 0 or start + size > limit:
            raise SceneError("body", f"the EXR attribute {name!r} passes the end of the header")
        value = data[start : start + size]
        if name == "dataWindow" and size == 16:
            out["dataWindow"] = struct.unpack("<4i", value)
        elif name == "channels":
            chans, k = {}, 0
            while k < len(value) and value[k] != 0:
                e = value.find(b"\0", k)
                if e < 0 or e + 17 > len(value):
                    raise SceneError("body", "the EXR channel list is cut short")
                # name NUL, int32 pixel type, uint8 pLinear, 3 reserved, int32 x and y sampling
                ptype = struct.unpack_from("<i", value, e + 1)[0]
                xs, ys = struct.unpack_from("<ii", value, e + 9)
                chans[value[k:e].decode("latin-1")] = (ptype, xs, ys)
                k = e + 17
            out["channels"] = chans
        pos = start + size
    if "dataWindow" not in out or "channels" not in out:
        raise SceneError("body", "the EXR header has no dataWindow or no channels")
    return out


def read_exr(data: bytes) -> np.ndarray:
    """The R, G, B channels (HALF or FLOAT, any compression OpenEXR reads) of a single-part EXR
    file: float32 (H, W, 3), row 0 at the top (the data window's)."""
    head = exr_header(data)
    x0, y0, x1, y1 = head["dataWindow"]
    check_size(x1 - x0 + 1, y1 - y0 + 1)
    if len(head["channels"]) > limits.MAX_ENV_CHANNELS:
        raise SceneError(
            "body",
            f"the EXR file has {len(head['channels'])} channels; at most {limits.MAX_ENV_CHANNELS} are accepted "
            "(R, G and B are read): save the image with fewer",
        )
    for c in "RGB":
        kind = head["channels"].get(c)
        if kind is None:
            raise SceneError("body", f"the EXR file has no {c} channel (R, G and B are read)")
        if kind[0] not in (1, 2) or kind[1:] != (1, 1):
            raise SceneError("body", f"channel {c}: only HALF or FLOAT samples, one per pixel, are read")
    import OpenEXR

    try:
        with OpenEXR.File(io.BytesIO(data), separate_channels=True) as f:
            ch = f.channels()
            rgb = np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=2)
    except Exception as e:  # the library's own errors: the file is damaged past its header
        raise SceneError("body", f"the EXR file does not decode ({type(e).__name__}: {e})") from None
    return check_texels(rgb)


def read_image(data: bytes, fmt: str) -> np.ndarray:
    """An environment image's texels from a file's bytes in ``fmt`` (``hdr`` or ``exr``)."""
    if fmt not in ENV_FORMATS:
        raise SceneError("format", f"unknown image format {fmt!r}; accepted: {', '.join(ENV_FORMATS)}")
    if not data:
        raise SceneError("body", "empty body: send the image file's bytes")
    return read_hdr(data) if fmt == "hdr" else read_exr(data)


def image_ref(texels: np.ndarray) -> str:
    """An uploaded image's reference in scene JSON: a digest of its texels."""
    return "image-" + hashlib.sha256(np.ascontiguousarray(texels, dtype=np.float32).tobytes()).hexdigest()[:16]


# ---- the map ---------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class EnvironmentMap:
    """An equirectangular image as the environment: ``texels`` float32 (H, W, 3) (the module's
    convention), times ``scale``, turned by ``rotation_deg`` about +y. ``ref``: how scene JSON
    names the image (:data:`SKY_REF`, or an uploaded image's :func:`image_ref`)."""

    ref: str
    texels: np.ndarray = field(repr=False)
    scale: float = 1.0
    rotation_deg: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.ref, str) or not self.ref or len(self.ref) > 64:
            raise SceneError("environment.image", "expected a reference of 1–64 characters")
        object.__setattr__(self, "texels", check_texels(self.texels))
        for name, lo, hi in (
            ("scale", 0.0, limits.MAX_ENV_SCALE),
            ("rotation_deg", -limits.MAX_ENV_ROTATION_DEG, limits.MAX_ENV_ROTATION_DEG),
        ):
            x = getattr(self, name)
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or not lo <= x <= hi:
                raise SceneError(f"environment.{name}", f"must be a number in [{lo:g}, {hi:g}], got {x!r}")
            object.__setattr__(self, name, float(x))

    @property
    def width(self) -> int:
        return int(self.texels.shape[1])

    @property
    def height(self) -> int:
        return int(self.texels.shape[0])

    def to_json(self) -> dict[str, Any]:
        return {"image": self.ref, "scale": self.scale, "rotation_deg": self.rotation_deg}

    # ---- directions ↔ image ----
    def uv(self, d: np.ndarray) -> np.ndarray:
        """(…, 2) image coordinates of unit directions ``d`` (…, 3)."""
        d = np.asarray(d, dtype=np.float64)
        u = np.arctan2(d[..., 0], -d[..., 2]) / (2 * math.pi) + self.rotation_deg / 360.0
        v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / math.pi
        return np.stack([u - np.floor(u), v], axis=-1)

    def direction(self, uv: np.ndarray) -> np.ndarray:
        """The unit directions (…, 3) of image coordinates ``uv`` (…, 2)."""
        uv = np.asarray(uv, dtype=np.float64)
        phi = 2 * math.pi * (uv[..., 0] - self.rotation_deg / 360.0)
        theta = math.pi * uv[..., 1]
        s = np.sin(theta)
        return np.stack([s * np.sin(phi), np.cos(theta), -s * np.cos(phi)], axis=-1)

    def radiance(self, d: np.ndarray) -> np.ndarray:
        """The radiance (…, 3) float64 seen along unit directions ``d``: bilinear, times ``scale``."""
        uv = self.uv(d)
        w, h = self.width, self.height
        s = uv[..., 0] * w - 0.5
        fs = np.floor(s)
        fx = (s - fs)[..., None]
        i0 = fs.astype(np.int64) % w
        i1 = (i0 + 1) % w
        t = uv[..., 1] * (h - 1)
        j0 = np.minimum(np.floor(t).astype(np.int64), h - 2)
        fy = (t - j0)[..., None]
        tx = self.texels.astype(np.float64)
        a = tx[j0, i0] * (1 - fx) + tx[j0, i1] * fx
        b = tx[j0 + 1, i0] * (1 - fx) + tx[j0 + 1, i1] * fx
        return self.scale * (a * (1 - fy) + b * fy)

    @property
    def held_bytes(self) -> int:
        """The bytes this image holds once drawn: its texels, the sampling tables (float32 CDFs)
        and the packed copies of both that its textures are uploaded from
        (:func:`renderer.gpu.gpu_layout.env_textures`, kept as long as the image is)."""
        texels, patches = self.width * self.height, self.width * (self.height - 1)
        return 2 * (12 * texels + 4 * (patches + self.height - 1))

    # ---- sampling ----
    @property
    def patch_weights(self) -> np.ndarray:
        """float64 (H − 1, W): each patch's mean corner luminance × its row band's solid angle / 2π
        (made again when asked: the sampling tables are what is kept)."""
        lum = self.texels.astype(np.float64) @ np.asarray(LUMINANCE)
        corners = lum[:-1] + lum[1:]
        mean = 0.25 * (corners + np.roll(corners, -1, axis=1))
        cos = np.cos(np.pi * np.arange(self.height) / (self.height - 1))
        weights = mean * (cos[:-1] - cos[1:])[:, None]
        return weights if weights.sum() > 0 else np.ones_like(weights)  # a black image: uniform

    @cached_property
    def sampling_tables(self) -> tuple[np.ndarray, np.ndarray]:
        """(conditional, marginal): float32 (H − 1, W) CDFs of each row's patches, and (H − 1,) of
        the rows; each ends at exactly 1 (a row without light: uniform)."""
        wts = self.patch_weights
        rows = wts.sum(axis=1)
        safe = np.where(rows > 0, rows, 1.0)[:, None]
        cond = np.where(rows[:, None] > 0, np.cumsum(wts, axis=1) / safe, np.arange(1, self.width + 1) / self.width)
        cond[:, -1] = 1.0
        marg = np.cumsum(rows) / rows.sum()
        marg[-1] = 1.0
        return cond.astype(np.float32), marg.astype(np.float32)

    def pdf(self, d: np.ndarray) -> np.ndarray:
        """The sampling's pdf (per steradian) of unit directions ``d``, from the float32 tables as
        the shader has them."""
        cond, marg = self.sampling_tables
        uv = self.uv(d)
        w, h = self.width, self.height
        i = np.floor(uv[..., 0] * w - 0.5).astype(np.int64) % w
        j = np.minimum(np.floor(uv[..., 1] * (h - 1)).astype(np.int64), h - 2)
        pm = marg[j].astype(np.float64) - np.where(j > 0, marg[np.maximum(j - 1, 0)], 0.0)
        pc = cond[j, i].astype(np.float64) - np.where(i > 0, cond[j, np.maximum(i - 1, 0)], 0.0)
        sin = np.sin(np.pi * uv[..., 1])
        return np.where(sin > 0, pm * pc * w * (h - 1) / (2 * np.pi**2 * np.where(sin > 0, sin, 1.0)), 0.0)

    def sample(self, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
        """Unit directions (…, 3) for uniform numbers ``u1``, ``u2`` (as the shader samples)."""
        cond, marg = self.sampling_tables
        w, h = self.width, self.height
        u1, u2 = np.asarray(u1, dtype=np.float64), np.asarray(u2, dtype=np.float64)
        j = np.minimum(np.searchsorted(marg, u1, side="right"), h - 2)
        lo = np.where(j > 0, marg[np.maximum(j - 1, 0)], 0.0)
        fy = np.clip((u1 - lo) / np.maximum(marg[j] - lo, 1e-30), 0, 1)
        rows = cond[j]
        i = np.minimum((rows <= u2[..., None]).sum(axis=-1), w - 1)
        lo = np.where(i > 0, np.take_along_axis(rows, np.maximum(i - 1, 0)[..., None], -1)[..., 0], 0.0)
        hi = np.take_along_axis(rows, i[..., None], -1)[..., 0]
        fx = np.clip((u2 - lo) / np.maximum(hi - lo, 1e-30), 0, 1)
        u = ((i + 0.5 + fx) / w) % 1.0
        v = (j + fy) / (h - 1)
        return self.direction(np.stack([u, v], axis=-1))
