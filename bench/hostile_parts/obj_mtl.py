"""OBJ material libraries as an attack: zipped model folders whose ``.mtl`` reaches out of the
folder, defines or uses more materials than a scene holds, floods ``usemtl`` with names nothing
defines, or names an image bomb or more textures than a scene holds.

``obj_mtl`` sends each as ``POST /api/meshes?format=zip`` to a real server of ``--root`` (the
reader the server's dispatcher picks answers) and hands it to that checkout's OBJ reader itself
(``renderer.io.obj_model.load_obj_model``, in a child process with ``--root`` as its working
directory: the reader's own answer, its CPU seconds and peak memory, whatever the upload route
does with OBJ). The base commit has no such reader ("before": the server ignores the ``.mtl``).

Cases (``--mtl-materials`` sets the big library's size, 100,000):

- ``escape_mtllib``: ``mtllib ../../../etc/passwd``;
- ``escape_map``: ``map_Kd ..\\..\\..\\etc\\passwd`` (Windows separators);
- ``absolute_map``: ``map_Kd /etc/passwd`` (an author's absolute path: only its file name is
  looked up, in the folder);
- ``library_100k_one_used``: the big library, one material used;
- ``library_100k_all_used``: the big library, every material used by a face of its own;
- ``usemtl_flood``: 200,000 ``usemtl`` names no library defines, beside a 20,000-material library;
- ``image_bomb``: ``map_Kd`` of a PNG whose header declares 100,000 × 100,000 pixels;
- ``textures_65``: 65 materials, each its own 1 × 1 texture.

Loopback only; every loop is bounded.
"""

from __future__ import annotations

import io
import json
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path

import httpx

MIB = 1 << 20
OCTETS = {"content-type": "application/octet-stream"}
TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
# Runs in the child, in the checkout under test: the reader's answer as one JSON line.
_READER = r"""
import json, resource, sys, time, zipfile, io
try:
    from renderer.io.obj_model import load_obj_model
except ImportError:
    print(json.dumps({"reader": "none in this checkout"})); raise SystemExit
from renderer import limits
from renderer.io.model_archive import open_archive
from renderer.geometry.scene import SceneError
data = sys.stdin.buffer.read()
t0 = time.process_time()
try:
    m = load_obj_model(open_archive(data), max_triangles=limits.MAX_TRIANGLES, max_vertices=limits.MAX_MESH_VERTICES)
    out = {"reader": "model", "materials": len(m.materials), "textures": len(m.textures),
           "notices": len(m.notices), "first_notice": (m.notices or ("",))[0][:110]}
except SceneError as e:
    out = {"reader": "refused", "message": e.message[:110]}
out["cpu_s"] = round(time.process_time() - t0, 3)
out["peak_mib"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
print(json.dumps(out))
"""


def add_arguments(ap) -> None:
    ap.add_argument("--mtl-materials", type=int, default=100_000, help="obj_mtl: materials of the big library")


def zipped(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, compresslevel=6) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def png_1x1(value: int) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (1, 1), (value, value, value)).save(buf, format="PNG")
    return buf.getvalue()


def png_bomb(side: int = 100_000) -> bytes:
    """A PNG header declaring ``side``² RGBA pixels and no data worth the name."""
    ihdr = b"IHDR" + struct.pack(">IIBBBBB", side, side, 8, 6, 0, 0, 0)
    chunk = struct.pack(">I", 13) + ihdr + struct.pack(">I", zlib.crc32(ihdr) & 0xFFFFFFFF)
    return b"\x89PNG\r\n\x1a\n" + chunk + bytes(64)


def folder(obj: str, side: dict[str, bytes]) -> bytes:
    return zipped({"model/model.obj": obj.encode(), **{f"model/{k}": v for k, v in side.items()}})


def cases(n_materials: int) -> dict[str, bytes]:
    face = "f 1/1 2/2 3/3\n"
    big = "".join(f"newmtl m{i}\nKd 0.5 0.5 0.5\nNs 10\n" for i in range(n_materials)).encode()
    small = "".join(f"newmtl M{i}\n" for i in range(20_000)).encode()
    return {
        "escape_mtllib": folder("mtllib ../../../etc/passwd\nusemtl a\n" + TRIANGLE + face, {}),
        "escape_map": folder(
            "mtllib m.mtl\nusemtl a\n" + TRIANGLE + face, {"m.mtl": b"newmtl a\nmap_Kd ..\\..\\..\\etc\\passwd\n"}
        ),
        "absolute_map": folder(
            "mtllib m.mtl\nusemtl a\n" + TRIANGLE + face, {"m.mtl": b"newmtl a\nmap_Kd /etc/passwd\n"}
        ),
        "library_100k_one_used": folder(
            f"mtllib big.mtl\nusemtl m{n_materials - 1}\n" + TRIANGLE + face, {"big.mtl": big}
        ),
        "library_100k_all_used": folder(
            "mtllib big.mtl\n" + TRIANGLE + "".join(f"usemtl m{i}\n{face}" for i in range(n_materials)),
            {"big.mtl": big},
        ),
        "usemtl_flood": folder(
            "mtllib m.mtl\n" + TRIANGLE + "".join(f"usemtl x{i}\n{face}" for i in range(200_000)), {"m.mtl": small}
        ),
        "image_bomb": folder(
            "mtllib m.mtl\nusemtl a\n" + TRIANGLE + face,
            {"m.mtl": b"newmtl a\nmap_Kd bomb.png\n", "bomb.png": png_bomb()},
        ),
        "textures_65": folder(
            "mtllib m.mtl\n" + TRIANGLE + "".join(f"usemtl m{i}\n{face}" for i in range(65)),
            {
                "m.mtl": "".join(f"newmtl m{i}\nmap_Kd t{i}.png\n" for i in range(65)).encode(),
                **{f"t{i}.png": png_1x1(i) for i in range(65)},
            },
        ),
    }


def _reader(root: Path, body: bytes) -> dict:
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", _READER], input=body, cwd=root, capture_output=True, timeout=300, check=False
    )
    lines = r.stdout.decode(errors="replace").strip().splitlines()
    out = json.loads(lines[-1]) if lines else {"reader": "crashed", "stderr": r.stderr.decode(errors="replace")[-300:]}
    out["wall_s"] = round(time.perf_counter() - t0, 2)
    return out


def part_obj_mtl(root: Path, args) -> dict:
    from bench.hostile import Server

    bodies = cases(args.mtl_materials)
    out: dict = {name: {"bytes_sent": len(body), **_reader(root, body)} for name, body in bodies.items()}
    s = Server(root, max_body_bytes=str(16 * MIB))
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            for name, body in bodies.items():
                t0 = time.perf_counter()
                r = c.post("/api/meshes", params={"format": "zip", "size": 10}, content=body, headers=OCTETS)
                ms = round((time.perf_counter() - t0) * 1e3)
                detail = (
                    r.json().get("detail") if r.headers.get("content-type", "").startswith("application/json") else None
                )
                msg = detail[0]["msg"] if isinstance(detail, list) and detail else ""
                out[name].update(
                    server_status=r.status_code,
                    server_ms=ms,
                    server_message=msg[:110],
                    passwd_in_answer=b"root:" in r.content,
                )
        out["server_rss_mib"] = round(s.memory()["VmRSS"])
    finally:
        s.close()
    return out


PARTS = {"obj_mtl": part_obj_mtl}
