"""Engine benchmark: BIH build time and trace time, BIH vs brute force.

    ./dev bench engine            # full tables (minutes)
    ./dev bench engine --quick    # small n, fewer runs

Prints two Markdown tables:
1. build time (median of runs) for n = 64 … 1,048,576, scenarios 1–3, max_prims 1 and 8;
2. trace time at 640 × 1088 (GPU trace stage only: draw + finish) for BIH
   (max_prims 8) and brute force, primary rays only (depth 1) and depth 5,
   with the speed-up. Brute force is skipped where one frame would exceed
   --bf-budget seconds; its time is then extrapolated linearly in n from the
   largest measured n (marked "~").
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

from renderer.accel.bih import build_for_spheres
from renderer.config.settings import RenderSettings
from renderer.gl.renderer import GLRenderer
from renderer.scenes.scenarios import scenario


def machine() -> str:
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"


def build_table(ns: list[int], runs: int) -> None:
    print(f"\n### BIH build time (ms, median of {runs} runs)\n")
    print("| n | sc1 mp1 | sc1 mp8 | sc2 mp1 | sc2 mp8 | sc3 mp1 | sc3 mp8 |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n in ns:
        cells = []
        for sc in (1, 2, 3):
            s = scenario(sc, n)
            for mp in (1, 8):
                r = runs if n <= 65536 else max(1, runs // 3)
                times = []
                for _ in range(r):
                    t0 = time.perf_counter()
                    build_for_spheres(s.sphere_centers, s.sphere_radii, mp)
                    times.append((time.perf_counter() - t0) * 1e3)
                cells.append(f"{statistics.median(times):.2f}")
        print(f"| {n:,} | " + " | ".join(cells) + " |", flush=True)


def trace_ms(r: GLRenderer, sc, st: RenderSettings, runs: int) -> float:
    r.render(sc, st)  # compile the variant, warm caches
    return statistics.median(r.render(sc, st).timings["trace"] for _ in range(runs))


def trace_table(ns: list[int], scenarios: list[int], runs: int, bf_budget: float) -> None:
    r = GLRenderer()
    print(f"\n### Trace time at 640 × 1088 (ms, median of {runs}), GL: {r.info['renderer']}\n")
    print("| scenario | n | depth | BIH 8 | brute force | speed-up |")
    print("|---:|---:|---:|---:|---:|---:|")
    for sc in scenarios:
        for depth in (1, 5):
            last_bf = None  # (n, ms) of the largest measured brute force
            for n in ns:
                scene = scenario(sc, n)
                base = RenderSettings(width=640, height=1088, max_recursion_depth=depth, max_prims=8)
                bih = trace_ms(r, scene, base.with_(method="bih"), runs)
                if last_bf is None or last_bf[1] * n / last_bf[0] <= bf_budget * 1e3:
                    bf = trace_ms(r, scene, base.with_(method="bruteforce"), max(1, runs // 2))
                    last_bf = (n, bf)
                    bf_cell = f"{bf:.0f}"
                else:
                    bf = last_bf[1] * n / last_bf[0]
                    bf_cell = f"~{bf:.0f}"
                print(f"| {sc} | {n:,} | {depth} | {bih:.1f} | {bf_cell} | {bf / bih:.1f}× |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small n and one run: a smoke test")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--bf-budget", type=float, default=20.0, help="seconds one brute-force frame may take")
    ap.add_argument("--skip-build", action="store_true")
    ap.add_argument("--skip-trace", action="store_true")
    a = ap.parse_args()
    print(f"Machine: {machine()}")
    if a.quick:
        build_ns, trace_ns, scs, runs = [64, 4096], [64, 256], [2], 1
    else:
        build_ns = [64, 256, 1024, 4096, 16384, 65536, 262144, 1048576]
        trace_ns, scs, runs = [64, 256, 1024, 4096], [1, 2, 3], a.runs
    if not a.skip_build:
        build_table(build_ns, runs)
    if not a.skip_trace:
        trace_table(trace_ns, scs, runs if not a.quick else 1, a.bf_budget)


if __name__ == "__main__":
    main()
