"""Environment images (``PUT /api/sessions/{id}/environment``) as an attack, one server each:

- ``env_memory``: one session re-uploading a 549 kB run-length ``.hdr`` of 4096 × 2048 texels
  ``--env-uploads`` (8) times, then ``--env-sessions`` (17) sessions with one upload each, a
  32 × 32 frame after every upload (the image drawn: its sampling tables and upload copies made):
  the server's resident memory after each, the answers, and the bytes the store's quota counts;
- ``env_parse``: two 16 MB ``.hdr`` files of one-byte runs (declared 4096 × 2048, cut short) sent at
  once from 127.0.0.1, and meanwhile an honest 32 kB ``.hdr`` from 127.0.0.2, ``--env-honest``
  (5) times one after another: its latency (and alone, before), the attack's answers and times.

Run against another checkout with ``--root`` (the base commit: "before").
"""

from __future__ import annotations

import statistics
import threading
import time
from pathlib import Path

import httpx
import numpy as np

MIB = 1 << 20


def add_arguments(ap) -> None:
    ap.add_argument("--env-uploads", type=int, default=8, help="env_memory: uploads to one session")
    ap.add_argument("--env-sessions", type=int, default=17, help="env_memory: sessions with one upload each")
    ap.add_argument("--env-honest", type=int, default=5, help="env_parse: the honest client's uploads")


def smooth_hdr(seed: int, width: int = 4096, height: int = 2048) -> bytes:
    """A run-length ``.hdr`` of ``width × height`` texels in runs of 127 (549 kB at 4096 × 2048):
    a brightness per row, ``seed`` in the first texel so that each file is another image."""
    out = bytearray(f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n".encode())
    runs = [127] * (width // 127) + ([width % 127] if width % 127 else [])
    for y in range(height):
        out += bytes([2, 2, width >> 8, width & 255])
        level = 64 + (y * 191) // height
        for value in (level, level, level, 129):
            first = True
            for run in runs:
                if first:
                    out += bytes([1, (seed * 37) % 256 if value != 129 else 129])
                    if run > 1:
                        out += bytes([128 + run - 1, value])
                    first = False
                else:
                    out += bytes([128 + run, value])
    return bytes(out)


def one_byte_runs(size: int = 16_000_000, width: int = 4096, height: int = 2048) -> bytes:
    """``size`` bytes of a ``.hdr`` declaring ``width × height`` whose scanlines are runs of one
    byte each: legal, the slowest to cut into packets, and cut short (refused at its end)."""
    head = f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n".encode()
    line = bytes([2, 2, width >> 8, width & 255]) + bytes([0x81, 77]) * (4 * width)
    body = line * ((size - len(head)) // len(line) + 1)
    return head + body[: size - len(head)]


def honest_hdr() -> bytes:
    """A flat 64 × 128 ``.hdr``: 32 kB."""
    from renderer.materials.envmap import write_hdr

    return write_hdr(np.linspace(0.0, 2.0, 64 * 128 * 3).reshape(64, 128, 3))


def _session(c: httpx.Client) -> str:
    r = c.post("/api/sessions", json={"scenario": 1, "n": 8, "settings": {"format": "jpeg"}})
    r.raise_for_status()
    return r.json()["id"]


def _used(c: httpx.Client) -> float | None:
    for line in c.get("/metrics").text.splitlines():
        if line.startswith("pocketray_store_bytes "):
            return round(float(line.split()[1]) / MIB, 1)
    return None


def part_env_memory(root: Path, args) -> dict:
    from bench.hostile import Server

    s = Server(root, session_create_per_min="0", max_body_bytes=str(16 * MIB))
    try:
        with httpx.Client(base_url=s.url, timeout=600) as c:
            idle = round(s.memory()["VmRSS"])

            def upload(sid: str, seed: int) -> tuple[int, float, float]:
                t0 = time.perf_counter()
                r = c.put(f"/api/sessions/{sid}/environment", params={"format": "hdr"}, content=smooth_hdr(seed))
                took = time.perf_counter() - t0
                if r.status_code == 200:
                    c.get(f"/api/sessions/{sid}/frame", params={"width": 32, "height": 32})
                return r.status_code, round(took, 2), round(s.memory()["VmRSS"])

            sid = _session(c)
            same = [upload(sid, i) for i in range(args.env_uploads)]
            c.delete(f"/api/sessions/{sid}")
            after_delete = round(s.memory()["VmRSS"])
            many = [upload(_session(c), 100 + i) for i in range(args.env_sessions)]
            used = _used(c)
        return {
            "file_kb": round(len(smooth_hdr(0)) / 1000),
            "rss_idle_mib": idle,
            "one_session": {
                "codes": [x[0] for x in same],
                "upload_s": [x[1] for x in same],
                "rss_mib": [x[2] for x in same],
            },
            "rss_after_delete_mib": after_delete,
            "many_sessions": {
                "codes": [x[0] for x in many],
                "upload_s": [x[1] for x in many],
                "rss_mib": [x[2] for x in many],
            },
            "store_quota_counts_mib": used,
            "rss_peak_mib": round(s.memory()["VmHWM"]),
        }
    finally:
        s.close()


def part_env_parse(root: Path, args) -> dict:
    from bench.hostile import Server

    s = Server(root, session_create_per_min="0", max_body_bytes=str(32 * MIB), model_timeout_s="60")
    slow, honest = one_byte_runs(), honest_hdr()
    try:
        other = httpx.Client(base_url=s.url, timeout=600, transport=httpx.HTTPTransport(local_address="127.0.0.2"))
        with httpx.Client(base_url=s.url, timeout=600) as c, other:
            mine = _session(other)

            def put_honest() -> float:
                t0 = time.perf_counter()
                r = other.put(f"/api/sessions/{mine}/environment", params={"format": "hdr"}, content=honest)
                assert r.status_code == 200, r.text
                return (time.perf_counter() - t0) * 1e3

            put_honest()  # the workers started, the first upload's imports done
            alone = [put_honest() for _ in range(args.env_honest)]
            sids = [_session(c) for _ in range(2)]
            attack: list[tuple[int, float, str]] = []

            def attacker(sid: str) -> None:
                with httpx.Client(base_url=s.url, timeout=600) as a:
                    t0 = time.perf_counter()
                    r = a.put(f"/api/sessions/{sid}/environment", params={"format": "hdr"}, content=slow)
                    attack.append((r.status_code, round(time.perf_counter() - t0, 2), r.text[:160]))

            threads = [threading.Thread(target=attacker, args=(sid,)) for sid in sids]
            for t in threads:
                t.start()
            time.sleep(0.5)  # both bodies sent, their parses begun
            during = [put_honest() for _ in range(args.env_honest)]
            for t in threads:
                t.join()
        return {
            "attack_file_mb": round(len(slow) / 1e6, 1),
            "attack": [{"code": a[0], "s": a[1], "answer": a[2]} for a in attack],
            "honest_alone_ms": {"median": round(statistics.median(alone), 1), "max": round(max(alone), 1)},
            "honest_during_ms": {
                "median": round(statistics.median(during), 1),
                "max": round(max(during), 1),
                "each": [round(x, 1) for x in during],
            },
        }
    finally:
        s.close()


PARTS = {"env_memory": part_env_memory, "env_parse": part_env_parse}
