"""First hits without a traversal per pixel: the traversal, a quad per sphere, a list per tile.

Primary-ray frames (mode ``depth``, BIH, 640 × 1088) of the thesis's scenarios at n = 64 …
65,536, with and without the plane, traced three ways (the ``first_hits`` setting, the same ids
and distances bit for bit): ``trace`` (the method's traversal), ``raster`` (each sphere's
rectangle drawn, renderer/frame/first_hits.py) and ``tiles`` (each 16 × 16 tile's list, nearest
first). Each repetition renders the three in turn (interleaved: the machine is shared); the
trace stage (draws + glFinish, with the host's quads or lists made for the frame) per frame.
Beside them: the quads' fragments, the tiles' (sphere, tile) pairs and pixels, and the cost
model's estimates (renderer/frame/cost.py) — the choice of ``first_hits=auto`` against the fastest
measured. The cost model's constants for the two rasterised ways are fitted here (least squares
of the trace stage on those counts) and copied into renderer/frame/cost.py.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from renderer.config.methods import METHODS
from renderer.frame import cost, first_hits as fh
from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings
from .style import image_line, legend_outside, log_axis, plt, save, series
from .timing import Stat

NAME = "first_hits"
TITLE = "First hits without a traversal per pixel — the traversal, a quad per sphere, a list per tile"

HOWS = ("trace", "raster", "tiles")
NS = (64, 256, 1024, 4096, 16384, 65536)
NS_QUICK = (64, 256)
SCENARIOS = (1, 2, 3)
SCENARIOS_QUICK = (2,)
SIZE = (640, 1088)
SIZE_QUICK = (64, 108)


def _scene(scn: int, n: int, planes: bool):
    s = scenario(scn, n)
    return s if planes else dataclasses.replace(s, planes=())


def measure(ctx: Context) -> dict:
    w, h = SIZE_QUICK if ctx.quick else SIZE
    ns = NS_QUICK if ctx.quick else NS
    scs = SCENARIOS_QUICK if ctx.quick else SCENARIOS
    base = default_settings().with_(width=w, height=h, mode="depth", max_recursion_depth=1, method="bih")
    r = ctx.renderer
    rows = []
    jobs = [(scn, n, planes) for scn in scs for n in ns for planes in (True, False)]
    for scn, n, planes in ctx.bar(jobs, desc=NAME):
        scene = _scene(scn, n, planes)
        prep = METHODS["bih"].prepare(scene, base.max_prims, base.max_tree_depth, r.max_texture_width)
        quads = fh.instances(scene, (w, h), (w, h))
        tiles, entries = fh.tile_lists(scene, (w, h), (w, h))
        times: dict[str, list[float]] = {k: [] for k in HOWS}
        for how in HOWS:  # warm-up: compiles each variant
            r.render(scene, base.with_(first_hits=how), prepared=prep)
        for _ in range(max(1, ctx.runs)):
            for how in HOWS:
                times[how].append(r.render(scene, base.with_(first_hits=how), prepared=prep).timings["trace"])
        auto = r.render(scene, base.with_(first_hits="auto"), prepared=prep).stats.get("first_hits", "trace")
        lists = []  # the host's part of a tiles frame: its lists, made alone
        for _ in range(3):
            t0 = time.perf_counter()
            fh.tile_lists(scene, (w, h), (w, h))
            lists.append((time.perf_counter() - t0) * 1e3)
        rows.append(
            {
                "scenario": scn,
                "n": n,
                "planes": planes,
                "fragments": fh.covered_fragments(quads, (w, h)),
                "pairs": len(entries) // fh.ENTRY_TEXELS,
                "tile_pixels": fh.covered_fragments(tiles, (w, h)),
                "traversal_est_ms": cost.traversal_ms("bih", prep.stats, scene, base),
                "auto": auto,
                "lists_ms": float(np.median(lists)),
                **{k: Stat(v).to_json() for k, v in times.items()},
            }
        )
    return {"size": [w, h], "pixels": w * h, "rows": rows}


def nonnegative_fit(a: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least squares with every coefficient ≥ 0 (a cost cannot be negative): a term whose coefficient
    comes out negative is dropped (0) and the rest fitted again, until none is."""
    keep = np.ones(a.shape[1], dtype=bool)
    while True:
        c = np.zeros(a.shape[1])
        c[keep], *_ = np.linalg.lstsq(a[:, keep], y, rcond=None)
        if (c >= 0).all():
            return c
        keep &= c > 0


def fit(rows: list[dict], pixels: int) -> dict:
    """Least squares of each rasterised way's trace stage (ms) on its counts, scaled into the cost
    model's units by the traversal's measured / estimated ratio (median over the rows)."""
    if not rows:
        return {}
    med = lambda r, k: Stat.from_json(r[k]).median  # a short accessor
    scale = float(np.median([med(r, "trace") / max(r["traversal_est_ms"], 1e-9) for r in rows]))
    a = np.array([[1.0, r["fragments"], pixels * r["planes"]] for r in rows])
    raster = nonnegative_fit(a, np.array([med(r, "raster") for r in rows]))
    b = np.array([[1.0, r["pairs"], r["tile_pixels"], pixels * r["planes"]] for r in rows])
    tiles = nonnegative_fit(b, np.array([med(r, "tiles") for r in rows]))
    return {
        "scale": scale,
        "raster": {
            "ms": raster[0] / scale,
            "ns_fragment": raster[1] * 1e6 / scale,
            "ns_plane_pixel": raster[2] * 1e6 / scale,
        },
        "tiles": {
            "ms": tiles[0] / scale,
            "ns_pair": tiles[1] * 1e6 / scale,
            "ns_tile_pixel": tiles[2] * 1e6 / scale,
            "ns_plane_pixel": tiles[3] * 1e6 / scale,
        },
    }


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``first_hits.png``: trace-stage ms against n per way, one panel without and one with the plane."""
    pyplot = plt()
    rows = data["rows"]
    fig, axes = pyplot.subplots(1, 2, figsize=(12, 4.4), sharey=True, layout="constrained")
    for ax, planes in zip(axes, (False, True), strict=True):
        for scn in sorted({r["scenario"] for r in rows}):
            sel = [r for r in rows if r["scenario"] == scn and r["planes"] == planes]
            for i, how in enumerate(HOWS):
                style = series(f"scenario {scn}: {how}", variant=scn - 1, method=("bih", "rayengine", "bvh")[i])
                ax.plot([r["n"] for r in sel], [Stat.from_json(r[how]).median for r in sel], **style)
        log_axis(ax)
        ax.set_xlabel("spheres n")
        ax.set_title("with the plane" if planes else "spheres only")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("trace stage, ms")
    legend_outside(fig, axes, title="way (colour) × scenario (line)")
    save(fig, figures, NAME, quick)
    return {NAME: "trace-stage ms against n: the traversal, a quad per sphere, a list per tile"}


HEADERS = [
    "scenario",
    "n",
    "plane",
    "trace ms",
    "raster ms",
    "tiles ms",
    "trace / tiles",
    "fragments / px",
    "pairs",
    "tile px / px",
    "lists ms",
    "fastest",
    "auto",
]


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    rows = data["rows"]
    table = []
    right = 0
    for r in rows:
        med = {k: Stat.from_json(r[k]).median for k in HOWS}
        best = min(med, key=med.__getitem__)
        chosen = r["auto"] if r["auto"] in HOWS else "trace"
        right += chosen == best or med[chosen] <= 1.1 * med[best]
        table.append(
            [
                f"{r['scenario']}",
                f"{r['n']:,}",
                "yes" if r["planes"] else "no",
                *(Stat.from_json(r[k]).fmt(1) for k in HOWS),
                f"{med['trace'] / med['tiles']:.2f}×",
                f"{r['fragments'] / (w * h):.2f}",
                f"{r['pairs']:,}",
                f"{r['tile_pixels'] / (w * h):.2f}",
                f"{r['lists_ms']:.1f}" if "lists_ms" in r else "—",
                best,
                chosen,
            ]
        )
    f = fit(rows, data["pixels"])
    fit_txt = ""
    if f:
        fr, ft = f["raster"], f["tiles"]
        fit_txt = (
            f"Fitted (cost-model units, the traversal's measured / estimated ratio {f['scale']:.2f}): "
            f"a quad per sphere {fr['ms']:.2f} ms + {fr['ns_fragment']:.1f} ns per fragment + "
            f"{fr['ns_plane_pixel']:.1f} ns per pixel with planes; a list per tile {ft['ms']:.2f} ms + "
            f"{ft['ns_pair']:.1f} ns per (tile, sphere) pair + {ft['ns_tile_pixel']:.1f} ns per tile pixel + "
            f"{ft['ns_plane_pixel']:.1f} ns per pixel with planes (renderer/frame/cost.py holds these numbers)."
        )
    chart = "".join(image_line(name, alt) + "\n\n" for name, alt in charts.items())
    return f"""## {TITLE}

Primary rays ({w} × {h}, mode `depth`, BIH for the traversal) of the thesis's scenarios with and without
their plane, traced by the three ways of the `first_hits` setting (docs/SHADING.md, "First hits by
rasterisation"): the same ids and distances bit for bit (tests/renderer/gl/test_first_hits.py). Trace
stage in ms (draws and glFinish, with the quads or tile lists the host makes for the frame), interleaved
repetitions. *Fragments*: the quads' fragments per pixel (each pays its ray and test: no early depth
test when a shader writes depth); *pairs*: (tile, sphere) entries of the lists; *tile pixels*: pixels in
tiles with a list, per pixel; *lists ms*: the host's part of a tiles frame (its lists, made alone).
*auto*: what `first_hits=auto` chose (the cost model); it counts as right
when within 10 % of the fastest.

{chart}{md_table(HEADERS, table, "rrlrrrrrrrrll")}

{run.caption()}

`auto` chose the fastest, or within 10 % of it, in {right} of {len(rows)} frames. {fit_txt}

Raw data: [`figures/{NAME}.json`](figures/{NAME}.json).
"""
