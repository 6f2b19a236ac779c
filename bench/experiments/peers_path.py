"""Peers, full paths: our path integrator beside Mitsuba 3's ``path`` on one scene, interleaved.

The Cornell box (``path_scene("cornell")``, flat) at :data:`SIZE`, :data:`SPP` samples per pixel,
depth :data:`DEPTH`, through:

- ours: :data:`OURS` (label, method, settings beyond ``path.ours_settings``), ``integrator=path``;
  time = the frame's wall clock (``GLRenderer.render``: build, upload, trace, read-back);
- Mitsuba 3 ``llvm_ad_rgb``, its ``path`` integrator, the scene converted by
  ``renderer/oracle/mitsuba_scene.py`` and loaded once, ``max_depth`` = our depth and its Russian roulette
  started where ours starts (``rr_depth``, ``path.RR_DEPTH``); time = ``mi.render`` and its read-back.

The scene, the Mitsuba conversion and the settings are ``path.py``'s (its helpers, not copies).
One untimed warm-up frame each (shader variants, Dr.Jit's kernels), then each repetition renders
one frame of every engine in turn, so the ratio ours / Mitsuba comes from one run under one load.
Samples per second = width × height × spp / the median frame time. Each image's mean radiance
is kept beside it: the engines render the same scene (ours within a few per cent of Mitsuba's).
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer.oracle.path_scenes import path_scene

from .. import path_speed
from . import path
from .context import Context, RunInfo
from .markdown import md_table
from .peers import versions
from .style import colour_marker, image_line, legend_outside, method_of, plt, save
from .timing import Stat

NAME = "peers_path"
TITLE = "Peers, full paths — ours beside Mitsuba 3's path integrator"

SCENE = "cornell"
SIZE = (320, 544)
SIZE_QUICK = (20, 34)
SPP = 64
SPP_QUICK = 4
DEPTH = path.DEPTH
REPS = 3  # interleaved repetitions (at most --runs)
PROFILE_SIZE = (160, 272)  # the profile's frames: a quarter of the pixels, the same spp and depth
PROFILE_RUNS = 3
WARM_SPP = 4  # our warm-up frame compiles the variant; its sample count does not change it
# Our engines: (label, method, RenderSettings fields to change), one line each.
OURS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("ours: bih", "bih", {}),
    ("ours: bvh", "bvh", {}),
    ("ours: kdtree", "kdtree", {}),
    ("ours: twolevel", "twolevel", {}),
)
MITSUBA = path.MITSUBA
TARGET_ENGINE = "ours: bih"
TARGET_RATIO = 0.5  # ours / Mitsuba, samples per second


def measure(ctx: Context) -> dict:
    import mitsuba as mi

    mi.set_variant(path.MITSUBA_VARIANT)
    w, h = SIZE_QUICK if ctx.quick else SIZE
    spp = SPP_QUICK if ctx.quick else SPP
    scene = path_scene(SCENE)
    r = ctx.renderer
    able = set(path.path_methods())
    ours = [(label, m, extra) for label, m, extra in OURS if m in able]
    settings = {label: path.ours_settings(m, w, h, spp, DEPTH).with_(**extra) for label, m, extra in ours}
    load_before = [round(x, 2) for x in os.getloadavg()]
    t0 = time.perf_counter()
    loaded = path.mitsuba_load(scene, w, h, spp, DEPTH)
    load_ms = (time.perf_counter() - t0) * 1e3

    def frame(eng: str, seed: int) -> np.ndarray:
        if eng == MITSUBA:
            return path.mitsuba_frame(loaded, spp, seed)
        return r.render(scene, settings[eng]).image

    engines = [label for label, _, _ in ours] + [MITSUBA]
    for label in settings:  # warm-up: our variants compile (untimed) …
        r.render(scene, settings[label].with_(samples_per_pixel=min(spp, WARM_SPP)))
    path.mitsuba_frame(loaded, spp)  # … and Mitsuba's kernels
    reps = max(1, min(ctx.runs, REPS))
    ms: dict[str, list[float]] = {e: [] for e in engines}
    means: dict[str, list[float]] = {}
    for rep in ctx.bar(range(reps), desc="peers_path"):
        for eng in engines:  # interleaved: one frame of each engine in turn
            t0 = time.perf_counter()
            img = frame(eng, rep)
            ms[eng].append((time.perf_counter() - t0) * 1e3)
            means[eng] = [float(x) for x in np.asarray(img, dtype=np.float64)[..., :3].reshape(-1, 3).mean(0)]
    return {
        "scene": SCENE,
        "size": [w, h],
        "spp": spp,
        "depth": DEPTH,
        "rr_depth": path.RR_DEPTH,
        "reps": reps,
        "ours": [[label, m, extra] for label, m, extra in ours],
        "engines": {e: {"ms": Stat(ms[e]), "mean": means[e]} for e in engines},
        "mitsuba_load_ms": load_ms,
        "versions": {k: v for k, v in versions().items() if k in ("mitsuba", "drjit")},
        "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH", "Dr.Jit's default"),
        "load": {"before": load_before, "after": [round(x, 2) for x in os.getloadavg()]},
        "profile": profile_of(ctx, spp),
    }


def profile_of(ctx: Context, spp: int) -> dict:
    """Where our bih frame's time goes (bench/path_speed.py's profile: stripped variants of the shader,
    process CPU time, interleaved), at PROFILE_SIZE."""
    pw, ph = SIZE_QUICK if ctx.quick else PROFILE_SIZE
    runs = 1 if ctx.quick else PROFILE_RUNS
    prof = path_speed.profile(pw, ph, spp, DEPTH, runs, lambda _msg: None, ctx=ctx.renderer.ctx)
    return {"size": [pw, ph], "spp": spp, "runs": runs, **prof}


def rates(data: dict) -> dict[str, float]:
    """Msamples/s per engine, from the median frame time."""
    w, h = data["size"]
    return {e: w * h * data["spp"] / (Stat.from_json(v["ms"]).median / 1e3) / 1e6 for e, v in data["engines"].items()}


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    spp, depth = data["spp"], data["depth"]
    rate = rates(data)
    mit = rate.get(MITSUBA, math.nan)
    mit_mean = float(np.mean(data["engines"][MITSUBA]["mean"])) if MITSUBA in data["engines"] else math.nan
    rows = []
    for eng, v in data["engines"].items():
        ratio = rate[eng] / mit if eng != MITSUBA else math.nan
        mean = float(np.mean(v["mean"]))
        rows.append(
            [
                eng,
                Stat.from_json(v["ms"]).fmt(0),
                f"{rate[eng]:.3f}",
                f"{ratio:.2f}×" if math.isfinite(ratio) else "",
                f"{mean:.4f}" + (f" ({mean / mit_mean - 1:+.1%})" if eng != MITSUBA and mit_mean > 0 else ""),
            ]
        )
    table = md_table(
        ["engine", "ms per frame", "Msamples/s", "ours / Mitsuba", "mean radiance (vs Mitsuba)"], rows, "lrrrr"
    )
    target = rate.get(TARGET_ENGINE, math.nan) / mit
    target_txt = (
        f"`{TARGET_ENGINE.split(': ', 1)[-1]}` {rate[TARGET_ENGINE]:.3f} / Mitsuba {mit:.3f} Msamples/s = "
        f"**{target:.3f}×**, target ≥ {TARGET_RATIO:g}× {'met' if target >= TARGET_RATIO else 'NOT met'}"
        if math.isfinite(target)
        else "not measured in this run"
    )
    vers = ", ".join(f"{k} {v}" for k, v in data["versions"].items())
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    ld = data["load"]
    raw = f"figures/{NAME}.json"
    return f"""## {TITLE}

Full paths on one scene: the flat Cornell box (`path_scene("{data["scene"]}")`, `renderer/oracle/path_scenes.py`)
at {w} × {h}, {spp} samples per pixel, depth {depth}, through our path integrator (`integrator=path`;
{", ".join(f"`{m}`" for _, m, _ in data["ours"])}) and Mitsuba 3's `path` integrator (`{path.MITSUBA_VARIANT}`,
{vers}; libLLVM `{data["libllvm"]}`), the scene converted by `renderer/oracle/mitsuba_scene.py` and loaded once
({data["mitsuba_load_ms"]:,.0f} ms, not counted). Equal scene, sample count and depth: our
`max_recursion_depth` {depth} = Mitsuba's `max_depth` {depth} (docs/SHADING.md, "Path length"), and Mitsuba's
Russian roulette from the segment where ours starts it (`rr_depth` {data["rr_depth"]}) — the settings and
helpers of the path experiment (`bench/experiments/path.py`). Interleaved: after one untimed warm-up
frame each, every repetition renders one frame of each engine in turn ({data["reps"]} repetition(s),
median); time = the frame's wall clock (ours `GLRenderer.render`: build, upload, trace, read-back on
llvmpipe; Mitsuba `mi.render` and the read-back of its image). Samples/s = {w} × {h} × {spp} / time.
The mean radiance of each image shows the engines render the same scene. Load average of the machine
(shared with other jobs): {" / ".join(map(str, ld["before"]))} before, {" / ".join(map(str, ld["after"]))}
after (1, 5, 15 min).

**Target** (ours / Mitsuba, path samples per second of the same interleaved run): {target_txt}.

{img}

{table}

{run.caption(runs=data["reps"], what="median, spread min–max; engines interleaved")}
{profile_md(data, run)}
Raw data: [`{raw}`]({raw}).
"""


def profile_md(data: dict, run: RunInfo) -> str:
    """The profile's paragraph and table (none in data saved before it was measured)."""
    p = data.get("profile")
    if not p:
        return ""
    pw, ph = p["size"]
    return f"""
**Where our frame's time goes** (`bih`, {pw} × {ph}, {p["spp"]} spp, depth {data["depth"]}; `bench/path_speed.py`'s
profile: copies of our shader changed in one place each, process CPU time, {p["runs"]} interleaved run(s)):
*coherent* is the frame with every lane of a 4 × 2 pixel group tracing the same samples (what the lanes would cost
if they never waited on each other), *trace ×2* and *rnd ×2* double the traversal's and the sampler's work. What
remains to Mitsuba is mostly *lane idle*: llvmpipe runs 8 pixels in lock step and a traversal loop runs as long as
its slowest lane; sharing samples across a group would recover it but correlate the noise in 4 × 2 blocks.

{path_speed.profile_table(p, pw, ph, p["spp"])}

{run.caption_cpu(runs=p["runs"], what="median process CPU seconds, variants interleaved")}
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``peers_path.png``: Msamples/s per engine as bars (spread min–max), the target's line."""
    pyplot = plt()
    w, h = data["size"]
    engines = list(data["engines"])
    rate = rates(data)
    n = w * h * data["spp"] / 1e6
    lo = [n / (Stat.from_json(data["engines"][e]["ms"]).hi / 1e3) for e in engines]
    hi = [n / (Stat.from_json(data["engines"][e]["ms"]).lo / 1e3) for e in engines]
    vals = [rate[e] for e in engines]
    fig, ax = pyplot.subplots(figsize=(8, 0.5 * len(engines) + 1.6), layout="constrained")
    ys = np.arange(len(engines))[::-1]
    for y, e, v, a, b in zip(ys, engines, vals, lo, hi, strict=True):
        colour, _ = colour_marker(method_of(e))
        ax.barh(y, v, color=colour, hatch="" if e.startswith("ours") else "//", label=e)
        ax.errorbar(v, y, xerr=[[max(0.0, v - a)], [max(0.0, b - v)]], color="black", capsize=3, lw=1)
    if MITSUBA in rate:
        ax.axvline(TARGET_RATIO * rate[MITSUBA], color="grey", ls=":", label=f"target: {TARGET_RATIO:g} × Mitsuba")
    ax.set_yticks(ys, engines, fontsize=8)
    ax.set_xlabel("path samples per second (millions); spread min–max")
    ax.grid(True, axis="x", alpha=0.3)
    legend_outside(fig, ax, title="engine (hatched: peer)")
    fig.suptitle(f"Cornell box, {w} × {h}, {data['spp']} spp, depth {data['depth']}, engines interleaved")
    save(fig, figures, NAME, quick)
    return {NAME: "path samples per second, ours per method and Mitsuba 3 llvm, Cornell box"}
