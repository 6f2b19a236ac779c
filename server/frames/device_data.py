"""The device-data format: what a browser receives to run the very same tracer.

``GET /api/sessions/{id}/device-data`` (:mod:`server.api.routes.device`) answers one blob
of this format: the session's scene and the chosen method's acceleration data, packed by
:mod:`renderer.gpu.gpu_layout` — the one layout the moderngl renderer uploads too — wrapped
to the device's ``max_texture_size`` (a power of two; many phones: 4,096).

Binary format (all integers little-endian)::

    offset 0   4 bytes   magic b"PRDD"
    offset 4   uint32    format version (1)
    offset 8   uint32    H = length of the JSON header in bytes
    offset 12  H bytes   JSON header, UTF-8
               padding   zero bytes up to a multiple of 16
               …         texture data; each texture at its own ``offset``
                         (from the start of the blob, a multiple of 16)

The JSON header::

    {"format": "pocketray-device-data", "format_version": 1,
     "session": {"id", "version", "scene_rev"},
     "method": "bih",                       # auto resolved
     "settings": {"mode", "max_prims", "max_tree_depth", "max_recursion_depth", "width", "height", "time",
                  "samples_per_pixel", "integrator", "tone_map", "exposure", "denoise"},
     "shader": {"method", "mode", "max_recursion_depth", "features": ["NO_TRANSMISSION", …], "url"},
     "path": {"samples_per_pass": 4, "guides": false} | null,  # the path integrator's variant (features
                                            # has PATH), else null; guides: it writes them (GUIDES),
                                            # then also "atrous": renderer/image/atrous.py's parameters()
     "max_texture_size": 4096,              # the power of two the textures were wrapped to
     "camera": {...}, "home_camera": {...}, # camera JSON of docs/FORMATS.md (current, and the reset one)
     "uniforms": {"u_num_spheres": 64, "u_plane_point": [[0, -20, 0], …], …,
                  "u_cam_pos": [...], "u_cam_right": [...], "u_cam_up": [...], "u_cam_forward": [...],
                  "u_target_distance": 100.0, "u_min_weight": 0.0, "u_box_min": [...], …},
     "textures": [{"name": "u_spheres", "width", "height", "components": 4, "dtype": "f4",
                   "internal_format": "RGBA32F", "offset", "nbytes"}, …],   # a texture array (u_textures,
                                            # "dtype": "u1", "RGBA8") adds "layers" and "levels" (encode_blob)
     "surface": {"texture_bytes", "attribute_bytes", "notices": [...]},  # a textured scene's GPU bytes on
                                            # the device (every mip level) and what was resized for it
     "stats": {...}, "build_ms": 1.2, "pack_ms": 0.3, "nbytes": …}

``uniforms`` are every uniform of :func:`gpu_layout.pack_primitives`, of the
method's ``prepare(...).packed`` and of :func:`gpu_layout.frame_uniforms` (the ε cut-off,
0 here: the device sets its frame's; the path integrator's ``u_light_scale`` and emitters),
fixed-length arrays as lists, plus the camera terms that do not depend on the image size
(:func:`camera_uniforms`; ``u_half_extent`` and ``u_resolution`` do, and the device sets
them as ``gpu_layout.camera_uniforms`` computes them).

The shader variant is the one the server's frame of the same settings compiles
(:func:`renderer.frame.plan.plan_frame`, read by :func:`device_header`): with ``integrator`` ``path`` in colour mode it
carries ``PATH`` and its ``max_recursion_depth`` is a path's segments (up to
``MAX_PATH_DEPTH``). Such a variant's ``o_image.rgb`` is the *sum* of the radiance of the
``u_sample_count`` samples from ``u_sample_start`` on (``gpu_layout.path_uniforms``, set per
draw): the device draws passes of at most ``path.samples_per_pass`` samples
(``limits.DEVICE_PATH_SAMPLES_PER_PASS``), adds them up, divides by ``samples_per_pixel`` and
shows the mean as ``renderer/image/tonemap.py`` does with the header's ``tone_map`` and
``exposure``. With ``denoise`` on (any denoiser) the variant also carries ``GUIDES``: it writes
the sums of the first hit's albedo and normal at locations 2 and 3 (two more RGBA32F targets),
which the device adds up as the radiance and hands, as means, to its à-trous filter
(``renderer/image/atrous.py``'s GLSL copy) before tone mapping. The ``settings`` a session stored
before a setting existed read as its default.
Fields were only added to the header since format version 1 (a reader ignores those it does
not know), so the version stays 1. Each texture is ``height × width × components`` elements of ``dtype``
(``f4``: float32, ``u4``: uint32), row 0 first — exactly ``PackedTexture.data``; the
device uploads them with NEAREST filtering, as the server does.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Mapping
from typing import Any

import numpy as np

from renderer.config.methods import PreparedMethod
from renderer.frame.features import FEATURE_DEFINES  # noqa: F401 - re-exported: the shader variant's feature defines, in order
from renderer.frame.plan import FramePlan
from renderer.geometry.scene import Camera, Scene
from renderer.gpu import gpu_layout, texture_layout
from renderer.image import atrous
from renderer.limits import DEFAULT_TEXTURE_WIDTH, DEVICE_PATH_SAMPLES_PER_PASS

MAGIC = b"PRDD"
FORMAT_VERSION = 1
ALIGN = 16  # bytes: every texture starts at a multiple of this
HEADER_START = 12  # bytes: magic, version, header length
DEFAULT_MAX_TEXTURE_SIZE = DEFAULT_TEXTURE_WIDTH

# GL internal format of a PackedTexture by (dtype, components): what WebGL2 and moderngl create.
INTERNAL_FORMATS = {
    ("f4", 1): "R32F",
    ("f4", 2): "RG32F",
    ("f4", 3): "RGB32F",
    ("f4", 4): "RGBA32F",
    ("u4", 1): "R32UI",
    ("u4", 2): "RG32UI",
    ("u4", 3): "RGB32UI",
    ("u4", 4): "RGBA32UI",
}


def camera_uniforms(camera: Camera) -> dict[str, Any]:
    """The camera terms of :func:`renderer.gpu.gpu_layout.camera_uniforms` that do not depend on
    the image size (the device sets ``u_half_extent`` and ``u_resolution`` per frame)."""
    return {
        k: jsonable(v)
        for k, v in gpu_layout.camera_uniforms(camera, 1, 1).items()
        if k not in ("u_half_extent", "u_resolution")
    }


def device_uniforms(scene: Scene, prims: gpu_layout.PackedScene, prepared: PreparedMethod) -> dict[str, Any]:
    """The header's ``uniforms``: the primitives', the method's and the frame's (ε 0: the device sets its
    frame's, as the camera's image-size terms), then the camera's, as JSON."""
    packed = {**prims.uniforms, **prepared.packed.uniforms, **gpu_layout.frame_uniforms(scene, 0.0)}
    uniforms = {k: jsonable(v) for k, v in packed.items()}
    uniforms.update(camera_uniforms(scene.camera))
    return uniforms


def device_stats(plan: FramePlan, prepared: PreparedMethod) -> dict[str, Any]:
    """The build's statistics with the plan's method, recursion depth and variant's defines."""
    return {
        **prepared.stats,
        "method": plan.method,
        "recursion_depth": plan.recursion_depth,
        "features_removed": list(plan.defines),
    }


def device_header(
    plan: FramePlan,
    settings: Mapping[str, Any],
    uniforms: dict[str, Any],
    stats: dict[str, Any],
    *,
    session: dict[str, Any],
    camera: dict[str, Any],
    home_camera: dict[str, Any],
    max_texture_size: int,
    shader_url: str,
    build_ms: float,
    pack_ms: float,
) -> dict[str, Any]:
    """The JSON header (the module's format) of a one-pass frame's ``plan``: ``settings`` the session's
    merged with the query's, ``session`` its id, version and scene revision, ``camera`` and
    ``home_camera`` its camera JSON, ``shader_url`` where the variant's text is served; ms timings."""
    features = plan.features
    assert features is not None, "a one-pass method's plan has its variant's features"
    chosen = plan.settings
    return {
        "format": "pocketray-device-data",
        "format_version": FORMAT_VERSION,
        "session": session,
        "method": plan.method,
        "settings": {
            **{
                k: settings[k]
                for k in ("mode", "max_prims", "max_tree_depth", "max_recursion_depth", "width", "height")
            },
            # sessions stored before animation (or the path integrator) have none of these: defaults
            **{
                k: getattr(chosen, k)
                for k in ("time", "samples_per_pixel", "integrator", "tone_map", "exposure", "denoise")
            },
        },
        "shader": {
            "method": plan.method,
            "mode": settings["mode"],
            "max_recursion_depth": plan.recursion_depth,
            "features": list(plan.defines),
            "url": shader_url,
        },
        "path": (
            {
                "samples_per_pass": DEVICE_PATH_SAMPLES_PER_PASS,
                "guides": features.guides,
                **({"atrous": atrous.parameters()} if features.guides else {}),
            }
            if features.path
            else None
        ),
        "max_texture_size": max_texture_size,
        "camera": camera,
        "home_camera": home_camera,
        "uniforms": uniforms,
        "stats": jsonable_stats(stats),
        "build_ms": build_ms,
        "pack_ms": pack_ms,
    }


def surface_info(surface: texture_layout.SurfaceData) -> dict[str, Any]:
    """The header's ``surface``: the GPU bytes of the textures (every mip level) and of the triangles'
    attribute records this device uploads, and what was resized for its limits."""
    return {
        "texture_bytes": int(surface.nbytes.get(gpu_layout.TEXTURES.name, 0)),
        "attribute_bytes": int(sum(v for k, v in surface.nbytes.items() if k != gpu_layout.TEXTURES.name)),
        "notices": list(surface.array.notices) if surface.array is not None else [],
    }


def jsonable(v: Any) -> Any:
    """``v`` with NumPy scalars and arrays (also inside lists) as plain JSON numbers and lists."""
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, (np.integer, bool)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    return v


def jsonable_stats(stats: dict[str, Any]) -> dict[str, Any]:
    """A build's statistics (nested, NumPy values and all) as plain JSON."""
    return json.loads(json.dumps(stats, default=jsonable))


def encode_blob(header: dict[str, Any], textures: dict[str, gpu_layout.PackedTexture]) -> bytes:
    """Magic, version, header length, JSON header (with the textures' offsets), aligned texture bytes.
    A texture array (:class:`renderer.gpu.gpu_layout.PackedTextureArray`, RGBA8 with mip levels) is one
    entry with ``layers`` and ``levels``: each level's ``width``, ``height``, ``offset`` and ``nbytes``
    (``layers × height × width × 4`` bytes, layer 0 first, row 0 first); its ``offset`` and ``nbytes``
    are level 0's and the levels' total."""
    entries: list[dict[str, Any]] = []
    chunks: list[list[bytes]] = []
    for name, tex in textures.items():
        w, h = tex.size
        if isinstance(tex, gpu_layout.PackedTextureArray):
            parts = [np.ascontiguousarray(level, dtype=np.uint8).tobytes() for level in tex.levels]
            levels = [
                {"width": int(level.shape[2]), "height": int(level.shape[1]), "offset": 0, "nbytes": len(b)}
                for level, b in zip(tex.levels, parts, strict=True)
            ]
            entries.append(
                {
                    "name": name,
                    "width": w,
                    "height": h,
                    "layers": tex.layers,
                    "components": 4,
                    "dtype": "u1",
                    "internal_format": "RGBA8",
                    "levels": levels,
                    "offset": 0,
                    "nbytes": sum(len(b) for b in parts),
                }
            )
            chunks.append(parts)
            continue
        data = np.ascontiguousarray(tex.data, dtype="<f4" if tex.dtype == "f4" else "<u4")
        entries.append(
            {
                "name": name,
                "width": w,
                "height": h,
                "components": tex.components,
                "dtype": tex.dtype,
                "internal_format": INTERNAL_FORMATS[(tex.dtype, tex.components)],
                "offset": 0,
                "nbytes": int(data.nbytes),
            }
        )
        chunks.append([data.tobytes()])
    # The offsets depend on the header's length, which depends on the offsets' digits: iterate.
    head = b""
    for _ in range(4):
        start = _align(HEADER_START + len(head))
        pos = start
        for e, parts in zip(entries, chunks, strict=True):
            places = e.get("levels") or [e]
            for place, c in zip(places, parts, strict=True):
                place["offset"] = pos
                pos = _align(pos + len(c))
            e["offset"] = places[0]["offset"]
        new = json.dumps({**header, "textures": entries, "nbytes": pos}, separators=(",", ":")).encode()
        if new == head:
            break
        head = new
    out = bytearray(MAGIC + struct.pack("<II", FORMAT_VERSION, len(head)) + head)
    for e, parts in zip(entries, chunks, strict=True):
        for place, c in zip(e.get("levels") or [e], parts, strict=True):
            out.extend(b"\0" * (place["offset"] - len(out)))
            out.extend(c)
    out.extend(b"\0" * (_align(len(out)) - len(out)))
    return bytes(out)


def decode_blob(blob: bytes) -> tuple[dict[str, Any], dict[str, Any]]:
    """The header and the textures as (height, width, components) arrays (for tests and tools); a
    texture array as the list of its levels, uint8 (layers, height, width, 4) each."""
    if blob[:4] != MAGIC:
        raise ValueError("not pocketray device data")
    version, n = struct.unpack_from("<II", blob, 4)
    if version != FORMAT_VERSION:
        raise ValueError(f"device-data format {version}, expected {FORMAT_VERSION}")
    header = json.loads(blob[HEADER_START : HEADER_START + n])
    arrays: dict[str, Any] = {}
    for t in header["textures"]:
        if "levels" in t:
            arrays[t["name"]] = [
                np.frombuffer(blob, dtype=np.uint8, count=lv["nbytes"], offset=lv["offset"]).reshape(
                    t["layers"], lv["height"], lv["width"], 4
                )
                for lv in t["levels"]
            ]
            continue
        a = np.frombuffer(
            blob,
            dtype="<f4" if t["dtype"] == "f4" else "<u4",
            count=t["height"] * t["width"] * t["components"],
            offset=t["offset"],
        )
        arrays[t["name"]] = a.reshape(t["height"], t["width"], t["components"])
    return header, arrays


def _align(n: int) -> int:
    """``n`` bytes rounded up to a multiple of ALIGN."""
    return -(-n // ALIGN) * ALIGN
