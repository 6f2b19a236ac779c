"""Zipped model folders (``POST /api/meshes?format=zip``) as an attack, one server each:

- ``archive_bomb``: deflate bombs — one entry of ``--bomb-mib`` (1,024) MiB of zeros (~1 MB sent);
  the same stream under a central directory that declares 100 bytes (the size hidden); and 300
  entries of 1 MiB of zeros each (each under the ratio's floor, 300 MiB together);
- ``archive_entries``: ``--archive-entries`` (150,000) empty entries in one ~13 MB zip;
- ``archive_nested``: a zip holding the bomb as an inner zip.

For each: the answer's status, its time, the first words of its message, and the resident memory
of the server and the peak of its model workers (the processes that open the archive). A model
folder zipped honestly (a glTF with its .bin and image, ~3 kB) is sent first: its answer and time.
Run against another checkout with ``--root`` (the base commit: "before", where ``format=zip`` is
not a format).
"""

from __future__ import annotations

import io
import struct
import time
import zipfile
from pathlib import Path

import httpx

MIB = 1 << 20
OCTETS = {"content-type": "application/octet-stream"}


def add_arguments(ap) -> None:
    ap.add_argument("--bomb-mib", type=int, default=1024, help="archive_bomb: MiB of zeros in the one entry")
    ap.add_argument("--archive-entries", type=int, default=150_000, help="archive_entries: empty entries")


def zipped(files: dict[str, bytes], method: int = zipfile.ZIP_DEFLATED) -> bytes:
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", method, compresslevel=1 if method == zipfile.ZIP_DEFLATED else None) as z:
        for name, data in files.items():
            z.writestr(name, data)
    return out.getvalue()


def zeros_entry(mib: int, name: str = "bomb.obj") -> bytes:
    """A zip of one entry of ``mib`` MiB of zeros, deflated a MiB at a time (never held whole)."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED, compresslevel=9) as z:
        info = zipfile.ZipInfo(name)
        info.compress_type = zipfile.ZIP_DEFLATED
        with z.open(info, "w", force_zip64=True) as f:
            block = bytes(MIB)
            for _ in range(mib):
                f.write(block)
    return out.getvalue()


def hide_size(data: bytes, size: int = 100) -> bytes:
    """The zip with every central-directory entry's uncompressed size set to ``size`` (zip64's extra
    field dropped to the 32-bit one)."""
    out = bytearray(data)
    at = 0
    while (at := out.find(b"PK\x01\x02", at)) >= 0:
        struct.pack_into("<I", out, at + 24, size)
        at += 4
    return bytes(out)


def honest_folder() -> bytes:
    from renderer.geometry.meshes import icosphere
    from renderer.io.mesh_io import export_mesh

    obj = b"mtllib ball.mtl\nusemtl clay\n" + export_mesh(icosphere(2), "obj")
    png = b"\x89PNG\r\n\x1a\n" + struct.pack(">I4sII", 13, b"IHDR", 64, 64) + bytes(9)
    return zipped(
        {"ball/ball.obj": obj, "ball/ball.mtl": b"newmtl clay\nKd 0.8 0.8 0.8\nmap_Kd a.png\n", "ball/a.png": png}
    )


def _worker_peak_mib(pid: int) -> float:
    """The largest VmHWM among the server's child processes (the model workers), MiB."""
    peak = 0.0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            children = (task / "children").read_text().split()
        except OSError:
            continue
        for child in children:
            try:
                for line in Path(f"/proc/{child}/status").read_text().splitlines():
                    if line.startswith("VmHWM:"):
                        peak = max(peak, int(line.split()[1]) / 1024)
            except OSError:
                pass
    return round(peak)


def _send(root: Path, bodies: dict[str, bytes]) -> dict:
    from bench.hostile import Server

    s = Server(root, max_body_bytes=str(16 * MIB))
    out: dict = {}
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            # the first answer starts the model workers (imports): the second is an upload's own time
            for name, body in {"honest_first": honest_folder(), "honest": honest_folder(), **bodies}.items():
                t0 = time.perf_counter()
                r = c.post("/api/meshes", params={"format": "zip", "size": 10}, content=body, headers=OCTETS)
                ms = round((time.perf_counter() - t0) * 1e3)
                detail = (
                    r.json().get("detail") if r.headers.get("content-type", "").startswith("application/json") else None
                )
                msg = detail[0]["msg"] if isinstance(detail, list) and detail else str(detail or "")[:0]
                out[name] = {
                    "bytes_sent": len(body),
                    "status": r.status_code,
                    "ms": ms,
                    "message": msg[:110],
                    "server_rss_mib": round(s.memory()["VmRSS"]),
                    "worker_peak_mib": _worker_peak_mib(s.proc.pid),
                }
    finally:
        s.close()
    return out


def part_archive_bomb(root: Path, args) -> dict:
    bomb = zeros_entry(args.bomb_mib)
    spread = zipped(
        {"box.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", **{f"t/{i}.png": bytes(MIB) for i in range(300)}}
    )
    return _send(root, {"bomb": bomb, "bomb_size_hidden": hide_size(bomb), "spread_300_mib": spread})


def part_archive_entries(root: Path, args) -> dict:
    files = {str(i): b"" for i in range(args.archive_entries)}
    files["box.obj"] = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    return _send(root, {"many_entries": zipped(files, zipfile.ZIP_STORED)})


def part_archive_nested(root: Path, args) -> dict:
    inner = zeros_entry(min(args.bomb_mib, 256), "inner.obj")
    return _send(root, {"nested": zipped({"box.obj": b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "more.zip": inner})})


PARTS = {
    "archive_bomb": part_archive_bomb,
    "archive_entries": part_archive_entries,
    "archive_nested": part_archive_nested,
}
