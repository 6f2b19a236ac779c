"""Model files from assimp's corpus parsed and uploaded: the parse's CPU time in this process (best
of ``--repeat``) and an upload's wall time through a server child of ``--root``
(``POST /api/sessions/{id}/meshes``: a GLB alone, a .gltf as a zip of its folder; the median
after one warm-up), with what the session holds
after it (meshes, triangles as traced and distinct, texture bytes).

    .venv/bin/python -m bench.model_upload                     # this checkout
    .venv/bin/python -m bench.model_upload --root /tmp/base    # another one (its server; its parser
                                                               # in a child with its own path)

Prints one JSON object per file. Timings on a shared machine: give its load with them.
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parent.parent
CORPUS = Path("/usr/share/assimp/models/glTF2")
FILES = (
    "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
    "BoxTextured-glTF-Binary/BoxTextured.glb",
    "ClearCoat-glTF/ClearCoatTest.gltf",
    "textureTransform/TextureTransformTest.gltf",
)
OCTETS = {"content-type": "application/octet-stream"}

# run in a child with the measured checkout first on its path: its own loader (load_model, or
# load_mesh where there is none)
_PARSE = """
import json, sys, time
import renderer.io.mesh_io as m
load = getattr(m, "load_model", None) or m.load_mesh
path, repeat = sys.argv[1], int(sys.argv[2])
load(path)
best = min((lambda t: (load(path), time.process_time() - t)[1])(time.process_time()) for _ in range(repeat))
print(json.dumps(round(best * 1e3, 1)))
"""


def parse_ms(root: Path, path: Path, repeat: int) -> float:
    out = subprocess.run(
        [sys.executable, "-c", _PARSE, str(path), str(repeat)],
        cwd=root,
        env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def _body(path: Path) -> tuple[str, bytes]:
    """What a user sends: a GLB alone, a .gltf as a zip of its folder (its .bin and images)."""
    if path.suffix != ".gltf":
        return path.suffix.lstrip("."), path.read_bytes()
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for f in path.parent.iterdir():
            if f.is_file() and (f == path or f.suffix.lower() in (".bin", ".png", ".jpg", ".jpeg")):
                z.write(f, f.name)
    return "zip", out.getvalue()


def upload(root: Path, files: list[Path], uploads: int) -> dict[str, dict]:
    from bench.hostile import Server

    s = Server(root, max_body_bytes=str(16 << 20))
    out = {}
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            for path in files:
                times, r = [], None
                for _ in range(uploads + 1):
                    sid = c.post("/api/sessions", json={"mesh_scene": {"kind": "spheres"}}).json()["id"]
                    t0 = time.perf_counter()
                    fmt, body = _body(path)
                    r = c.post(
                        f"/api/sessions/{sid}/meshes", params={"format": fmt, "size": 20}, content=body, headers=OCTETS
                    )
                    times.append((time.perf_counter() - t0) * 1e3)
                assert r is not None and r.status_code == 201, r.text if r is not None else ""
                info = r.json()["scene_info"]
                out[path.name] = {
                    "upload_ms": round(statistics.median(times[1:])),
                    "n_meshes": info.get("n_meshes"),
                    "n_triangles": info.get("n_triangles"),
                    "n_unique_triangles": info.get("n_unique_triangles"),
                    "texture_bytes": info.get("texture_bytes", 0),
                }
    finally:
        s.close()
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=ROOT, help="the checkout measured")
    ap.add_argument("--repeat", type=int, default=5, help="parses per file (the best is kept)")
    ap.add_argument("--uploads", type=int, default=3, help="uploads per file after the warm-up (the median)")
    args = ap.parse_args(argv)
    files = [CORPUS / f for f in FILES]
    uploaded = upload(args.root, files, args.uploads)
    for path in files:
        print(
            json.dumps(
                {"file": path.name, "parse_cpu_ms": parse_ms(args.root, path, args.repeat), **uploaded[path.name]}
            )
        )


if __name__ == "__main__":
    main()
