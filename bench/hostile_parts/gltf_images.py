"""Images inside a glTF model as an attack (``POST /api/sessions/{id}/meshes?format=glb``), one server:

- ``gltf_images``: a GLB whose image header declares 60,000 × 60,000 pixels and holds none (refused by
  its header before any decoder runs); a decompression bomb, a real PNG of 8,192 × 8,192 zeros
  (~0.3 MB that decodes to 256 MiB: within MAX_MODEL_IMAGE_SIDE, decoded, reduced to the texture
  bound MAX_TEXTURE_SIDE); three such bombs in one GLB (the third past MAX_TEXTURE_TEXELS by the
  declared sizes, refused before it is decoded).

For each: the answer's status, its time, the first words of its message, the session's texture bytes
after it (scene_info's: the GPU texture array's, every mip level), the server's resident memory and
the peak of its model workers. An honest textured GLB
(256 × 256) is sent first, twice (the first answer starts the workers). Run against another checkout
with ``--root`` (the base commit: "before", where a model's images are not decoded at all).
"""

from __future__ import annotations

import io
import json
import struct
import time
import zlib
from pathlib import Path

import httpx
import numpy as np

OCTETS = {"content-type": "application/octet-stream"}


def _glb(images: list[bytes]) -> bytes:
    """A GLB of one triangle whose material reads each of ``images`` (PNG bytes in the BIN chunk)."""
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()
    uv = np.array([[0, 0], [1, 0], [0, 1]], np.float32).tobytes()
    binary = bytearray(pos + uv)
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 24}]
    for data in images:
        binary += b"\0" * (-len(binary) % 4)
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        binary += data
    binary += b"\0" * (-len(binary) % 4)
    slots = ["baseColorTexture", "metallicRoughnessTexture"]
    pbr = {slot: {"index": i} for i, slot in enumerate(slots[: len(images)])}
    material: dict = {"pbrMetallicRoughness": pbr}
    if len(images) > 2:
        material["emissiveTexture"] = {"index": 2}
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": views,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
        ],
        "images": [{"bufferView": 2 + i, "mimeType": "image/png"} for i in range(len(images))],
        "textures": [{"source": i} for i in range(len(images))],
        "materials": [material],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j + struct.pack("<I4s", len(binary), b"BIN\0") + bytes(binary)
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _png(width: int, height: int, rows: bytes | None = None) -> bytes:
    """An RGBA PNG of ``width`` × ``height`` zeros (``rows``: its raw scanlines instead), deflated a
    row at a time so that the bomb is never held decoded here."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    z = zlib.compressobj(9)
    line = b"\0" * (1 + 4 * width)  # filter byte, then the row
    idat = b"".join(z.compress(line) for _ in range(height)) + z.flush() if rows is None else zlib.compress(rows)
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


def _header_only(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))


def honest() -> bytes:
    from PIL import Image

    pixels = (np.indices((256, 256)).sum(axis=0) % 2 * 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(np.dstack([pixels] * 3 + [np.full_like(pixels, 255)]), "RGBA").save(buf, "PNG")
    return _glb([buf.getvalue()])


def part_gltf_images(root: Path, args) -> dict:
    from bench.hostile import Server
    from bench.hostile_parts.archives import _worker_peak_mib

    bomb = _png(8192, 8192)
    bodies = {
        "honest_first": honest(),
        "honest": honest(),
        "declared_60000": _glb([_header_only(60_000, 60_000)]),
        "png_bomb_8192": _glb([bomb]),
        "three_bombs": _glb([bomb, _png(8192, 8191), _png(8191, 8192)]),
    }
    s = Server(root, max_body_bytes=str(16 << 20))
    out: dict = {}
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            for name, body in bodies.items():
                sid = c.post("/api/sessions", json={"mesh_scene": {"kind": "spheres"}}).json()["id"]
                t0 = time.perf_counter()
                r = c.post(f"/api/sessions/{sid}/meshes", params={"format": "glb"}, content=body, headers=OCTETS)
                ms = round((time.perf_counter() - t0) * 1e3)
                detail = r.json().get("detail") if r.status_code >= 400 else None
                msg = detail[0]["msg"] if isinstance(detail, list) and detail else str(detail or "")
                info = c.get(f"/api/sessions/{sid}").json()["scene_info"]
                out[name] = {
                    "bytes_sent": len(body),
                    "status": r.status_code,
                    "ms": ms,
                    "message": msg[:110],
                    "texture_bytes": info.get("texture_bytes", 0),
                    "server_rss_mib": round(s.memory()["VmRSS"]),
                    "worker_peak_mib": _worker_peak_mib(s.proc.pid),
                }
    finally:
        s.close()
    return out


PARTS = {"gltf_images": part_gltf_images}
