"""Shared refinement (docs/DEPLOY.md, "Shared refinement"): how long a resting Cornell view takes to
reach ``--samples`` (256) samples on the loopback stack (:class:`server.tools.stack.Stack`: Redis,
N render processes, HAProxy) with 1, 2 and 4 render processes, each limited to one core
(``LP_NUM_THREADS=1``, its threads pinned with ``taskset`` to core i mod the cores there are: on a
2-core machine 4 processes share 2 cores), against the ideal (one process's time ÷ N); the Redis
traffic per sample (Redis's own byte counters over the stream, session reads and idle polling
included); the render processes' CPU seconds over the stream, all of them and the busiest one's
(on a loaded machine the wall times follow each process's share of the cores: the busiest one's
CPU time is about what the stream takes where each process has its core to itself, waits aside);
the merge's cost (a range's sum read from Redis and added, timed here on a sum of the frame's size).

Every stack is started first (all idle but one at a time; each process has compiled the stream's
shader variant: :func:`warm_up`), then the runs interleave (1, 2, 4, 1,
2, 4 …) so that the machine's other load falls on each alike; ``1 (alone)`` is one process with
POCKETRAY_SHARED_REFINE false: the service as it refines without the stack. The load average is
printed beside the table.

Usage::

    .venv/bin/python -m bench.shared_refine                       # 390 × 844, 256 samples, 2 rounds
    .venv/bin/python -m bench.shared_refine --width 98 --height 211 --rounds 3
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import time
from pathlib import Path

import httpx
import numpy as np

CORNELL = {"mesh_scene": {"kind": "cornell", "detail": 0}}
ENV = {
    "LP_NUM_THREADS": "1",
    "POCKETRAY_MAX_WORK": str(10**10),
    "POCKETRAY_MAX_FRAME_COST": "1000000",
    "POCKETRAY_MAX_REFINE_MS": "600000",
    "POCKETRAY_RENDER_TIMEOUT_S": "600",
    "POCKETRAY_LOG_LEVEL": "warning",
}


def pin(pid: int, core: int) -> None:
    """Every thread of ``pid`` (llvmpipe's, the GL thread) on ``core``."""
    subprocess.run(["taskset", "-a", "-cp", str(core), str(pid)], check=True, capture_output=True)


def redis_bytes(client) -> int:
    stats = client.info("stats")
    return int(stats["total_net_input_bytes"]) + int(stats["total_net_output_bytes"])


def cpu_s(pids: list[int]) -> list[float]:
    """CPU seconds (user + system, every thread) each process has used."""
    tick = os.sysconf("SC_CLK_TCK")
    out = []
    for pid in pids:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        out.append((int(fields[11]) + int(fields[12])) / tick)
    return out


def warm_up(ports: list[int], settings: dict) -> None:
    """Every render process compiles the stream's shader variant before anything is timed: a 16 × 16
    frame of the same settings, asked of each process directly (its first path frame would otherwise
    compile it inside the measurement, on llvmpipe seconds of CPU)."""
    for port in ports:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=600) as c:
            r = c.post("/api/sessions", json={**CORNELL, "settings": settings})
            r.raise_for_status()
            sid = r.json()["id"]
            c.get(f"/api/sessions/{sid}/frame", params={"width": 16, "height": 16}).raise_for_status()
            c.delete(f"/api/sessions/{sid}")


def stream_settings(width: int, height: int, samples: int) -> dict:
    return {
        "integrator": "path",
        "width": width,
        "height": height,
        "format": "png",
        "denoise": "off",
        "max_recursion_depth": 4,
        "refine_samples": samples,
        "refine_time_ms": 600_000,
    }


def one_run(url: str, client, pids: list[int], width: int, height: int, samples: int) -> dict:
    """A new Cornell session refined to ``samples`` through the balancer: seconds, the render
    processes' CPU seconds, Redis bytes."""
    settings = stream_settings(width, height, samples)
    with httpx.Client(base_url=url, timeout=900) as c:
        r = c.post("/api/sessions", json={**CORNELL, "settings": settings})
        r.raise_for_status()
        sid = r.json()["id"]
        got: list[int] = []
        b0, c0 = redis_bytes(client), cpu_s(pids)
        t0 = time.perf_counter()
        with c.stream("GET", f"/api/sessions/{sid}/frame", params={"refine": 1}) as s:
            s.raise_for_status()
            for chunk in s.iter_bytes():
                got.extend(int(v) for v in re.findall(rb"X-Samples: (\d+)", chunk))
        seconds = time.perf_counter() - t0
        b1, c1 = redis_bytes(client), cpu_s(pids)
        c.delete(f"/api/sessions/{sid}")
    if not got or got[-1] != samples:
        raise RuntimeError(f"the stream ended at {got[-1:] or 'nothing'} samples, not {samples}")
    used = [b - a for a, b in zip(c0, c1, strict=True)]
    return {"s": seconds, "cpu_s": sum(used), "busiest_cpu_s": max(used), "redis_bytes": b1 - b0, "frames": len(got)}


def merge_cost_ms(client, width: int, height: int, reps: int = 20) -> tuple[float, float]:
    """(GET of a range's float32 sum from Redis, its addition to the held sum), ms, medians."""
    rng = np.random.default_rng(0)
    part = rng.random((height, width, 3), dtype=np.float32)
    held = rng.random((height, width, 3), dtype=np.float32)
    client.set("bench:shared-refine:sum", part.tobytes())
    gets, adds = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        data = client.get("bench:shared-refine:sum")
        t1 = time.perf_counter()
        held = held + np.frombuffer(data, np.float32).reshape(part.shape)
        t2 = time.perf_counter()
        gets.append((t1 - t0) * 1e3)
        adds.append((t2 - t1) * 1e3)
    client.delete("bench:shared-refine:sum")
    return statistics.median(gets), statistics.median(adds)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--width", type=int, default=390)
    ap.add_argument("--height", type=int, default=844)
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--processes", default="1,2,4", help="render processes per stack, comma-separated")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--range-samples", type=int, default=16, help="POCKETRAY_SHARED_REFINE_RANGE_SAMPLES")
    ap.add_argument("--no-alone", action="store_true", help="leave out the one process without sharing")
    args = ap.parse_args()

    import redis

    from server.tools.stack import Stack

    cores = sorted(os.sched_getaffinity(0))
    env = {**ENV, "POCKETRAY_SHARED_REFINE_RANGE_SAMPLES": str(args.range_samples)}
    kinds = [] if args.no_alone else [("1 (alone)", 1, {"POCKETRAY_SHARED_REFINE": "false"})]
    kinds += [(str(n), n, {}) for n in (int(x) for x in args.processes.split(","))]
    stacks = {}
    try:
        for name, n, extra in kinds:
            st = Stack(processes=n, env={**env, **extra}, supervise=False, say=lambda line: None).start(600)
            for i, child in enumerate(st.renders):
                assert child.proc is not None
                pin(child.proc.pid, cores[i % len(cores)])
            warm_up([child.port for child in st.renders], stream_settings(args.width, args.height, args.samples))
            stacks[name] = (st, n, redis.Redis.from_url(st.redis_url))
        load0 = os.getloadavg()
        runs: dict[str, list[dict]] = {name: [] for name in stacks}
        for rnd in range(args.rounds):
            for name, (st, _, client) in stacks.items():
                pids = [child.proc.pid for child in st.renders if child.proc is not None]
                run = one_run(st.url, client, pids, args.width, args.height, args.samples)
                runs[name].append(run)
                print(f"round {rnd + 1}: {name:>9} processes: {run['s']:.1f} s, {run['cpu_s']:.1f} CPU s", flush=True)
        load1 = os.getloadavg()
        any_client = next(iter(stacks.values()))[2]
        get_ms, add_ms = merge_cost_ms(any_client, args.width, args.height)
    finally:
        for st, _, client in stacks.values():
            client.close()
            st.stop()

    base_name = "1 (alone)" if "1 (alone)" in runs else next(iter(runs))
    base = statistics.median(r["s"] for r in runs[base_name])
    frame_bytes = args.width * args.height * 12
    print(
        f"\nCornell box, path, {args.width} × {args.height}, {args.samples} samples, ranges of "
        f"{args.range_samples}; {len(cores)} cores; load average {load0[0]:.1f} before, {load1[0]:.1f} after\n"
    )
    print(
        "| render processes | time to the samples, s (median; runs) | × one process | ideal "
        "| their CPU s (median) | the busiest one's CPU s | Redis bytes / sample |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, rs in runs.items():
        n = stacks[name][1] if name in stacks else 1
        t = statistics.median(r["s"] for r in rs)
        per_sample = statistics.median(r["redis_bytes"] for r in rs) / args.samples
        each = ", ".join(f"{r['s']:.1f}" for r in rs)
        cpu = statistics.median(r["cpu_s"] for r in rs)
        busiest = statistics.median(r["busiest_cpu_s"] for r in rs)
        print(
            f"| {name} | {t:.1f} ({each}) | {t / base:.2f} | {1 / n:.2f} | {cpu:.1f} | {busiest:.1f} "
            f"| {per_sample / 1e3:,.1f} kB |"
        )
    print(
        f"\nmerge of one range ({frame_bytes / 1e6:.2f} MB float32 sum): Redis GET {get_ms:.2f} ms, "
        f"addition {add_ms:.2f} ms (medians of 20)"
    )


if __name__ == "__main__":
    main()
