"""The path integrator beside Mitsuba 3's (``llvm_ad_rgb``): error against time, rays per second.

Scenes: the Cornell box (``mesh_scene("cornell")``, flat) and two of the scenes the path
integrator is checked on against Mitsuba (``renderer/oracle/path_scenes.py``: a glass sphere's caustic,
a rough conductor). Per scene:

- reference: Mitsuba 3 ``llvm_ad_rgb`` at ``REF_SPP`` samples (passes of ``REF_CHUNK`` samples,
  each its own seed, averaged), cached on disk (``bench/experiments/cache.py``);
- ours (every one-pass method that traces ``integrator=path``) and Mitsuba (``llvm_ad_rgb``, its
  ``path`` integrator, the scene loaded once) at ``SPPS`` samples, interleaved: every repetition
  renders each engine once in turn, so a change of the machine's load falls on all of them;
  max_recursion_depth = Mitsuba's ``max_depth`` = ``DEPTH`` (the same count of segments,
  docs/SHADING.md, "Path length"), Mitsuba's Russian roulette started where ours starts
  (``rr_depth`` 3);
- PSNR of linear radiance clipped to [0, 1] against the reference; time = wall clock of the frame
  (ours: ``GLRenderer.render``, build to read-back; Mitsuba: ``mi.render`` and its read-back);
- primary rays per second: a depth-1 frame (camera rays only; emitters seen directly) at
  ``PRIMARY_SPP`` samples, ``width × height × spp / time``;
- rays traced per sample, counted by a counting variant of our shader (:class:`RayCounter`:
  the tracer with three lines changed so a sample's "radiance" is its number of
  ``intersect_scene`` calls — every segment and shadow ray — and of path segments); secondary
  rays per second = ``width × height × spp × (rays per sample − 1) / time`` of the full frame.
  Mitsuba's own count is not observable: its rays per second are given for our count (same
  depth, roulette start and lobe choice; its next-event estimation casts one shadow ray per
  vertex where ours casts one per sampled emitter), marked ≈.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer.config.settings import RenderSettings
from renderer.oracle import mitsuba_scene, path_scenes
from renderer.oracle.path_scenes import path_scene

from .cache import cached_array
from .context import Context, RunInfo
from .images import psnr
from .markdown import md_table
from .peers import versions
from .style import image_line, legend_outside, log_axis, plt, save, series

NAME = "path"
TITLE = "Path integrator — ours beside Mitsuba 3 (llvm)"

# scene → (width, height): the Cornell box's paths bounce inside a closed box, so its frames cost
# 10–15× the open scenes' per pixel here; it is measured at a quarter of their pixels.
SCENES = {"cornell": (80, 136), "glass_caustic": (160, 272), "rough_conductor": (160, 272)}
SCENES_QUICK = {"cornell": (20, 34), "glass_caustic": (40, 68)}
DEPTH = 8
SPPS = (16, 64, 256, 1024)
SPPS_QUICK = (16, 64)
REPS = {16: 3, 64: 2, 256: 1, 1024: 1}  # interleaved repetitions per spp (at most --runs)
REF_SPP = 16384
REF_SPP_QUICK = 1024
REF_CHUNK = 1024  # reference samples per mi.render call (seed REF_SEED + chunk)
REF_SEED = 1000
PRIMARY_SPP = 64
RR_DEPTH = 3  # Mitsuba's rr_depth where ours starts the roulette (docs/SHADING.md)
TARGETS_DB = (30.0, 35.0)
SPEED_TARGET = 0.25  # ours / Mitsuba, time to the same PSNR
PSNR_TARGET_DB = 35.0  # ours at 1,024 spp against the reference
POINT_BUDGET_S = 15.0  # an engine's frame predicted longer (from its last spp) … (see measure)
OUTLIER = 2.0  # … and longer than this × every other engine's is not measured
MITSUBA_VARIANT = "llvm_ad_rgb"
MITSUBA = "Mitsuba 3 llvm"
COUNT_SPP = 64  # samples per pixel of the counting frame
COUNT_DEPTHS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16)  # the depths whose rays per sample are counted (at 16 spp)


SCENE_WORDS = {
    "cornell": "the Cornell box",
    "area_light": "a diffuse sphere under an area light",
    "glass_caustic": "a glass sphere's caustic",
    "rough_conductor": "a rough conductor (GGX)",
}


# --------------------------------------------------------------------------- ray counting


# The counting variant's three changes to path_main (shaders/lighting.glsl): each anchor must be
# found once, so a change of the shader that moves them fails here instead of counting wrong.
_QUERY = "        Hit h = intersect_scene(q);\n        if (q.any_hit) {\n            if (h.id == NO_PRIM) L += contrib;"
_COUNT_PATCHES = (
    ("    vec3 sum = vec3(0.0);\n", "    vec3 sum = vec3(0.0);\n    float n_rays = 0.0, n_segments = 0.0;\n"),
    (_QUERY, "        n_rays += 1.0;\n        if (!q.any_hit) n_segments += 1.0;\n" + _QUERY),
    (
        "    o_image = vec4(sum, float(primary_id));\n",
        "    o_image = vec4(n_rays, n_segments, sum.r * 0.0, float(primary_id));\n",
    ),
)


def counting_source(src: str) -> str:
    """A path variant's text made to count: red = rays traced, green = path segments (per pass's
    samples; the frame's average over samples makes them per sample)."""
    for old, new in _COUNT_PATCHES:
        if src.count(old) != 1:
            raise RuntimeError(f"the counting patch's anchor {old.strip()!r} is not in the path shader once")
        src = src.replace(old, new)
    return src


def ray_counter(renderer: Any) -> Any:
    """A GLRenderer on ``renderer``'s context whose path variants count rays (its own programs)."""
    from renderer.gl.renderer import GLRenderer

    class RayCounter(GLRenderer):
        def fragment_text(self, src: str, features: tuple[str, ...]) -> str:
            return counting_source(src) if "PATH" in features else src

    return RayCounter(ctx=renderer.ctx)


def count_rays(counter: Any, scene, w: int, h: int, depth: int, spp: int = COUNT_SPP) -> tuple[float, float]:
    """(rays, path segments) per sample, mean over the frame's samples (the counting variant)."""
    img = counter.render(scene, ours_settings("bih", w, h, spp, depth)).image.astype(np.float64)
    return float(img[..., 0].mean()), float(img[..., 1].mean())


# --------------------------------------------------------------------------- engines


def ours_settings(method: str, w: int, h: int, spp: int, depth: int) -> RenderSettings:
    return RenderSettings(
        width=w,
        height=h,
        integrator="path",
        samples_per_pixel=spp,
        max_recursion_depth=depth,
        method=method,
        format="npy",
    )


def path_methods() -> list[str]:
    """The one-pass methods that trace the path integrator (not ``auto``: it is one of them)."""
    from renderer.config.methods import integrator_methods

    return [m for m in integrator_methods("path") if m != "auto"]


def mitsuba_load(scene, w: int, h: int, spp: int, depth: int) -> Any:
    return mitsuba_scene.load(scene, w, h, spp, depth, MITSUBA_VARIANT, 0, rr_depth=RR_DEPTH)


def mitsuba_frame(loaded: Any, spp: int, seed: int = 0) -> np.ndarray:
    import mitsuba as mi

    img = mi.render(loaded, spp=spp, seed=seed)  # type: ignore[arg-type]
    return np.asarray(img, dtype=np.float32)[..., :3]  # the read-back waits for the kernels


def reference(name: str, scene, w: int, h: int, spp: int) -> tuple[np.ndarray, float]:
    """Mitsuba's ``spp``-sample image (cached) and the seconds it took when it was made."""
    key = {
        "what": "path reference",
        "scene": name,
        "w": w,
        "h": h,
        "depth": DEPTH,
        "spp": spp,
        "chunk": REF_CHUNK,
        "seed": REF_SEED,
        "rr_depth": RR_DEPTH,
        "variant": MITSUBA_VARIANT,
        "versions": versions(),
    }
    src = [Path(mitsuba_scene.__file__), Path(path_scenes.__file__)]

    def compute() -> dict[str, np.ndarray]:
        t0 = time.perf_counter()
        chunk = min(spp, REF_CHUNK)
        loaded = mitsuba_load(scene, w, h, chunk, DEPTH)
        acc = np.zeros((h, w, 3), dtype=np.float64)
        for k in range(spp // chunk):
            acc += mitsuba_frame(loaded, chunk, REF_SEED + k)
        return {"image": (acc / (spp // chunk)).astype(np.float32), "seconds": np.array(time.perf_counter() - t0)}

    out = cached_array(key, compute, src)
    return out["image"], float(out["seconds"])


# --------------------------------------------------------------------------- analysis


def time_to(times: list[float], psnrs: list[float], target: float) -> tuple[float, bool]:
    """Seconds to reach ``target`` dB, interpolated in log-log (PSNR is log MSE; log time), and
    whether it was extrapolated past the last point (along the last segment's slope)."""
    pts = sorted((t, p) for t, p in zip(times, psnrs, strict=True) if t > 0 and math.isfinite(p))
    if len(pts) < 2:
        return math.nan, False
    if pts[0][1] >= target:
        return pts[0][0], False
    for (t0, p0), (t1, p1) in zip(pts, pts[1:], strict=False):
        if p0 < target <= p1:
            x = math.log(t0) + (math.log(t1) - math.log(t0)) * (target - p0) / (p1 - p0)
            return math.exp(x), False
    (t0, p0), (t1, p1) = pts[-2], pts[-1]
    if p1 <= p0:
        return math.inf, True
    return math.exp(math.log(t1) + (math.log(t1) - math.log(t0)) * (target - p1) / (p1 - p0)), True


def fit_rays(depths: list[int], rays: list[float]) -> tuple[float, float]:
    """Least-squares fit of rays per sample ``R(D) = R∞ − (R∞ − 1) · r^(D − 1)`` (one ray at depth 1,
    a share r of what is left added by each further segment): ``(R∞, r)``; r on a grid of 0.001,
    R∞ in closed form for each r."""
    d = np.asarray(depths, dtype=float)
    y = np.asarray(rays, dtype=float) - 1.0
    best = (math.inf, 1.0, 0.5)
    for r in np.arange(0.001, 1.0, 0.001):
        x = 1.0 - r ** (d - 1.0)
        a = float(x @ y / (x @ x)) if x @ x > 0 else 0.0
        err = float(np.sum((a * x - y) ** 2))
        if err < best[0]:
            best = (err, 1.0 + a, float(r))
    return best[1], best[2]


def rays_model(depth: float, limit: float, rate: float) -> float:
    return limit - (limit - 1.0) * rate ** (depth - 1.0)


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


# --------------------------------------------------------------------------- experiment


def measure(ctx: Context) -> dict:
    import mitsuba as mi

    mi.set_variant(MITSUBA_VARIANT)
    scenes = SCENES_QUICK if ctx.quick else SCENES
    spps = SPPS_QUICK if ctx.quick else SPPS
    ref_spp = REF_SPP_QUICK if ctx.quick else REF_SPP
    methods = path_methods()
    engines = [f"ours: {m}" for m in methods] + [MITSUBA]
    r = ctx.renderer
    counter = ray_counter(r)
    load_before = _load()
    out: dict[str, Any] = {}
    skipped: list[str] = []
    for name, (w, h) in scenes.items():
        scene = path_scene(name)
        ref, ref_s = reference(name, scene, w, h, ref_spp)
        ctx.log(f"path: {name} {w}×{h}, reference {ref_spp} spp ({ref_s:.0f} s when made)")
        t0 = time.perf_counter()
        loaded = mitsuba_load(scene, w, h, spps[0], DEPTH)
        load_ms = (time.perf_counter() - t0) * 1e3
        loaded1 = mitsuba_load(scene, w, h, PRIMARY_SPP, 1)

        def frame(eng: str, spp: int, depth: int = DEPTH, at: tuple = (scene, w, h, loaded, loaded1)) -> np.ndarray:
            scene_, w_, h_, full, primary = at  # this scene's (bound now: the function is made per scene)
            if eng == MITSUBA:
                return mitsuba_frame(full if depth == DEPTH else primary, spp)
            return r.render(scene_, ours_settings(eng[6:], w_, h_, spp, depth)).image

        for eng in engines:  # warm-up: compiles the variants and kernels
            frame(eng, spps[0])
            frame(eng, PRIMARY_SPP, 1)
        rows: dict[str, dict[str, Any]] = {e: {"spp": [], "ms": [], "psnr": [], "samples": []} for e in engines}
        last_s: dict[str, tuple[int, float]] = {}
        for spp in ctx.bar(spps, desc=f"path: {name}"):
            # An engine far slower than the others (brute force) stops once its next frame is predicted
            # over the budget and over OUTLIER × the others' slowest: the run's time stays bounded, while
            # a machine made slow by its load leaves out nothing.
            guess = {e: t * spp / s0 for e, (s0, t) in last_s.items()}
            live = []
            for eng in engines:
                others = max((g for e, g in guess.items() if e != eng), default=0.0)
                if eng in guess and guess[eng] > max(POINT_BUDGET_S, OUTLIER * others):
                    skipped.append(f"{eng}, {name}, {spp} spp: predicted {guess[eng]:,.0f} s per frame")
                    continue
                live.append(eng)
            samples: dict[str, list[float]] = {e: [] for e in live}
            images: dict[str, np.ndarray] = {}
            for _ in range(max(1, min(ctx.runs, REPS.get(spp, 1)))):
                for eng in live:  # interleaved: one frame of each engine in turn
                    t0 = time.perf_counter()
                    images[eng] = frame(eng, spp)
                    samples[eng].append((time.perf_counter() - t0) * 1e3)
            for eng in live:
                ms = float(np.median(samples[eng]))
                last_s[eng] = (spp, ms / 1e3)
                rows[eng]["spp"].append(spp)
                rows[eng]["ms"].append(ms)
                rows[eng]["samples"].append(samples[eng])
                rows[eng]["psnr"].append(psnr(ref, images[eng]))
        # Primary rays: depth-1 frames, interleaved.
        prim: dict[str, list[float]] = {e: [] for e in engines}
        for _ in range(max(1, min(ctx.runs, 3))):
            for eng in engines:
                t0 = time.perf_counter()
                frame(eng, PRIMARY_SPP, 1)
                prim[eng].append((time.perf_counter() - t0) * 1e3)
        rays, segments = count_rays(counter, scene, w, h, DEPTH)
        by_depth = [count_rays(counter, scene, w, h, d, 16) for d in COUNT_DEPTHS]
        out[name] = {
            "size": [w, h],
            "reference_s": ref_s,
            "reference_mean": float(ref.mean()),
            "mitsuba_load_ms": load_ms,
            "rows": rows,
            "primary_ms": {e: float(np.median(v)) for e, v in prim.items()},
            "rays_per_sample": rays,
            "segments_per_sample": segments,
            "rays_per_sample_depth1": by_depth[0][0],
            "rays_by_depth": [n for n, _ in by_depth],
            "segments_by_depth": [g for _, g in by_depth],
        }
    return {
        "scenes": out,
        "depth": DEPTH,
        "spps": list(spps),
        "ref_spp": ref_spp,
        "rr_depth": RR_DEPTH,
        "primary_spp": PRIMARY_SPP,
        "count_spp": COUNT_SPP,
        "count_depths": list(COUNT_DEPTHS),
        "engines": engines,
        "versions": versions(),
        "libllvm": os.environ.get("DRJIT_LIBLLVM_PATH", "Dr.Jit's default"),
        "load": {"before": load_before, "after": _load()},
        "skipped": skipped,
    }


# --------------------------------------------------------------------------- report


def summary(data: dict) -> dict[str, dict[str, Any]]:
    """Per scene and engine: time to each target, PSNR at the largest spp, rays per second."""
    out: dict[str, dict[str, Any]] = {}
    for name, sc in data["scenes"].items():
        w, h = sc["size"]
        per: dict[str, Any] = {}
        for eng, row in sc["rows"].items():
            if not row["spp"]:
                continue
            times = [ms / 1e3 for ms in row["ms"]]
            d: dict[str, Any] = {"targets": {}}
            for target in TARGETS_DB:
                d["targets"][target] = time_to(times, row["psnr"], target)
            spp, ms = row["spp"][-1], row["ms"][-1]
            d["psnr_1024"] = row["psnr"][row["spp"].index(1024)] if 1024 in row["spp"] else math.nan
            d["ms_1024"] = row["ms"][row["spp"].index(1024)] if 1024 in row["spp"] else math.nan
            d["primary_mrays"] = w * h * data["primary_spp"] / (sc["primary_ms"][eng] / 1e3) / 1e6
            d["msamples"] = w * h * spp / (ms / 1e3) / 1e6
            d["secondary_mrays"] = d["msamples"] * (sc["rays_per_sample"] - 1.0)
            d["all_mrays"] = d["msamples"] * sc["rays_per_sample"]
            per[eng] = d
        out[name] = per
    return out


def _fmt_t(v: tuple[float, bool]) -> str:
    t, extra = v
    if not math.isfinite(t):
        return "—"
    return ("≈ " if extra else "") + f"{t:,.2f}"


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    s = summary(data)
    depth, ref_spp = data["depth"], data["ref_spp"]
    rows = []
    ratio_rows = []
    for name, per in s.items():
        sc = data["scenes"][name]
        w, h = sc["size"]
        mit = per.get(MITSUBA)
        for eng, d in per.items():
            mark = "≈ " if eng == MITSUBA else ""
            rows.append(
                [
                    f"{name} ({w} × {h})",
                    eng,
                    " / ".join(f"{ms / 1e3:,.2f}" for ms in sc["rows"][eng]["ms"]),
                    " / ".join(f"{p:.1f}" for p in sc["rows"][eng]["psnr"]),
                    _fmt_t(d["targets"][30.0]),
                    _fmt_t(d["targets"][35.0]),
                    f"{d['primary_mrays']:.2f}",
                    f"{d['msamples']:.3f}",
                    f"{mark}{d['secondary_mrays']:.2f}",
                ]
            )
        if mit is None:
            continue
        for eng, d in per.items():
            if eng == MITSUBA:
                continue
            t35, tm35 = d["targets"][35.0][0], mit["targets"][35.0][0]
            t30, tm30 = d["targets"][30.0][0], mit["targets"][30.0][0]
            eq = (
                mit["ms_1024"] / d["ms_1024"]
                if math.isfinite(d["ms_1024"]) and math.isfinite(mit["ms_1024"])
                else math.nan
            )
            ratio_rows.append(
                [
                    name,
                    eng,
                    f"{eq:.3f}" if math.isfinite(eq) else "—",
                    f"{tm30 / t30:.3f}" if math.isfinite(t30) and math.isfinite(tm30) else "—",
                    f"{tm35 / t35:.3f}" if math.isfinite(t35) and math.isfinite(tm35) else "—",
                    f"{d['psnr_1024']:.2f}" if math.isfinite(d["psnr_1024"]) else "—",
                    f"{mit['psnr_1024']:.2f}" if math.isfinite(mit["psnr_1024"]) else "—",
                ]
            )
    table = md_table(
        [
            "scene",
            "engine",
            f"time s at {' / '.join(map(str, data['spps']))} spp",
            "PSNR dB",
            "s to 30 dB",
            "s to 35 dB",
            "primary Mrays/s",
            "Msamples/s",
            "secondary Mrays/s",
        ],
        rows,
        "llrrrrrrr",
    )
    ratios = md_table(
        [
            "scene",
            "ours",
            "speed at equal spp (1,024): t_Mitsuba / t_ours",
            "speed to 30 dB",
            "speed to 35 dB",
            f"ours PSNR at 1,024 spp vs Mitsuba {ref_spp:,}",
            "Mitsuba's own at 1,024 spp",
        ],
        ratio_rows,
        "llrrrrr",
    )
    counts = md_table(
        ["scene", "rays per sample (all)", "of them path segments", "shadow rays", "depth-1 frame: rays per sample"],
        [
            [
                name,
                f"{sc['rays_per_sample']:.3f}",
                f"{sc['segments_per_sample']:.3f}",
                f"{sc['rays_per_sample'] - sc['segments_per_sample']:.3f}",
                f"{sc['rays_per_sample_depth1']:.3f}",
            ]
            for name, sc in data["scenes"].items()
        ],
        "lrrrr",
    )
    speeds = [
        float(r[4])
        for r in ratio_rows
        if r[4] != "—"  # the speed to 35 dB
    ]
    psnrs = [float(r[5]) for r in ratio_rows if r[5] != "—"]
    speed_txt = (
        f"ours / Mitsuba, time to 35 dB: {min(speeds):.2f}× … {max(speeds):.2f}× over the scenes and methods "
        f"(target ≥ {SPEED_TARGET:g}×: {'met' if min(speeds) >= SPEED_TARGET else 'NOT met'} everywhere"
        + ("" if min(speeds) >= SPEED_TARGET else f"; met in {sum(x >= SPEED_TARGET for x in speeds)} of {len(speeds)}")
        + ")"
        if speeds
        else "no speed ratio (a target was not reached)"
    )
    psnr_txt = (
        f"ours at 1,024 spp against Mitsuba at {ref_spp:,}: {min(psnrs):.2f} … {max(psnrs):.2f} dB "
        f"(target ≥ {PSNR_TARGET_DB:g} dB: {'met' if min(psnrs) >= PSNR_TARGET_DB else 'NOT met'} everywhere"
        + (
            ""
            if min(psnrs) >= PSNR_TARGET_DB
            else f"; met in {sum(x >= PSNR_TARGET_DB for x in psnrs)} of {len(psnrs)}"
        )
        + ")"
        if psnrs
        else "no 1,024-spp frame measured"
    )
    depth_txt = depth_fit_md(data, run)
    scenes_txt = ", ".join(f"{SCENE_WORDS.get(n, n)} (`{n}`)" for n in data["scenes"])
    vers = ", ".join(f"{k} {v}" for k, v in data["versions"].items())
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    skipped = ("\n\n**Not measured:** " + "; ".join(data["skipped"]) + ".") if data["skipped"] else ""
    ld = data["load"]
    path = f"figures/{NAME}.json"
    return f"""## {TITLE}

Our path integrator (`integrator=path`, every one-pass method) and Mitsuba 3's `path` integrator
(`{MITSUBA_VARIANT}`, {vers}; libLLVM `{data["libllvm"]}`) on the same scenes, made from our scene JSON
by `renderer/oracle/mitsuba_scene.py`: {scenes_txt} (`renderer/oracle/path_scenes.py`; sizes in the table — the
Cornell box's closed room costs 10–15× per pixel, so it has a quarter of the pixels).
Equal depth: our `max_recursion_depth` {depth} = Mitsuba's `max_depth` {depth} (both count the
camera's segment and a shadow ray as a path's last segment, docs/SHADING.md, "Path length"), and
Mitsuba's Russian roulette from the same segment as ours (`rr_depth` {data["rr_depth"]}; its default
is 5). Reference: Mitsuba at {ref_spp:,} samples per pixel ({REF_CHUNK:,} per call, each its own seed),
cached. PSNR of linear radiance clipped to [0, 1]. The engines run interleaved — each repetition
renders one frame of every engine in turn — {", ".join(f"{REPS[s]} × at {s} spp" for s in data["spps"] if s in REPS)}
(median). Time = the frame's wall clock: ours `GLRenderer.render` (build, upload, trace, read-back;
llvmpipe), Mitsuba `mi.render` with the read-back of its image (scene loaded beforehand; its
kernels compiled by an untimed warm-up frame, as our shader is). Load average of the machine
(shared with other jobs): {" / ".join(map(str, ld["before"]))} before, {" / ".join(map(str, ld["after"]))}
after (1, 5, 15 min).

{img}

**Speed against accuracy.** Times to 30 and 35 dB are interpolated between the measured spp in
log time against PSNR (= log MSE); "≈" marks an extrapolation past the last point along the last
segment. Primary rays: a depth-1 frame at {data["primary_spp"]} spp (camera rays only), width × height × spp /
time. Secondary rays: samples per second × (rays per sample − 1), the rays per sample counted by
our shader (below); Mitsuba's "≈": its count is not observable, so ours is used (same depth,
roulette and lobe choice; its next-event estimation casts one shadow ray per vertex, ours one per
sampled emitter).

{table}

{run.caption(runs="interleaved repetitions as stated above")}

**Ours against Mitsuba** (speed ratio > 1: ours faster). {speed_txt}; {psnr_txt}.

{ratios}

**Rays per sample, counted.** A counting variant of our tracer (`bench/experiments/path.py`,
`counting_source`: the same shader text with three lines changed, so that a sample's output is its
number of `intersect_scene` calls and of path segments) renders each scene at {data["count_spp"]} spp with
`bih`; the frame's mean is the count per sample. A depth-1 frame counts exactly 1 (last column),
the check that the counting itself is right.

{counts}

{depth_txt}{skipped}

Raw data: [`{path}`]({path}).
"""


def depth_fit(data: dict) -> tuple[str, float, float]:
    """The scene whose paths trace the most rays at the deepest counted depth, and its fit (R∞, r):
    the cost model's expected segments of a path sample (``renderer/frame/cost.py``)."""
    depths = data["count_depths"]
    worst = max(data["scenes"], key=lambda n: data["scenes"][n]["rays_by_depth"][-1])
    limit, rate = fit_rays(depths, data["scenes"][worst]["rays_by_depth"])
    return worst, limit, rate


def depth_fit_md(data: dict, run: RunInfo) -> str:
    """The rays per sample against depth, each scene's fit, and the cost model's."""
    if "count_depths" not in data:
        return ""
    depths = data["count_depths"]
    rows = []
    for name, sc in data["scenes"].items():
        limit, rate = fit_rays(depths, sc["rays_by_depth"])
        err = max(abs(rays_model(d, limit, rate) / m - 1.0) for d, m in zip(depths, sc["rays_by_depth"], strict=True))
        rows.append([name, *(f"{x:.2f}" for x in sc["rays_by_depth"]), f"{limit:.2f}", f"{rate:.3f}", f"{err:.1%}"])
    worst, limit, rate = depth_fit(data)
    run.note(
        f"path: PATH_SEGMENTS_LIMIT = {limit:.2f}, PATH_SEGMENTS_RATE = {rate:.3f} (renderer/frame/cost.py; {worst})"
    )
    table = md_table(
        ["scene", *(f"D = {d}" for d in depths), "R∞", "r", "max error of the fit"], rows, "l" + "r" * (len(depths) + 3)
    )
    return f"""**Segments per path sample against depth** (the cost model's input). Rays per sample
(segments and shadow rays, as docs/SHADING.md counts a path's segments) counted at 16 spp with
`bih` at each max_recursion_depth D, and the least-squares fit R(D) = R∞ − (R∞ − 1) · r^(D − 1)
(one ray at D = 1; each further segment adds a share r of what is left). The open scenes end
most paths on their second segment (a bounce off the floor leaves the scene); the closed Cornell
box, walls of albedo ≈ 0.7, keeps them until Russian roulette ends them. `renderer/frame/cost.py` takes
the fit of the scene with the most rays ({worst}: R∞ = {limit:.2f}, r = {rate:.3f}) as the expected
segments of a sample, for the frame's cost and for the `POCKETRAY_MAX_WORK` check of path frames
(spp × segments × pixels): it overestimates the open scenes about twice.

{table}
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``path.png``: PSNR against time per scene, one series per engine (ours per method, Mitsuba)."""
    pyplot = plt()
    names = list(data["scenes"])
    fig, axes = pyplot.subplots(1, len(names), figsize=(4.6 * len(names) + 2.5, 4.4), layout="constrained")
    axes = np.atleast_1d(axes)
    for ax, name in zip(axes, names, strict=True):
        sc = data["scenes"][name]
        for eng, row in sc["rows"].items():
            if not row["spp"]:
                continue
            ax.plot(
                [ms / 1e3 for ms in row["ms"]], row["psnr"], **series(eng, ls="-" if eng.startswith("ours") else "--")
            )
            for t, p, spp in zip([ms / 1e3 for ms in row["ms"]], row["psnr"], row["spp"], strict=True):
                if eng == MITSUBA:
                    ax.annotate(f"{spp}", (t, p), fontsize=6, xytext=(3, -8), textcoords="offset points")
        for target in TARGETS_DB:
            ax.axhline(target, color="grey", lw=0.8, ls=":")
        log_axis(ax, "x", minor_labels=False)
        ax.grid(True, which="both", alpha=0.3)
        w, h = sc["size"]
        ax.set_title(f"{name}, {w} × {h}", fontsize=9)
        ax.set_xlabel("time per frame (s)")
    axes[0].set_ylabel(f"PSNR vs Mitsuba {data['ref_spp']:,} spp (dB)")
    legend_outside(fig, axes, title="engine (solid: ours); Mitsuba's spp marked")
    fig.suptitle(
        f"Path integrator, depth {data['depth']}: error against time at {', '.join(map(str, data['spps']))} spp"
    )
    save(fig, figures, NAME, quick)
    return {NAME: "PSNR against time per scene, our methods and Mitsuba 3 llvm"}
