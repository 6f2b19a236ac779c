"""Dynamic scenes: Reiter's Figures 5.11, 5.4 and 5.6 for spheres.

1. **Updating schemes (Fig. 5.11).** A BART-Museum-like animation (``renderer.scenes.animation.museum``:
   n moving spheres in a static room of 576 spheres and the floor) is played for ``FRAMES``
   frames at 25 frames/s, for each kind of motion, with the thesis's BIH rebuilt every frame
   and a BVH rebuilt, refitted or selectively rebuilt (+30 %). The BVH/BIH update runs on every
   frame; every ``RENDER_EVERY``-th frame is also traced (primid mode, "simple colour coding")
   with the tree of that frame. Frame time = update + upload/trace/read-back (mean over the
   traced frames). From the same data: the n from which updating beats rebuilding the BIH
   for every request, per kind of motion.
2. **Cost-scaling termination (Fig. 5.4).** The kd-tree with leaf costs scaled down
   exponentially with depth (scale s at the maximal depth) against the plain SAH
   criterion (s = 1): trace time, build time and tree bytes, relative to s = 1.
3. **Two levels (Fig. 5.6).** The Museum with 4096 moving spheres, BVH only (all spheres in
   one BVH, selective rebuild) against BVH + kd-tree (static spheres in a kd-tree built once,
   moving ones in the BVH), in four shading configurations, summed over an animation.

Standalone: ``python -m bench.experiments.dynamic [--quick] [--out DIR]``.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from renderer.accel.bih import sphere_aabbs
from renderer.accel.kdtree import build_kdtree
from renderer.config.methods import METHODS
from renderer.config.settings import RenderSettings
from renderer.scenes.animation import AnimatedScene, museum, pose
from renderer.scenes.scenarios import scenario
from renderer.scenes.tree_update import TreeUpdate

from .context import Context, RunInfo
from .markdown import md_table
from .style import image_line, legend_outside, log_axis, plt, save, series
from .timing import Stat, crossover_n

NAME = "dynamic"
TITLE = "Dynamic scenes — BVH updates, cost-scaling kd-tree, two levels (Reiter Figs. 5.11, 5.4, 5.6)"

FPS = 25.0
KINDS = ("rigid", "deformable", "incoherent", "incoherent_appear")
KIND_TEXT = {
    "rigid": "rigid groups",
    "deformable": "deformable (travelling wave)",
    "incoherent": "incoherent, fixed count (respawning)",
    "incoherent_appear": "incoherent, appearing/disappearing (20 % absent)",
}
SCHEMES = (
    ("BIH rebuild (thesis)", "bih", "rebuild"),
    ("BVH rebuild", "bvh", "rebuild"),
    ("BVH refit", "bvh", "refit"),
    ("BVH selective +30 %", "bvh", "selective"),
)
NS, NS_QUICK = (256, 1024, 4096, 16384, 65536), (256, 1024)
FRAMES, FRAMES_QUICK = 100, 6
PLAY_BUDGET_S = 45.0  # one (motion, n, scheme) animation stops taking frames after this long (≥ MIN_FRAMES)
MIN_FRAMES = 20
RENDER_EVERY, RENDER_EVERY_QUICK = 10, 3
SIZE, SIZE_QUICK = (256, 256), (48, 48)
COST_SCALES = (1.0, 0.9, 0.75, 0.5, 0.25, 0.1)
MAX_PRIMS = 4


def make_anim(kind: str, n: int) -> AnimatedScene:
    base = "incoherent" if kind.startswith("incoherent") else kind
    return museum(n, base, seed=1, absent=0.2 if kind == "incoherent_appear" else 0.0)


# ------------------------------------------------------------------ Fig. 5.11


def play(
    ctx: Context, anim: AnimatedScene, method: str, scheme: str, frames: int, every: int, settings: RenderSettings
) -> dict:
    key = ("dynamic", id(anim), method, scheme, time.perf_counter())
    impl = METHODS[method]
    upd, trace, sah = [], [], []
    t_start = time.perf_counter()
    for f in range(frames):
        if not ctx.quick and f >= MIN_FRAMES and time.perf_counter() - t_start > PLAY_BUDGET_S:
            break
        frame = pose(anim, f / FPS)
        if method == "bvh":
            prepared = impl.prepare(
                frame.scene, MAX_PRIMS, 64, ctx.renderer.max_texture_width, TreeUpdate(scheme, key=key)
            )
            sah.append(prepared.stats["sah_cost"])
        else:
            prepared = impl.prepare(frame.scene, MAX_PRIMS, 64, ctx.renderer.max_texture_width)
        upd.append(prepared.build_ms)
        if (f + 1) % every == 0:
            res = ctx.renderer.render(frame.scene, settings.with_(method=method), prepared=prepared)
            trace.append(res.timings["upload"] + res.timings["trace"] + res.timings["read"])
    # frame 0 builds from scratch for every scheme: the means are over the following frames
    u, t = float(np.mean(upd[1:] if len(upd) > 1 else upd)), float(np.mean(trace))
    return {
        "update_ms": u,
        "trace_ms": t,
        "frame_ms": u + t,
        "update_samples": upd,
        "trace_samples": trace,
        "sah": sah,
        "frames": len(upd),
    }


def crossover_text(ns, ours, theirs) -> str:
    """Where ``ours`` < ``theirs`` at every larger measured n (timing.crossover_n), as table text."""
    n, i = crossover_n(ns, ours, theirs)
    if i == 0:
        return f"≤ {ns[0]:,}"
    if i == len(ns):
        return f"> {ns[-1]:,} (never within the measured n)"
    return f"≈ {n:,.0f}"


def measure_fig_5_11(ctx: Context) -> tuple[dict, dict]:
    """(raw, params): per motion, n and scheme the frame and update times."""
    ns = getattr(ctx, "dynamic_ns", None) or (NS_QUICK if ctx.quick else NS)
    frames = getattr(ctx, "dynamic_frames", None) or (FRAMES_QUICK if ctx.quick else FRAMES)
    every = RENDER_EVERY_QUICK if ctx.quick else RENDER_EVERY
    w, h = SIZE_QUICK if ctx.quick else SIZE
    settings = RenderSettings(width=w, height=h, mode="primid", max_recursion_depth=1, max_prims=MAX_PRIMS)
    data: dict = {}
    warm = make_anim("rigid", 8)
    for _, method, _ in SCHEMES:  # compile the shader variants before anything is timed
        ctx.renderer.render(warm, settings.with_(method=method))
    jobs = [(k, n, s) for k in KINDS for n in ns for s in SCHEMES]
    for kind, n, (label, method, scheme) in ctx.bar(jobs, desc="fig 5.11"):
        anim = make_anim(kind, n)
        data[(kind, n, label)] = play(ctx, anim, method, scheme, frames, every, settings)
    raw = {f"{k}/{n}/{lab}": v for (k, n, lab), v in data.items()}
    return raw, {"frames": frames, "every": every, "size": [w, h]}


def report_fig_5_11(raw: dict, params: dict, run: RunInfo, img: str) -> str:
    frames, every = params["frames"], params["every"]
    w, h = params["size"]
    data = {}
    for key, v in raw.items():
        k, n, lab = key.split("/", 2)
        data[(k, int(n), lab)] = v
    ns = sorted({n for _, n, _ in data})
    tables = []
    cross_rows = []
    for kind in KINDS:
        rows = []
        for n in ns:
            row = [f"{n:,}"]
            for label, _, _ in SCHEMES:
                d = data[(kind, n, label)]
                short = "" if d["frames"] >= frames else f" [{d['frames']} frames]"
                row.append(f"{d['frame_ms']:,.1f} ({100 * d['update_ms'] / d['frame_ms']:.0f} %){short}")
            rows.append(row)
        tables.append(
            f"**{KIND_TEXT[kind]}** — mean ms per frame (share of the update):\n\n"
            + md_table(["moving n"] + [s[0] for s in SCHEMES], rows)
        )
        bih = [data[(kind, n, SCHEMES[0][0])]["frame_ms"] for n in ns]
        cells = [KIND_TEXT[kind]]
        for label in (SCHEMES[2][0], SCHEMES[3][0]):
            txt = crossover_text(ns, [data[(kind, n, label)]["frame_ms"] for n in ns], bih)
            cells.append(txt)
        cross_rows.append(cells)
    cross = md_table(
        ["kind of motion", "refit beats BIH rebuild from n", "selective beats BIH rebuild from n"], cross_rows, "lll"
    )
    frag = f"""### Updating schemes (Reiter Fig. 5.11)

Museum-like animation, {frames} frames at {FPS:g} frames/s, primid mode (colour coding of the visible
sphere) at {w} × {h}, recursion depth 1, `MAX_PRIMS` {MAX_PRIMS}; the update runs on every frame, the
trace on every {every}th (with that frame's tree). Means exclude frame 0, where every scheme builds from
scratch. The static room (576 spheres) is in the same tree as the moving spheres. An animation stops
taking frames after {PLAY_BUDGET_S:g} s (at least {MIN_FRAMES}); such cells say how many frames they cover.

{img}

{chr(10).join(t + chr(10) for t in tables)}
**Where updating beats the thesis's rebuild-every-request** (frame time of the BVH scheme below the
BIH rebuild's at that n and every larger measured n):

{cross}

{run.caption(1, what="")}
"""
    return frag


# ------------------------------------------------------------------- Fig. 5.4


def measure_fig_5_4(ctx: Context) -> tuple[dict, dict]:
    """(raw, params): per scene and cost scale the kd-tree's trace, build and size."""
    n = 512 if ctx.quick else 4096
    w, h = SIZE_QUICK if ctx.quick else SIZE
    scenes = [(f"scenario {sc}, n = {n:,}", scenario(sc, n)) for sc in (1, 2, 3)]
    mus = museum(n, "deformable").scene
    scenes.append((f"Museum room + {n:,} sculpture spheres (rest pose)", mus))
    settings = RenderSettings(width=w, height=h, mode="color", max_recursion_depth=1, method="kdtree")
    kd_method = METHODS["kdtree"]
    saved = kd_method.cost_scale
    raw = {}
    try:
        for name, scene in ctx.bar(scenes, desc="fig 5.4"):
            lo, hi = sphere_aabbs(scene.sphere_centers, scene.sphere_radii)
            for s in COST_SCALES:
                builds = []
                for _ in range(ctx.runs):
                    kd = build_kdtree(lo, hi, cost_scale=s)
                    builds.append(kd.stats.build_ms)
                kd_method.cost_scale = s
                t = ctx.time_render(scene, settings)
                rec = {
                    "build_ms": float(np.median(builds)),
                    "trace_ms": t.stages["trace"].median,
                    "bytes": kd.stats.bytes,
                    "nodes": kd.stats.nodes,
                    "depth": kd.stats.depth_max,
                    "refs_per_prim": kd.stats.refs_per_prim,
                    "sah": kd.stats.sah_cost,
                }
                raw[f"{name}/{s}"] = rec
    finally:
        kd_method.cost_scale = saved
    return raw, {"size": [w, h]}


def report_fig_5_4(raw: dict, params: dict, run: RunInfo, img: str) -> str:
    w, h = params["size"]
    rows, bases = [], {}
    for key, rec in raw.items():  # in the order measured: scene, then the scales from 1 down
        name, s = key.rsplit("/", 1)
        first = name not in bases
        base = bases.setdefault(name, rec)
        rows.append(
            [
                name if first else "",
                f"{float(s):g}",
                f"{rec['trace_ms']:,.1f} ({rec['trace_ms'] / base['trace_ms']:.2f})",
                f"{rec['build_ms']:,.1f} ({rec['build_ms'] / base['build_ms']:.2f})",
                f"{rec['bytes']:,} ({rec['bytes'] / base['bytes']:.2f})",
                f"{rec['nodes']:,}",
                str(rec["depth"]),
                f"{rec['refs_per_prim']:.2f}",
            ]
        )
    table = md_table(
        [
            "scene",
            "scale s at max. depth",
            "trace ms (rel.)",
            "build ms (rel.)",
            "bytes (rel.)",
            "nodes",
            "depth",
            "refs / sphere",
        ],
        rows,
        "lrrrrrrr",
    )
    frag = f"""### Cost-scaling termination criterion (Reiter Fig. 5.4)

SAH kd-tree, leaf cost scaled by s^((depth − 1)/(D − 1)) (D = min(64, 8 + 1.3 log₂ n)); s = 1 is the plain
SAH criterion, to which the values in brackets are relative. Trace: colour, recursion depth 1, {w} × {h}.

{img}

{table}

{run.caption()}
"""
    return frag


# ------------------------------------------------------------------- Fig. 5.6


def measure_fig_5_6(ctx: Context) -> tuple[dict, dict]:
    """(raw, params): per shading configuration and method the animations' times."""
    n = 256 if ctx.quick else 4096
    frames = 3 if ctx.quick else 25
    w, h = (48, 36) if ctx.quick else (320, 240)
    anim = museum(n, "mixed", seed=2)
    dark = AnimatedScene(dataclasses.replace(anim.scene, lights=()), anim.motions)
    configs = [
        ("a) primary rays only (no light: ambient)", dark, 1),
        ("b) with shadows", anim, 1),
        ("c) reflection and refraction (no light)", dark, 3),
        ("d) all effects", anim, 3),
    ]
    methods = ("bvh", "twolevel")
    raw = {}
    for label, a, depth in ctx.bar(configs, desc="fig 5.6"):
        totals: dict = {m: [] for m in methods}
        split: dict = {m: {"update": [], "trace": []} for m in methods}
        for _ in range(ctx.runs):  # the two methods alternate, so drift hits both alike
            for method in methods:
                s = RenderSettings(
                    width=w,
                    height=h,
                    mode="color",
                    max_recursion_depth=depth,
                    method=method,
                    max_prims=MAX_PRIMS,
                    update="selective",
                )
                key = ("fig56", label, method, time.perf_counter())  # a fresh animation every run
                ctx.renderer.render(a, s, key=key)  # warm-up: first build, shader variant
                upd = trc = 0.0
                t0 = time.perf_counter()
                for f in range(frames):
                    res = ctx.renderer.render(a, s.with_(time=f / FPS), key=key)
                    upd += res.timings["update"]
                    trc += res.timings["trace"]
                totals[method].append((time.perf_counter() - t0) * 1e3)
                split[method]["update"].append(upd / frames)
                split[method]["trace"].append(trc / frames)
        raw[label] = {m: {"total_ms": totals[m], **split[m]} for m in methods}
    return raw, {"n": n, "frames": frames, "size": [w, h], "runs": ctx.runs}


def report_fig_5_6(raw: dict, params: dict, run: RunInfo, img: str) -> str:
    n, frames, runs = params["n"], params["frames"], params["runs"]
    w, h = params["size"]
    methods = ("bvh", "twolevel")
    rows = []
    for label, per_method in raw.items():
        st = {m: Stat(per_method[m]["total_ms"]) for m in methods}
        split = per_method
        per_frame = {
            m: f"{float(np.median(split[m]['update'])):,.1f} / {float(np.median(split[m]['trace'])):,.1f}"
            for m in methods
        }
        rows.append(
            [
                label,
                st["bvh"].fmt(0),
                per_frame["bvh"],
                st["twolevel"].fmt(0),
                per_frame["twolevel"],
                f"{100 * (st['bvh'].median / st['twolevel'].median - 1):+.1f} %",
            ]
        )
    table = md_table(
        [
            "configuration",
            "BVH only: total ms",
            "update / trace ms per frame",
            "BVH + kd-tree: total ms",
            "update / trace ms per frame",
            "speed-up (medians)",
        ],
        rows,
        "lrrrrr",
    )
    frag = f"""### Two levels: static spheres in a kd-tree (Reiter Fig. 5.6)

Museum with {n:,} moving spheres (a third each rigid, deformable, incoherent), {frames} frames at
{FPS:g} frames/s after one untimed warm-up frame, {w} × {h}, total wall time (pose + update + upload +
trace + read back), median (min–max) of {runs} animations per method, the methods alternating.
"BVH only": every sphere in one BVH, selective rebuild; "BVH + kd-tree": the 576
static spheres in a kd-tree built once, the moving ones in a BVH with selective rebuild. Our shader has
no unshadowed diffuse term, so Reiter's "diffuse" row becomes primary rays with ambient shading only
(the light removed), and his "reflections and refractions" row the same with recursion depth 3.

{table}

{run.caption()}
"""
    return frag


def plot_fig_5_11(raw: dict, figures: Path, quick: bool = False) -> str:
    """``dynamic_fig_5_11.png`` from ``dynamic.json``'s ``fig_5_11``: ms per frame against n per
    motion; a scheme's method colour (BIH blue, BVH green; the BVH's schemes as line styles),
    dotted = its update alone; the legend outside. Returns the alt text."""
    pyplot = plt()
    data = {tuple(k.split("/", 2)): v for k, v in raw.items()}
    kinds = [k for k in KINDS if any(d[0] == k for d in data)]
    labels = [lab for lab, _, _ in SCHEMES if any(d[2] == lab for d in data)]
    method = {lab: m for lab, m, _ in SCHEMES}
    fig, axes = pyplot.subplots(
        1, len(kinds), figsize=(4.4 * len(kinds) + 2.5, 4.2), sharey=True, layout="constrained", squeeze=False
    )
    for ax, kind in zip(axes[0], kinds, strict=True):
        ns = sorted({int(n) for k, n, _ in data if k == kind})
        for lab in labels:
            same = [x for x in labels if method[x] == method[lab]]
            i = same.index(lab)
            style = series(lab, method=method[lab], variant=i, ls=("-", "--", "-.")[i % 3])  # ':' is the update
            ax.plot(ns, [data[(kind, str(n), lab)]["frame_ms"] for n in ns], **style)
            ax.plot(
                ns,
                [data[(kind, str(n), lab)]["update_ms"] for n in ns],
                **{**style, "ls": ":", "alpha": 0.7, "marker": None, "label": "_update"},
            )
        ax.set_xscale("log", base=2)
        log_axis(ax, "y")
        ax.set_title(KIND_TEXT[kind], fontsize=9)
        ax.set_xlabel("moving spheres n")
        ax.grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("ms per frame (solid: update + trace; dotted: update)")
    legend_outside(fig, axes, title="scheme")
    alt = "Frame time per updating scheme and n, per kind of motion"
    save(fig, figures, "dynamic_fig_5_11", quick)
    return alt


def plot_fig_5_4(raw: dict, figures: Path, quick: bool = False) -> str:
    """``dynamic_fig_5_4.png`` from ``dynamic.json``'s ``fig_5_4``: the kd-tree's trace, build and
    bytes relative to plain SAH against the cost scale; all kd-tree (its colour), one line style
    per scene; the legend outside. Returns the alt text."""
    pyplot = plt()
    scenes = list(dict.fromkeys(k.rsplit("/", 1)[0] for k in raw))
    scales = sorted({float(k.rsplit("/", 1)[1]) for k in raw}, reverse=True)

    def rec(name: str, s: float) -> dict:
        return raw.get(f"{name}/{s}") or raw[f"{name}/{s:g}"]

    fig, axes = pyplot.subplots(1, 3, figsize=(15, 3.8), sharex=True, layout="constrained")
    for i, name in enumerate(scenes):
        style = series(name, method="kdtree", variant=i)
        for ax, key in zip(axes, ("trace_ms", "build_ms", "bytes"), strict=True):
            b = rec(name, scales[0])[key]
            ax.plot(scales, [rec(name, s)[key] / b for s in scales], **style)
    for ax, t in zip(axes, ("trace time", "build time", "tree bytes"), strict=True):
        ax.set_xscale("log")
        ax.invert_xaxis()
        ax.set_title(f"{t} relative to plain SAH")
        ax.set_xlabel("leaf-cost scale at the maximal depth")
        ax.grid(True, alpha=0.3)
    legend_outside(fig, axes, title="kd-tree, scene")
    save(fig, figures, "dynamic_fig_5_4", quick)
    return "kd-tree cost-scaling criterion against plain SAH"


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """Both charts from ``dynamic.json`` (the parts it holds)."""
    out = {}
    if data.get("fig_5_11"):
        out["dynamic_fig_5_11"] = plot_fig_5_11(data["fig_5_11"], figures, quick)
    if data.get("fig_5_4"):
        out["dynamic_fig_5_4"] = plot_fig_5_4(data["fig_5_4"], figures, quick)
    return out


PARTS = {
    "fig_5_11": (measure_fig_5_11, report_fig_5_11, "dynamic_fig_5_11"),
    "fig_5_4": (measure_fig_5_4, report_fig_5_4, "dynamic_fig_5_4"),
    "fig_5_6": (measure_fig_5_6, report_fig_5_6, None),
}


def measure(ctx: Context) -> dict:
    only = getattr(ctx, "dynamic_only", None)
    data: dict = {"params": {}}
    for name, (fn, _, _) in PARTS.items():
        if only and name not in only:
            continue
        data[name], data["params"][name] = fn(ctx)
    return data


def legacy_params(run: RunInfo) -> dict:
    """The parameters of data saved before it kept them: those of the run's mode (no standalone overrides)."""
    q = run.quick
    return {
        "fig_5_11": {
            "frames": FRAMES_QUICK if q else FRAMES,
            "every": RENDER_EVERY_QUICK if q else RENDER_EVERY,
            "size": list(SIZE_QUICK if q else SIZE),
        },
        "fig_5_4": {"size": list(SIZE_QUICK if q else SIZE)},
        "fig_5_6": {
            "n": 256 if q else 4096,
            "frames": 3 if q else 25,
            "size": [48, 36] if q else [320, 240],
            "runs": run.runs,
        },
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    params = data.get("params") or legacy_params(run)
    parts = []
    for name, (_, fn, chart) in PARTS.items():
        if name in data:
            img = image_line(chart, charts[chart]) if chart in charts else ""
            parts.append(fn(data[name], params[name], run, img))
    path = f"figures/{NAME}.json"
    return f"## {TITLE}\n\n" + "\n".join(parts) + f"\nRaw data: [`{path}`]({path}).\n"


if __name__ == "__main__":
    import argparse
    import tempfile

    from .steps import run_one

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--runs", type=int, default=None)
    ap.add_argument("--ns", default="", help="comma-separated moving-sphere counts for Fig. 5.11 (default: all)")
    ap.add_argument("--frames", type=int, default=None, help="frames per animation for Fig. 5.11")
    ap.add_argument("--only", default="", help="comma-separated parts: fig_5_11, fig_5_4, fig_5_6")
    a = ap.parse_args()
    out = a.out or Path(tempfile.mkdtemp(prefix="pocketray-dynamic-"))
    ctx = Context(quick=a.quick, out=out, runs=a.runs or (1 if a.quick else 3), progress=False)
    ctx.dynamic_ns = tuple(int(x) for x in a.ns.split(",") if x.strip()) or None
    ctx.dynamic_frames = a.frames
    ctx.dynamic_only = tuple(x.strip() for x in a.only.split(",") if x.strip()) or None
    _, text, _ = run_one(ctx, NAME)
    (out / "dynamic.md").write_text(text)
    print(text)
    print(f"\nwrote {out / 'dynamic.md'} and {out / 'figures'}/")
