"""What reading an OBJ with its materials costs: renderer.io.obj_model's reader against trimesh's OBJ
loader (materials skipped, as the service used it), each in a fresh process (its CPU seconds, the
median of ``--repeats``, and its peak resident memory), on

- ``grid``: a generated height field of ``--side``² vertices (v, vt, one vn), quads with
  ``v/vt/vn`` corners, one material (~1 M triangles at the default side 700: near MAX_TRIANGLES);
- ``spider``: assimp's ``OBJ/spider.obj`` with its MTL and five JPEG textures (four read).

Usage: ``.venv/bin/python -m bench.obj_model_parse [--side 700] [--repeats 3]``. Prints a markdown
table; writes nothing but a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SPIDER = Path("/usr/share/assimp/models/OBJ/spider.obj")
_RUN = r"""
import io, json, resource, sys, time
from pathlib import Path
path, reader = Path(sys.argv[1]), sys.argv[2]
t0 = time.process_time()
if reader == "obj_model":
    from renderer import limits
    from renderer.io.mesh_io import model_files
    from renderer.io.obj_model import load_obj_model
    m = load_obj_model(model_files(path), max_triangles=limits.MAX_TRIANGLES, max_vertices=limits.MAX_MESH_VERTICES)
    out = {"triangles": m.n_triangles, "parts": len(m.parts), "textures": len(m.textures)}
else:
    import trimesh
    t = trimesh.load(io.BytesIO(path.read_bytes()), file_type="obj", process=False, skip_materials=True)
    g = [t] if isinstance(t, trimesh.Trimesh) else list(t.geometry.values())
    out = {"triangles": sum(len(x.faces) for x in g), "parts": len(g), "textures": 0}
out["cpu_s"] = time.process_time() - t0
out["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def grid(folder: Path, side: int) -> Path:
    xs, ys = np.meshgrid(np.arange(side, dtype=float), np.arange(side, dtype=float))
    x, y = xs.ravel(), ys.ravel()
    idx = np.arange(side * side).reshape(side, side) + 1
    q = np.column_stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()])
    lines = ["mtllib grid.mtl", "usemtl ground"]
    lines += [f"v {a:.6f} {b:.6f} {np.sin(a * 0.1):.6f}" for a, b in zip(x, y, strict=True)]
    lines += [f"vt {a / side:.6f} {b / side:.6f}" for a, b in zip(x, y, strict=True)]
    lines += ["vn 0 0 1"]
    lines += [f"f {a}/{a}/1 {b}/{b}/1 {c}/{c}/1 {d}/{d}/1" for a, b, c, d in q.tolist()]
    path = folder / "grid.obj"
    path.write_text("\n".join(lines) + "\n")
    (folder / "grid.mtl").write_text("newmtl ground\nKd 0.5 0.4 0.3\nNs 50\n")
    return path


def measure(path: Path, reader: str, repeats: int) -> dict:
    runs = []
    for _ in range(repeats):
        r = subprocess.run([sys.executable, "-c", _RUN, str(path), reader], capture_output=True, check=True)
        runs.append(json.loads(r.stdout))
    out = dict(runs[-1])
    out["cpu_s"] = statistics.median(x["cpu_s"] for x in runs)
    out["peak_mib"] = max(x["peak_mib"] for x in runs)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side", type=int, default=700)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        files = {"grid": grid(Path(tmp), args.side), "spider": SPIDER}
        print("| file | MB | reader | triangles | parts | textures | CPU s (median) | peak MiB |")
        print("|---|---|---|---|---|---|---|---|")
        for name, path in files.items():
            for reader in ("obj_model", "trimesh"):
                m = measure(path, reader, args.repeats)
                print(
                    f"| {name} | {path.stat().st_size / 1e6:.1f} | {reader} | {m['triangles']:,} | {m['parts']} | "
                    f"{m['textures']} | {m['cpu_s']:.2f} | {m['peak_mib']:.0f} |"
                )


if __name__ == "__main__":
    main()
