"""The tracer's cost per variant against the base commit's unshaped shader, in one run.

Every configuration (method × mode × scene × size) is traced by two or more *sides*, each
a worker process with its own GL context:

- ``base``: the renderer, shaders and layouts of ``--base`` (default: :data:`BASE_COMMIT`,
  the unshaped tracer), extracted from git into a temporary directory;
- ``new``: this checkout as the service runs it (uniform blocks where the data fit);
- ``new/tex``: this checkout with textures only (the device's layout, and the server's
  above the uniform-block size);
- ``new/nobg``: this checkout without the background variant (every pixel of a
  primary-ray frame traced by the tracer).

Timing: process CPU time (``time.process_time``: llvmpipe's threads included) of the
frame's slices — bind, draw, ``glFinish`` — without the read-back and the box filter,
which are reported apart (``read``). Sides and configurations are interleaved
(A/B/A/B …), one untimed warm-up frame each (the compile), then ``--runs`` frames;
medians, and ratios against ``base`` from the same run. The acceleration structure is
built once per configuration and side (``prepare`` is not timed).

    .venv/bin/python -m bench.shader                  # every configuration, 7 runs
    .venv/bin/python -m bench.shader --quick          # tiny images, 1 run (smoke)
    .venv/bin/python -m bench.shader --only colour_d3,primary --runs 9
    .venv/bin/python -m bench.shader --sides base,new,new/tex --json out.json
    .venv/bin/python -m bench.shader --sides new,try=/tmp/copy   # a modified copy of renderer/ + shaders/

``bench/experiments/shader.py`` runs it for docs/RESULTS.md.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BASE_COMMIT = "cda5fce"  # the tracer before it was shaped for llvmpipe


@dataclass(frozen=True)
class Config:
    name: str
    what: str
    scene: dict  # worker scene spec (see _scene)
    settings: dict  # RenderSettings keywords
    quick: dict = field(default_factory=dict)  # overrides with --quick


S3 = {"kind": "scenario", "number": 3, "n": 4096}
S2 = {"kind": "scenario", "number": 2, "n": 4096}
COLOUR = {"width": 320, "height": 544, "mode": "color", "format": "jpeg", "max_prims": 8}
PRIMARY = {"width": 640, "height": 1088, "mode": "primid", "format": "npy", "max_prims": 8}
SMALL = {"width": 32, "height": 54}

CONFIGS = (
    Config(
        "colour_d3",
        "colour, depth 3, 320 × 544, scenario 3, 4,096 spheres",
        S3,
        {**COLOUR, "max_recursion_depth": 3},
        SMALL,
    ),
    Config(
        "colour_d5", "colour, depth 5, 320 × 544, scenario 3, 4,096", S3, {**COLOUR, "max_recursion_depth": 5}, SMALL
    ),
    Config(
        "interactive",
        "interactive profile (depth 3, ε 0.3, 1 spp), 320 × 544, scenario 3, 4,096",
        S3,
        {**COLOUR, "max_recursion_depth": 3, "min_weight": 0.3},
        SMALL,
    ),
    Config(
        "still",
        "still profile (depth 3, ε 0.03, 4 spp), 320 × 544, scenario 3, 4,096",
        S3,
        {**COLOUR, "max_recursion_depth": 3, "min_weight": 0.03, "samples_per_pixel": 4},
        SMALL,
    ),
    Config("primary", "primary rays (primid), 640 × 1088, scenario 3, 4,096", S3, PRIMARY, SMALL),
    Config(
        "primary_s2",
        "primary rays (depth), 640 × 1088, scenario 2, 4,096 (the peers' scene)",
        S2,
        {**PRIMARY, "mode": "depth"},
        SMALL,
    ),
    Config(
        "primary_64k",
        "primary rays (primid), 640 × 1088, scenario 2, 65,536 (textures)",
        {"kind": "scenario", "number": 2, "n": 65536},
        PRIMARY,
        {**SMALL, "n": 1024},
    ),
    Config(
        "floor_primid",
        "floor: primid, 640 × 1088, 0 spheres (the plane)",
        {"kind": "scenario", "number": 1, "n": 0},
        PRIMARY,
        SMALL,
    ),
    Config(
        "floor_colour",
        "floor: colour depth 3, 640 × 1088, 0 spheres",
        {"kind": "scenario", "number": 1, "n": 0},
        {**PRIMARY, "mode": "color", "format": "jpeg", "max_recursion_depth": 3},
        SMALL,
    ),
    *(
        Config(
            f"{m}_colour",
            f"{m}: colour depth 3, 320 × 544, scenario 3, 4,096",
            S3,
            {**COLOUR, "method": m, "max_recursion_depth": 3},
            SMALL,
        )
        for m in ("bvh", "kdtree", "twolevel")
    ),
    *(
        Config(
            f"{m}_primary",
            f"{m}: primary rays (primid), 640 × 1088, scenario 3, 4,096",
            S3,
            {**PRIMARY, "method": m},
            SMALL,
        )
        for m in ("bvh", "kdtree", "twolevel")
    ),
    Config(
        "bruteforce",
        "bruteforce: colour depth 3, 320 × 544, scenario 3, 256",
        {**S3, "n": 256},
        {**COLOUR, "method": "bruteforce", "max_recursion_depth": 3},
        SMALL,
    ),
)
SIDES = {"base": {}, "new": {}, "new/tex": {"uniform_blocks": False}, "new/nobg": {"background": False}}


# ---- the worker (runs in its own process, the side's code first on PYTHONPATH) ---------------
def _scene(spec: dict):
    from renderer.scenes.scenarios import scenario

    if spec["kind"] == "scenario":
        return scenario(spec["number"], spec["n"], seed=spec.get("seed", 0), radius=spec.get("radius", 1.0))
    raise ValueError(spec)


def _timed(fn, aside: list[float]):
    """``fn``, its process time added to ``aside[0]`` (the part of a frame spent outside the tracer)."""

    def run(*a):
        c = time.process_time()
        out = fn(*a)
        aside[0] += time.process_time() - c
        return out

    return run


def worker(renderer_kw: dict) -> None:
    from renderer.config.methods import METHODS
    from renderer.config.settings import RenderSettings
    from renderer.frame.plan import plan_frame
    from renderer.gl import GLRenderer

    r = GLRenderer(**renderer_kw)
    cache: dict = {}
    print(json.dumps({"ready": True, "renderer": r.info}), flush=True)
    for line in sys.stdin:
        job = json.loads(line)
        key = json.dumps([job["scene"], job["settings"]], sort_keys=True)
        if key not in cache:
            scene = _scene(job["scene"])
            settings = RenderSettings(**job["settings"])
            plan = plan_frame(scene, settings)  # the method the renderer traces with: auto resolved once
            m = METHODS[plan.method]
            cache[key] = (
                scene,
                settings,
                plan,
                m.prepare(scene, settings.max_prims, settings.max_tree_depth, r.max_texture_width),
            )
        scene, settings, plan, prepared = cache[key]
        f = r.begin(scene, settings, plan=plan, prepared=prepared)
        aside = [0.0]
        f._finish_pass = _timed(f._finish_pass, aside)
        f._compose = _timed(f._compose, aside)
        w0, c0 = time.perf_counter(), time.process_time()
        while not f.step():
            pass
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        print(
            json.dumps(
                {
                    "trace_ms": (cpu - aside[0]) * 1e3,
                    "read_ms": aside[0] * 1e3,
                    "wall_ms": wall * 1e3,
                    "stats": {k: v for k, v in f.result().stats.items() if k in ("target", "blocks")},
                }
            ),
            flush=True,
        )


class Side:
    """A worker process of one side."""

    def __init__(self, name: str, code_root: Path, renderer_kw: dict):
        self.name = name
        env = {**os.environ, "PYTHONPATH": str(code_root)}
        self.proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), "--worker", json.dumps(renderer_kw)],
            cwd=code_root,
            env=env,
            text=True,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        hello = json.loads(self.proc.stdout.readline())
        self.info = hello["renderer"]

    def run(self, cfg: Config, quick: bool) -> dict:
        settings = {**cfg.settings, **({k: v for k, v in cfg.quick.items() if k != "n"} if quick else {})}
        scene = {**cfg.scene, **({"n": cfg.quick["n"]} if quick and "n" in cfg.quick else {})}
        self.proc.stdin.write(json.dumps({"scene": scene, "settings": settings}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"worker {self.name} died")
        return json.loads(line)

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def extract(commit: str, into: Path) -> Path:
    """``renderer/`` and ``shaders/`` of ``commit`` under ``into``."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "renderer", "shaders"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into


def measure(configs, sides: list[str], runs: int, quick: bool = False, base: str = BASE_COMMIT, progress=print) -> dict:
    """{config name: {side: {"trace": [ms…], "read": [ms…], "stats": …}}}, interleaved."""
    with tempfile.TemporaryDirectory(prefix="pocketray-base-") as tmp:
        roots = {"base": extract(base, Path(tmp)) if "base" in sides else None}

        def root_of(side: str) -> Path:
            if side == "base":
                return roots["base"]
            return Path(side.split("=", 1)[1]) if "=" in side else ROOT

        workers = {s: Side(s, root_of(s), SIDES.get(s, {})) for s in sides}
        try:
            out = {c.name: {s: {"trace": [], "read": [], "wall": []} for s in sides} for c in configs}
            for rep in range(runs + 1):  # rep 0: the untimed warm-up (compiles)
                for c in configs:
                    for s in sides:
                        r = workers[s].run(c, quick)
                        if rep:
                            d = out[c.name][s]
                            d["trace"].append(r["trace_ms"])
                            d["read"].append(r["read_ms"])
                            d["wall"].append(r["wall_ms"])
                            d["stats"] = r["stats"]
                progress(f"  run {rep}/{runs} done" if rep else "  warm-up done")
            info = workers[sides[0]].info
        finally:
            for w in workers.values():
                w.close()
    return {"results": out, "gl": info, "runs": runs, "base": base, "sides": sides}


def table(data: dict, configs) -> str:
    sides = data["sides"]
    ref = "base" if "base" in sides else sides[0]
    sides_shown = {s: s.split("=", 1)[0] for s in sides}
    head = [
        "configuration",
        *(f"{sides_shown[s]} trace ms" for s in sides),
        *(f"{sides_shown[s]} / {sides_shown[ref]}" for s in sides if s != ref),
        *(f"{sides_shown[s]} read ms" for s in sides),
    ]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in configs:
        d = data["results"][c.name]
        med = {s: statistics.median(d[s]["trace"]) for s in sides}
        rd = {s: statistics.median(d[s]["read"]) for s in sides}
        rows.append(
            "| "
            + " | ".join(
                [
                    c.what,
                    *(f"{med[s]:.1f}" for s in sides),
                    *(f"**{med[s] / med[ref]:.2f}×**" for s in sides if s != ref),
                    *(f"{rd[s]:.2f}" for s in sides),
                ]
            )
            + " |"
        )
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--quick", action="store_true", help="tiny images, 1 run")
    ap.add_argument("--only", default="", help="comma-separated configuration names")
    ap.add_argument(
        "--sides",
        default="base,new",
        help=f"comma-separated, of {', '.join(SIDES)} or NAME=PATH (a directory with renderer/ and shaders/)",
    )
    ap.add_argument("--base", default=BASE_COMMIT, help="the commit to compare against")
    ap.add_argument("--json", type=Path, help="write the raw measurements here")
    a = ap.parse_args(argv)
    if a.worker is not None:
        worker(json.loads(a.worker))
        return 0
    names = [s for s in a.only.split(",") if s]
    configs = [c for c in CONFIGS if not names or c.name in names]
    sides = [s for s in a.sides.split(",") if s]
    runs = 1 if a.quick else a.runs
    print(f"# tracer CPU time per frame (process time, median of {runs}, interleaved), base = {a.base}")
    print(f"# load average before: {os.getloadavg()[0]:.2f}", flush=True)
    data = measure(configs, sides, runs, a.quick, a.base, progress=lambda m: print(m, file=sys.stderr, flush=True))
    print(f"# GL: {data['gl']}; load average after: {os.getloadavg()[0]:.2f}\n")
    print(table(data, configs))
    if a.json:
        a.json.write_text(json.dumps(data, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
