"""Szécsi's experiment here: the ray engine, the hierarchical ray engine, brute force and BIH.

Frames per second against the primitive count (16 … 4,096) at 256 × 256 and 640 × 1,088,
refractive spheres filling the view, recursion depth 5, every method in one run; the
tile-size sweep of the hierarchical ray engine (8, 16, 32); the cone-angle images of
his Fig. 4 (generations 1, 2, 4, 8) through the render mode ``cones``; and whether his
"twice as fast as the ray engine from 100 primitives on" holds here.

The scene (``filled_view``): ``n`` transparent spheres (Table 4.1's *transparent*,
kt = 0.7, ior 0.95, no reflection) on a ``k × k × m`` grid in the cube [−20, 20]³
(``k`` = 4, 8 or 16 across, ``m = n / k²`` deep), radius 0.72 of a cell so that the
front layer covers its square, seen from the front with a field of view that the front
face fills: every primary ray meets a refractive sphere (the figure is reported). No
plane: every generation is one layer (the transmitted path), as in the paper's
refraction experiment; one point light, so each generation also traces shadow rays.

On llvmpipe (no GPU) the ray engine's frames take minutes at 640 × 1,088: each method's
series stops at the first ``n`` whose frame exceeds the frame budget, and those points are
marked "over budget" (never extrapolated).

Standalone: ``python -m bench.experiments.ray_engines [--quick] [--out DIR]``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.geometry.scene import Camera, Light, Scene
from renderer.limits import DEFAULT_TILE_SIZE
from renderer.scenes.scenarios import TRANSPARENT

from .context import Context, RunInfo
from .machine import ROOT
from .markdown import md_table
from .style import image_line, legend_outside, log_axis, plt, save, series

NAME = "ray_engines"
TITLE = "The hierarchical ray engine (Szécsi 2006) against the ray engine, brute force and BIH"

METHODS = ("bruteforce", "rayengine", "hre", "bih")
NS = (16, 64, 256, 1024, 4096)
NS_QUICK = (16, 64, 256)
SIZES = ((256, 256), (640, 1088))
SIZES_QUICK = ((64, 64), (40, 68))
TILES = (8, 16, 32)
GENERATIONS = (1, 2, 4, 8)
DEPTH = 5
FRAME_BUDGET_S = 10.0  # a method's series stops after a frame slower than this
FRAME_BUDGET_S_QUICK = 10.0


def filled_view(n: int, width: int, height: int) -> Scene:
    """``n`` refractive spheres whose front layer fills the view (see the module doc)."""
    k = 4 if n <= 64 else 8 if n <= 512 else 16
    m = max(1, -(-n // (k * k)))
    cell = 40.0 / k
    depth_cell = 40.0 / m
    xs = -20.0 + cell * (np.arange(k) + 0.5)
    zs = 20.0 - depth_cell * (np.arange(m) + 0.5)
    z, y, x = np.meshgrid(zs, xs, xs, indexing="ij")
    centers = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)[:n]
    r = 0.72 * cell
    front = zs[0] + r
    dist = 60.0
    half = 20.0 - cell / 2  # the front layer covers [−half, half]² without gaps
    tan_y = half / dist * min(1.0, height / width)
    cam = Camera((0.0, 0.0, front + dist), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), math.degrees(2 * math.atan(tan_y)))
    return Scene(
        cam,
        (Light((0.0, 40.0, 60.0), (1.0, 1.0, 1.0)),),
        (TRANSPARENT,),
        centers,
        np.full(len(centers), r),
        np.zeros(len(centers), np.int32),
        (),
    )


def _settings(method: str, w: int, h: int, **kw) -> RenderSettings:
    return RenderSettings(width=w, height=h, method=method, mode="color", max_recursion_depth=DEPTH, max_prims=8, **kw)


def measure_fps(ctx, sizes, ns, budget_s: float) -> dict:
    out: dict = {}
    for w, h in sizes:
        for method in METHODS:
            over = False
            for n in ns:
                key = f"{w}x{h}/{method}/{n}"
                if over:
                    out[key] = None
                    continue
                scene = filled_view(n, w, h)
                # compile the variants on a tiny frame: a warm-up at full size would double minutes-long frames
                ctx.renderer.render(scene, _settings(method, 16, 16))
                t = ctx.time_render(scene, _settings(method, w, h), runs=ctx.runs, warmup=0, budget_s=budget_s)
                res = t.result
                filled = float((res.primid >= 0).mean())
                out[key] = {
                    "ms": t.total.to_json(),
                    "fps": 1e3 / t.total.median,
                    "filled": filled,
                    "stats": {k: v for k, v in (res.stats or {}).items() if isinstance(v, (int, float, str))},
                }
                ctx.log(f"{key}: {t.total.median:,.0f} ms")
                over = t.total.median > budget_s * 1e3
    return out


def tile_sweep(ctx, size, ns, budget_s: float) -> dict:
    w, h = size
    out = {}
    r = ctx.renderer
    for n in ns:
        scene = filled_view(n, w, h)
        for ts in TILES:
            s = _settings("hre", w, h, tile_size=ts)
            r.render(scene, s)  # warm-up (compiles the TILE variant of the cone pass)
            samples = []
            for _ in range(max(1, ctx.runs)):
                res = r.render(scene, s)
                samples.append(res.timings["total"])
                if sum(samples) > budget_s * 1e3:
                    break
            med = float(np.median(samples))
            out[f"{n}/{ts}"] = {
                "ms": med,
                "samples": samples,
                "cull_fraction": res.stats["cull_fraction"],
                "build_ms": res.timings["build"],
            }
    return out


def cone_images(ctx, size, n: int) -> dict[int, np.ndarray]:
    w, h = size
    scene = filled_view(n, w, h)
    return {
        g: ctx.renderer.render(
            scene, RenderSettings(width=w, height=h, method="hre", mode="cones", max_recursion_depth=g)
        ).image
        for g in GENERATIONS
    }


def twice_as_fast(fps: dict, size) -> tuple[str, list[tuple[int, float]]]:
    """(verdict, [(n, hre speed-up over the ray engine)]) at ``size``."""
    w, h = size
    ratios = []
    for key, v in fps.items():
        sz, method, n = key.split("/")
        if sz != f"{w}x{h}" or method != "hre" or v is None:
            continue
        re_ = fps.get(f"{sz}/rayengine/{n}")
        if re_ is None:
            continue
        ratios.append((int(n), re_["ms"]["median"] / v["ms"]["median"]))
    ratios.sort()
    if not ratios:
        return "not measured (both series over budget)", ratios
    from_n = next((n for i, (n, _) in enumerate(ratios) if all(r >= 2.0 for _, r in ratios[i:])), None)
    over_100 = [(n, r) for n, r in ratios if n >= 100]
    measured = ", ".join(f"{n:,}" for n, _ in over_100)
    if not over_100:
        verdict = "**cannot be decided here**: no n ≥ 100 where both were measured (the ray engine is over budget)" + (
            f"; ≥ 2× from n = {from_n:,} among the measured n" if from_n else ""
        )
    elif all(r >= 2.0 for _, r in over_100):
        verdict = f"**holds** at every measured n ≥ 100 (n = {measured}); ≥ 2× from n = {from_n:,} on"
    elif from_n is not None:
        verdict = f"**holds only from n = {from_n:,}** (not from 100)"
    else:
        verdict = "**does not hold** in the measured range"
    return verdict, ratios


def measure(ctx: Context) -> dict:
    quick = ctx.quick
    sizes = getattr(ctx, "ray_engine_sizes", None) or (SIZES_QUICK if quick else SIZES)
    ns = NS_QUICK if quick else NS
    budget = getattr(ctx, "ray_engine_budget_s", None) or (FRAME_BUDGET_S_QUICK if quick else FRAME_BUDGET_S)
    fps = measure_fps(ctx, sizes, ns, budget)
    sweep_ns = ns[:3] if not quick else ns[:2]
    sweep = tile_sweep(ctx, sizes[0], sweep_ns, budget)
    cones_n = ns[min(2, len(ns) - 1)]
    cones = cone_images(ctx, sizes[0], cones_n)
    return {
        "fps": fps,
        "tile_sweep": sweep,
        "sizes": sizes,
        "ns": ns,
        "depth": DEPTH,
        "budget_s": budget,
        "cones": {
            "n": cones_n,
            "size": list(sizes[0]),
            "tile": DEFAULT_TILE_SIZE,
            "tiles": {str(g): tile_grid(img) for g, img in cones.items()},
        },
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    fps, sweep, ns, budget = data["fps"], data["tile_sweep"], data["ns"], data["budget_s"]
    sizes = [tuple(s) for s in data["sizes"]]
    rows = []
    for w, h in sizes:
        for n in ns:
            cells = []
            for method in METHODS:
                v = fps.get(f"{w}x{h}/{method}/{n}")
                cells.append("over budget" if v is None else f"{v['fps']:.3g} ({v['ms']['median']:,.0f} ms)")
            filled = next((v["filled"] for m in METHODS if (v := fps.get(f"{w}x{h}/{m}/{n}"))), math.nan)
            rows.append([f"{w} × {h}", f"{n:,}", f"{100 * filled:.1f} %", *cells])
    table = md_table(["size", "n", "primary rays on a sphere", *[f"{m} fps (ms)" for m in METHODS]], rows)

    verdicts = []
    for size in sizes:
        verdict, ratios = twice_as_fast(fps, size)
        rs = ", ".join(f"n = {n:,}: {r:.2f}×" for n, r in ratios)
        verdicts.append(f"- {size[0]} × {size[1]}: {verdict}. hre / ray engine speed-up: {rs or '—'}.")

    sweep_ns = [int(n) for n in dict.fromkeys(k.split("/")[0] for k in sweep)]
    srows = [
        [
            f"{n:,}",
            *[
                f"{sweep[f'{n}/{ts}']['ms']:,.0f} ms, {100 * sweep[f'{n}/{ts}']['cull_fraction']:.0f} % culled"
                for ts in TILES
            ],
        ]
        for n in sweep_ns
    ]
    stable = md_table(["n", *[f"tile {ts} × {ts}" for ts in TILES]], srows)

    path = f"figures/{NAME}.json"
    img_fps = image_line("ray_engines_fps", charts["ray_engines_fps"])
    img_cones = image_line("ray_engines_cones", charts["ray_engines_cones"])
    return f"""## {TITLE}

Refractive spheres filling the view (every primary ray meets one), recursion depth {DEPTH}, colour with shadows,
every method in one run. A series stops at the first frame slower than {budget:g} s ("over budget").

{img_fps}

{table}

{run.caption()}

Szécsi: "Already at a triangle count of 100, the new algorithm runs twice as fast" as the ray engine. Here:

{chr(10).join(verdicts)}

Tile-size sweep of the hierarchical ray engine at {sizes[0][0]} × {sizes[0][1]} (frame time, share of (tile,
primitive) pairs culled):

{stable}

Cone angles per tile (his Fig. 4; mode `cones`, brighter = narrower, black = no live ray, dark red = no useful cone),
{ns[min(2, len(ns) - 1)]:,} spheres, generations {", ".join(map(str, GENERATIONS))}:

{img_cones}

Raw data: [`{path}`]({path}).
"""


def tile_grid(img: np.ndarray, tile: int = DEFAULT_TILE_SIZE) -> list:
    """The per-tile colours of a ``cones`` image (each tile is one colour), rounded, as lists."""
    return np.round(np.asarray(img)[::tile, ::tile, :3], 4).tolist()


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``ray_engines_fps.png`` (frames/s against n, method colours, legend outside) and
    ``ray_engines_cones.png`` (cone half-angle per tile with its colour scale) from
    ``ray_engines.json``. Data saved before the cones were kept: they are rendered again (GL)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.patches import Patch

    pyplot = plt()
    sizes = [tuple(sz) for sz in data["sizes"]]
    ns = data["ns"]
    fps = data["fps"]
    methods = list(dict.fromkeys(k.split("/")[1] for k in fps)) or list(METHODS)
    fig, axes = pyplot.subplots(1, len(sizes), figsize=(6 * len(sizes) + 2, 4), squeeze=False, layout="constrained")
    for ax, (w, h) in zip(axes[0], sizes, strict=True):
        for method in methods:
            pts = [(n, fps[f"{w}x{h}/{method}/{n}"]["fps"]) for n in ns if fps.get(f"{w}x{h}/{method}/{n}")]
            if pts:
                ax.plot(*zip(*pts, strict=True), **series(method))
        log_axis(ax)
        ax.set_xlabel("primitives (refractive spheres)")
        ax.set_ylabel("frames / s")
        ax.set_title(f"{w} × {h}, recursion {data.get('depth', DEPTH)}")
        ax.grid(True, which="both", alpha=0.3)
    legend_outside(fig, axes)
    save(fig, figures, "ray_engines_fps", quick)

    cones = data.get("cones")
    if cones is None:  # data of a run before the cones were saved: render them again
        import types

        from renderer.gl.renderer import GLRenderer

        n = ns[min(2, len(ns) - 1)]
        images = cone_images(types.SimpleNamespace(renderer=GLRenderer()), sizes[0], n)
        cones = {
            "n": n,
            "size": list(sizes[0]),
            "tile": DEFAULT_TILE_SIZE,
            "tiles": {str(g): tile_grid(img) for g, img in images.items()},
        }
    gens = sorted(int(g) for g in cones["tiles"])
    fig, axes = pyplot.subplots(1, len(gens), figsize=(3 * len(gens) + 1.5, 3.4), layout="constrained")
    for ax, g in zip(np.atleast_1d(axes), gens, strict=True):
        ax.imshow(np.clip(np.asarray(cones["tiles"][str(g)], dtype=float), 0, 1), interpolation="nearest")
        ax.set_title(f"generation {g}")
        ax.axis("off")
    # The image's grey is 1 − φ / 90°: white = a narrow cone (good culling), black = 90° or no live ray.
    bar = fig.colorbar(ScalarMappable(Normalize(0, 90), cmap="gray_r"), ax=axes, shrink=0.85, pad=0.02)
    bar.set_label("cone half-angle φ (°)")
    fig.legend(
        handles=[Patch(color="black", label="no live ray"), Patch(color=(0.25, 0, 0), label="no useful cone")],
        loc="outside lower center",
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    fig.suptitle(
        f"hre cones per {cones['tile']} × {cones['tile']} tile, {cones['n']:,} spheres, "
        f"{cones['size'][0]} × {cones['size'][1]}",
        fontsize=10,
    )
    save(fig, figures, "ray_engines_cones", quick)
    return {
        "ray_engines_fps": "frames per second against primitive count",
        "ray_engines_cones": "cone angles per tile, generations 1, 2, 4, 8, with the colour scale",
    }


def main(argv=None) -> None:
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes and n: a smoke run")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "out" / NAME)
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--sizes", default=None, help="e.g. 256x256,640x1088 (default: both, or tiny with --quick)")
    ap.add_argument("--budget", type=float, default=None, help="frame budget in s that ends a series")
    a = ap.parse_args(argv)
    from .steps import run_one

    ctx = Context(quick=a.quick, out=a.out, runs=a.runs or (1 if a.quick else 3), progress=False)
    if a.sizes:
        ctx.ray_engine_sizes = tuple(tuple(int(v) for v in s.split("x")) for s in a.sizes.split(","))
    ctx.ray_engine_budget_s = a.budget
    _, md, _ = run_one(ctx, NAME)
    (ctx.out / f"{NAME}.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
