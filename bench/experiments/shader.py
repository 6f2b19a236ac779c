"""The tracer shaped for llvmpipe, against the shader before it, in one run.

``bench/shader.py`` traces every configuration with three sides, each a worker process:
the renderer, shaders and layouts of the unshaped base commit (extracted from git),
this checkout as the service runs it (record arrays in uniform blocks where they fit, an
RGBA8 target for jpeg frames at one sample per pixel), and this checkout with textures
only (the device's layout). Process CPU time of the frame's draws (``glFinish``
included, read-back apart), interleaved, medians; ratios against the base from the same
run. The images are bit for bit the base's (``tests/renderer/gl/test_base_images.py``).
"""

from __future__ import annotations

import math
import statistics
import time

import numpy as np

from bench import shader as S

from . import data as saved_data
from .context import Context, RunInfo
from .markdown import md_table

NAME = "shader"
TITLE = "The tracer shaped for llvmpipe (issue 18) — CPU time against the shader before it"

SIDES = ["base", "new", "new/tex"]
TARGETS = {"colour_d3": 0.55, "primary": 0.80}  # at most these ratios against the base


def measure(ctx: Context) -> dict:
    configs = (
        S.CONFIGS if not ctx.quick else [c for c in S.CONFIGS if c.name in ("colour_d3", "primary", "floor_primid")]
    )
    return {"trace": S.measure(configs, SIDES, ctx.runs, quick=ctx.quick, progress=ctx.log), "next": measure_next(ctx)}


def dump(saved: dict, figures) -> None:
    """Two files: ``shader.json`` (the three sides' traces, with the run) and ``shader_next.json``."""
    saved_data.save(figures, "shader", {**saved["trace"], **({"run": saved["run"]} if "run" in saved else {})})
    saved_data.save(figures, "shader_next", saved["next"])


def load(figures) -> dict:
    trace = saved_data.load(figures, "shader")
    run = trace.pop("run", None)
    return {"trace": trace, "next": saved_data.load(figures, "shader_next"), **({"run": run} if run else {})}


def report(saved: dict, run: RunInfo, charts: dict[str, str]) -> str:
    data = saved["trace"]
    res = data["results"]
    configs = [c for c in S.CONFIGS if c.name in res]
    med = {c.name: {s: statistics.median(res[c.name][s]["trace"]) for s in SIDES} for c in configs}
    lines = [
        f"## {TITLE}",
        "",
        "CPU time of one frame's trace (`time.process_time` around the draws and `glFinish`: llvmpipe's "
        "threads included; read-back apart, last columns) for three sides traced in turn — **base**: "
        f"renderer, shaders and layouts of `{data['base']}`, the commit before issue 18; **new**: this "
        "checkout as the service runs it (record arrays in uniform blocks where they fit 64 KiB, one RGBA8 "
        "target for jpeg frames at 1 sample per pixel); **new/tex**: this checkout with textures only "
        "(the device's layout, and the server's above 64 KiB). Every image is bit for bit the base's "
        "(`tests/renderer/gl/test_base_images.py`). Written by `bench/shader.py` (standalone: "
        "`.venv/bin/python -m bench.shader`).",
        "",
        S.table(data, configs),
        "",
        run.caption(run.runs, "median, configurations and sides interleaved, one untimed warm-up frame each"),
        "",
    ]
    verdicts = []
    for name, limit in TARGETS.items():
        if name in med:
            r = med[name]["new"] / med[name]["base"]
            what = next(c.what for c in configs if c.name == name)
            verdicts.append(
                f"- {what}: **{r:.2f}×** the base (target ≤ {limit:.2f}×: {'met' if r <= limit else 'NOT met'})"
            )
    if verdicts:
        lines += ["Targets of issue 18 (same run):", "", *verdicts, ""]
    if "floor_primid" in med:
        f = med["floor_primid"]
        lines += [
            f"The floor — what a frame costs with no sphere at all (the plane only, 640 × 1088): "
            f"{f['new']:.0f} ms (base {f['base']:.0f} ms) for primid"
            + (
                f", {med['floor_colour']['new']:.0f} ms (base {med['floor_colour']['base']:.0f} ms) for colour "
                f"at depth 3"
                if "floor_colour" in med
                else ""
            )
            + ": ray set-up, the plane, the outputs, and the traversal's loops, which llvmpipe runs once "
            "with every lane masked off even when no lane enters them.",
            "",
        ]
    lines += report_next(saved["next"], run)
    return "\n".join(lines)


# ---- where a primary ray's time goes now -------------------------------------------------------
TILE = 8  # pixels per side of a tile of the candidate-list estimate


def _lane_use(a: np.ndarray) -> float:
    """Mean over max of a per-pixel count in groups of 8 pixels (4 × 2: llvmpipe's 8 lanes)."""
    h, w = a.shape
    g = a[: h // 2 * 2, : w // 4 * 4].reshape(h // 2, 2, w // 4, 4).transpose(0, 2, 1, 3).reshape(-1, 8)
    top = g.max(axis=1).sum()
    return float(g.mean(axis=1).sum() / top) if top else 1.0


def _tile_candidates(scene, w: int, h: int) -> np.ndarray:
    """Spheres whose (widened) screen circle overlaps each TILE × TILE tile of primary rays."""
    right, up, fwd = scene.camera.basis()
    s = math.tan(math.radians(scene.camera.fov_y) / 2.0)
    v = scene.sphere_centers - np.asarray(scene.camera.position)
    z = v @ fwd
    r = scene.sphere_radii
    front = z > r
    px = ((v @ right) / z / (s * w / h) + 1) * w / 2
    row = (1 - (v @ up) / z / s) * h / 2
    rad = r / np.sqrt(np.maximum(z * z - r * r, 1e-12)) / s * h / 2 * 1.05 + 1.0
    tiles = np.zeros((-(-h // TILE), -(-w // TILE)), np.int64)
    for x, y, rr in zip(px[front], row[front], rad[front], strict=True):
        x0, x1 = max(0, int((x - rr) // TILE)), min(tiles.shape[1] - 1, int((x + rr) // TILE))
        y0, y1 = max(0, int((y - rr) // TILE)), min(tiles.shape[0] - 1, int((y + rr) // TILE))
        if x1 >= x0 and y1 >= y0:
            tiles[y0 : y1 + 1, x0 : x1 + 1] += 1
    return tiles


def measure_next(ctx: Context) -> dict:
    """Counts of the CPU mirror, the measured floor and per-test cost, and an estimate."""
    from renderer.accel.bih import build_for_spheres
    from renderer.accel.bih_traverse import traverse
    from renderer.config.methods import METHODS
    from renderer.config.settings import RenderSettings
    from renderer.oracle.reference import primary_rays
    from renderer.scenes.scenarios import scenario

    w, h = (64, 108) if ctx.quick else (640, 1088)
    n = 256 if ctx.quick else 4096
    r = ctx.renderer

    def cpu_ms(scene, method: str, mode: str = "primid") -> float:
        st = RenderSettings(width=w, height=h, mode=mode, method=method, format="npy", max_prims=8)
        prep = METHODS[method].prepare(scene, 8, 64, r.max_texture_width)
        out = []
        for _ in range(ctx.runs + 1):
            f = r.begin(scene, st, prepared=prep)
            c0 = time.process_time()
            for prog, vao, sc in f._draws(w, h, 0, h):
                f._bind(f.passes[0], prog)
                f.fbo.use()
                f.fbo.scissor = sc
                vao.render()
            f.ctx.finish()
            out.append((time.process_time() - c0) * 1e3)
            f.fbo.scissor = None
            f.release()
        return statistics.median(out[1:])

    floor = cpu_ms(scenario(1, 0), "bih")
    bf0, bf32 = cpu_ms(scenario(2, 0), "bruteforce"), cpu_ms(scenario(2, 32), "bruteforce")
    per_test = (bf32 - bf0) / 32 / (w * h) * 1e6  # ns of CPU per sphere test per pixel, uniform loop
    data = {"size": [w, h], "n": n, "floor_ms": floor, "uniform_test_ns": per_test, "scenes": {}}
    for number in (2, 3):
        scene = scenario(number, n)
        o, d = primary_rays(scene.camera, w, h)
        bih = build_for_spheres(scene.sphere_centers, scene.sphere_radii, 8, 64)
        res = traverse(bih, scene.sphere_centers, scene.sphere_radii, o, d)
        nodes = res.nodes_visited.reshape(h, w).astype(float)
        tests = res.tests.reshape(h, w).astype(float)
        frame = cpu_ms(scene, "bih")
        steps = float((nodes + tests).sum())
        step_ns = (frame - floor) / steps * 1e6 if steps else float("nan")
        tiles = _tile_candidates(scene, w, h)
        cand = np.repeat(np.repeat(tiles, TILE, 0), TILE, 1)[:h, :w]
        estimate = floor + float(cand.sum()) * per_test / 1e6
        data["scenes"][number] = {
            "hit": float(np.mean(res.prim >= 0)),
            "nodes": float(nodes.mean()),
            "tests": float(tests.mean()),
            "lanes_nodes": _lane_use(nodes),
            "lanes_tests": _lane_use(tests),
            "frame_ms": frame,
            "step_ns": step_ns,
            "tile_candidates": float(cand.mean()),
            "tile_estimate_ms": estimate,
        }
    return data


def report_next(data: dict, run: RunInfo) -> list[str]:
    w, h = data["size"]
    n, floor, per_test = data["n"], data["floor_ms"], data["uniform_test_ns"]
    rows = []
    for number, e in data["scenes"].items():
        frame, step_ns, estimate = e["frame_ms"], e["step_ns"], e["tile_estimate_ms"]
        rows.append(
            [
                f"scenario {number}",
                f"{e['hit']:.1%}",
                f"{e['nodes']:.1f}",
                f"{e['tests']:.1f}",
                f"{e['lanes_nodes']:.2f} / {e['lanes_tests']:.2f}",
                f"{frame:.0f}",
                f"{floor:.0f}",
                f"{step_ns:.1f}",
                f"{e['tile_candidates']:.1f}",
                f"{estimate:.0f} ({estimate / frame:.2f}×)",
            ]
        )
    ratios = [e["step_ns"] / per_test for e in data["scenes"].values() if per_test > 0 and e["step_ns"] == e["step_ns"]]
    ratio_txt = f"{min(ratios):.1f}–{max(ratios):.1f}×" if ratios else "more than"
    return [
        "### Where a primary ray's time goes now — the next factor",
        "",
        f"Primary rays at {w} × {h}, {n:,} spheres, BIH (max_prims 8). Per ray, from the CPU mirror "
        "(`bih_traverse`, the shader's decisions): spheres hit, nodes visited and spheres tested; lane use = "
        "mean ÷ max of those counts over groups of 8 pixels (4 × 2, llvmpipe's lanes: a group runs as long "
        "as its slowest pixel). Measured here (CPU ms, median): the frame, the floor (no spheres: the "
        "background variant everywhere, the plane and the outputs), so (frame − floor) ÷ (nodes + tests) "
        "is the CPU cost of one traversal step. A uniform loop over spheres (brute force, n = 32 against "
        f"n = 0) costs {per_test:.1f} ns of CPU per sphere and pixel; the estimate is the floor plus that "
        f"for the spheres whose screen circle overlaps each {TILE} × {TILE}-pixel tile (a per-tile candidate "
        "list made before the draw, no traversal in the shader).",
        "",
        md_table(
            [
                "scene",
                "rays hitting",
                "nodes / ray",
                "tests / ray",
                "lane use nodes / tests",
                "frame ms",
                "floor ms",
                "ns per step",
                "candidates / pixel",
                "estimate ms",
            ],
            rows,
        ),
        "",
        run.caption(run.runs),
        "",
        f"A step of the traversal (a node or a sphere test, with the loops around it and its record fetch) "
        f"costs {ratio_txt} a test in a loop every lane runs alike: the fetches are gathers lane by lane, "
        "the loops run as long as the slowest of 8 pixels, and every loop body runs once even when no lane "
        "needs it. For primary rays the next "
        "factor is to take the traversal out of the shader: per-tile candidate lists (sorted front to back "
        "for an early exit), estimated above; for the secondary rays of colour frames, which are most of "
        "their time and incoherent, passes that sort rays by direction before tracing them (the ray "
        "engines' passes) would restore the lane use the primary rays have.",
        "",
    ]
