"""Refinement while still (``bench/refine.py``): the memory the accumulations of refining sessions
hold, and a light session's 32 × 32 frame latency while four sessions refine.

Quick mode: 2 sessions of 48 × 48 to 8 samples, 1 busy session, 3 light frames.
"""

from __future__ import annotations

from pathlib import Path

from bench import refine as R
from bench.child import ServerChild

from .context import Context, RunInfo
from .markdown import md_table

NAME = "refine"
TITLE = "Refinement while still — memory of refining sessions, a light session's frames meanwhile"

ROOT = Path(__file__).resolve().parents[2]


def measure(ctx: Context) -> dict:
    sizes = (
        dict(sessions=2, busy=1, width=48, height=48, samples=8, frames=3)
        if ctx.quick
        else dict(sessions=8, busy=4, width=180, height=370, samples=64, frames=20)
    )
    server = ServerChild(ROOT, R.SERVER_SETTINGS)
    try:
        return R.measure(server.url, server, **sizes)
    finally:
        server.close()


def _mib(x: float | None) -> str:
    return "—" if x is None else f"{x:,.0f}"


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    m, lat = data["memory"], data["latency"]
    memory = md_table(
        [
            "sessions refining",
            "frame",
            "to samples",
            "frames per stream",
            "wall s",
            "RSS before MiB",
            "RSS peak MiB",
            "RSS after MiB",
            "accumulations held",
        ],
        [
            [
                str(m["sessions"]),
                m["size"].replace("x", " × "),
                str(m["samples"]),
                f"{min(m['frames_per_stream'])}–{max(m['frames_per_stream'])}",
                f"{m['wall_s']:.0f}",
                _mib(m["rss_before_mib"]),
                _mib(m["rss_peak_mib"]),
                _mib(m["rss_after_mib"]),
                f"{m['accumulation_bytes'] / 2**20:.1f} MiB (8 × W × H × 12 B = {m['expected_bytes'] / 2**20:.1f})"
                if m["sessions"] == 8
                else f"{m['accumulation_bytes'] / 2**20:.2f} MiB",
            ]
        ],
        align="lllrrrrrl",
    )
    latency = md_table(
        ["light session's 32 × 32 frame", "frames", "median ms", "p90 ms", "max ms"],
        [
            ["alone", str(lat["frames"]), f"{lat['alone_p50_ms']:.0f}", f"{lat['alone_p90_ms']:.0f}", "—"],
            [
                f"while {lat['busy']} sessions refine",
                str(lat["frames"]),
                f"{lat['during_p50_ms']:.0f}",
                f"{lat['during_p90_ms']:.0f}",
                f"{lat['during_max_ms']:.0f}",
            ],
        ],
        align="lrrrr",
    )
    verdict = "meets" if lat["during_p90_ms"] <= 500 else "misses"
    return f"""## {TITLE}

A `python -m server` process (`POCKETRAY_QUEUE_SIZE=16`). **Memory**: {m["sessions"]} Cornell-box
sessions (`integrator=path`, depth {m["depth"]}, png) refine at once, each through
`GET …/frame?refine=1` to {m["samples"]} samples per pixel (docs/API.md, "Refinement"): the
server's resident memory before, the highest sampled every 0.2 s while they refine, after, and
`pocketray_accumulation_bytes` at the end — the float32 sums the accumulations hold, 12 bytes a
pixel (within `POCKETRAY_MAX_ACCUMULATION_BYTES`, 256 MiB).

{memory}

{run.caption(1, "")}

**Latency**: a light session (scenario 1, 16 spheres, Whitted, depth 2) asks 32 × 32 png frames
one after another, alone and then while {lat["busy"]} Cornell-box sessions of the same size refine
(streams to 65,536 samples, each past its first frame before the light frames start): client-side
time per frame. The streams' frames are background frames — the GL thread serves an interactive
frame first and holds it up by at most the slice in progress. Target: ≤ 0.5 s; this run
{verdict} it at p90.

{latency}

{run.caption(f"{lat['frames']} frames each (median, p90, max)")}
"""
