"""Speed against accuracy: every knob that trades one for the other, with the Pareto front.

Reference image: the float64 reference tracer at recursion depth 8 with 4 × 4
supersampling (rendered at 4W × 4H, clamped, box-filtered), cached on disk. Knobs:

- recursion depth 1 … 8;
- rendering at ½ and ¼ of the resolution, upscaled bilinearly (the upscaling is timed);
- samples per pixel 1 and 4 (``RenderSettings.samples_per_pixel``);
- the weight cut-off ε (``RenderSettings.min_weight``): secondary rays whose path weight
  is below ε are not traced.

The path integrator (``integrator=path``) estimates another image — light transport, not the
Whitted tracer's — so it has its own panel and reference: the Cornell box against Mitsuba 3 at
16,384 samples (the path experiment's cached reference, ``bench/experiments/path.py``), its knobs
samples per pixel and max_recursion_depth (a shorter path is faster and darker: biased).

Time to image = wall time of the whole frame (build, upload, trace, read back, upscale),
median of the runs with min–max spread. Error against the reference: PSNR, max absolute
error, SSIM (scikit-image). Methods and BIH parameters do not change the image: they are
rendered at one knob setting to show the same error at different times.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from renderer.oracle import reference as _reference_module
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import scenario

from .cache import cached_array
from .context import Context, RunInfo
from .images import max_abs, psnr, ssim, upscale
from .markdown import details, fmt_db, md_table
from .scenes import default_settings, has_setting, method_names
from .style import image_line, legend_outside, log_axis, plt, save, series as line_style
from .timing import Stat

NAME = "pareto"
TITLE = "Speed against accuracy — the Pareto front"

N = 256
N_QUICK = 16
# Half the thesis's side: the float64 reference at depth 8 with 4 × 4 supersampling of a
# full 640 × 1088 frame would take tens of minutes per scenario here.
SIZE = (320, 544)
SIZE_QUICK = (64, 108)
REF_DEPTH = 8
REF_SS = 4
SCALES = (1, 2, 4)  # render at 1/s of the resolution, then upscale
SPPS = (1, 4)
EPSILONS = (0.003, 0.01, 0.03, 0.1, 0.3)
# Recommendation rules (stated in the section). Quality = worst scenario, time = mean of the scenarios.
# "interactive": the fastest setting at most this much worse than the baseline frame (the
# service's previous default: depth 5, full resolution, 1 spp, no cut-off).
BASELINE = dict(depth=5, scale=1, spp=1, eps=0.0)
INTERACTIVE_MAX_PSNR_LOSS_DB = 1.0
INTERACTIVE_MAX_SSIM_LOSS = 0.01
# "still": the fastest setting within this of the best worst-scenario PSNR measured.
STILL_WITHIN_DB = 0.5
EXACT_AT = dict(depth=5, scale=1, spp=1, eps=0.0)  # where methods / MAX_PRIMS are compared
EXACT_MAX_PRIMS = (1, 4, 8, 16)
# The path integrator's panel: the Cornell box, its knobs samples per pixel × depth.
PATH_SCENE = "cornell"
PATH_SPPS = (16, 64, 256)
PATH_SPPS_QUICK = (16,)
PATH_DEPTHS = (2, 4, 8)
PATH_DEPTHS_QUICK = (2, 8)
PATH_RUNS = 3  # runs per path point (after the warm-up frame)


@dataclasses.dataclass(frozen=True)
class Knobs:
    depth: int
    scale: int = 1
    spp: int = 1
    eps: float = 0.0

    @property
    def label(self) -> str:
        parts = [f"depth {self.depth}"]
        if self.scale != 1:
            parts.append(f"1/{self.scale} res")
        if self.spp != 1:
            parts.append(f"{self.spp} spp")
        if self.eps:
            parts.append(f"ε {self.eps:g}")
        return ", ".join(parts)

    @property
    def family(self) -> str:
        if self.eps:
            return "weight cut-off ε"
        if self.scale != 1:
            return f"1/{self.scale} resolution" + (f", {self.spp} spp" if self.spp != 1 else "")
        if self.spp != 1:
            return f"{self.spp} spp"
        return "recursion depth"


def knob_grid(quick: bool) -> list[Knobs]:
    spps = SPPS if has_setting("samples_per_pixel") else (1,)
    eps = EPSILONS if has_setting("min_weight") else ()
    if quick:
        depths_main, depths_other = (1, 2, BASELINE["depth"], 8), (1, 8)
        eps = eps[-1:] if eps else ()
        scales = (1, 2)
    else:
        depths_main, depths_other = tuple(range(1, 9)), (1, 2, 3, 5, 8)
        scales = SCALES
    grid = [Knobs(d) for d in depths_main]
    for sc in scales:
        for spp in spps:
            if (sc, spp) != (1, 1):
                grid += [Knobs(d, sc, spp) for d in depths_other]
    for spp in spps:
        grid += [Knobs(max(depths_main), 1, spp, e) for e in eps]
    return list(dict.fromkeys(grid))


def reference_image(sc: int, n: int, w: int, h: int) -> np.ndarray:
    key = {
        "what": "pareto reference",
        "scenario": sc,
        "n": n,
        "seed": 0,
        "radius": 1.0,
        "w": w,
        "h": h,
        "depth": REF_DEPTH,
        "ss": REF_SS,
    }
    src = [Path(_reference_module.__file__), Path(_reference_module.__file__).parent / "scenarios.py"]

    def compute():
        scene = scenario(sc, n, seed=0, radius=1.0)
        st = default_settings().with_(
            width=w, height=h, mode="color", max_recursion_depth=REF_DEPTH, method="bruteforce"
        )
        return {"image": render_reference(scene, st, supersample=REF_SS).image.astype(np.float32)}

    return cached_array(key, compute, src)["image"]


def to_u8(img: np.ndarray) -> np.ndarray:
    """The service's 8-bit image of a float image (RenderResult.image_u8's rounding)."""
    return np.floor(np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats in both time (lower) and quality (higher)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], -points[i][1]))
    front, best = [], -math.inf
    for i in order:
        if points[i][1] > best:
            front.append(i)
            best = points[i][1]
    return front


def step_front(ax, points: list[tuple[float, float]]) -> list[int]:
    """Draw the Pareto front of (time, PSNR) points as a black step line; its indices."""
    front = pareto_front(points)
    ax.step(
        [points[i][0] for i in front],
        [points[i][1] for i in front],
        where="post",
        color="black",
        lw=1.2,
        alpha=0.7,
        label="Pareto front",
    )
    return front


def measure(ctx: Context) -> dict:
    n = N_QUICK if ctx.quick else N
    w, h = SIZE_QUICK if ctx.quick else SIZE
    grid = knob_grid(ctx.quick)
    base = default_settings().with_(width=w, height=h, mode="color")
    scs = (1, 2, 3)

    refs = {}
    for sc in ctx.bar(scs, desc="pareto: float64 references"):
        refs[sc] = reference_image(sc, n, w, h)

    def settings_for(k: Knobs, **over):
        kw = dict(width=max(1, w // k.scale), height=max(1, h // k.scale), max_recursion_depth=k.depth)
        if has_setting("samples_per_pixel"):
            kw["samples_per_pixel"] = k.spp
        if has_setting("min_weight"):
            kw["min_weight"] = k.eps
        kw.update(over)
        return base.with_(**kw)

    def post_for(k: Knobs):
        if k.scale == 1:
            return lambda res: res.image
        return lambda res: upscale(res.image, w, h)

    results: dict[tuple[int, Knobs], dict] = {}
    jobs = [(sc, k) for sc in scs for k in grid]
    for sc, k in ctx.bar(jobs, desc="pareto: knobs"):
        scene = scenario(sc, n, seed=0, radius=1.0)
        t = ctx.time_render(scene, settings_for(k), post=post_for(k), budget_s=None)
        img = t.result
        results[(sc, k)] = {
            "time": t.total,
            "psnr": psnr(refs[sc], img),
            "ssim": ssim(refs[sc], img),
            "max_abs": max_abs(refs[sc], img),
        }

    # Methods and MAX_PRIMS at one knob setting: same image, different time.
    ek = Knobs(**EXACT_AT)
    exact_variants = exact_variants_of_the_code()
    exact: dict[tuple[int, str], dict] = {}
    for sc in ctx.bar(scs, desc="pareto: methods"):
        scene = scenario(sc, n, seed=0, radius=1.0)
        first_img = None
        for label, over in exact_variants:
            if not ctx.within_budget(scene, settings_for(ek, **over), f"{label}, scenario {sc}"):
                continue
            t = ctx.time_render(scene, settings_for(ek, **over), post=post_for(ek), budget_s=None)
            img = t.result
            if first_img is None:
                first_img = img
            exact[(sc, label)] = {
                "time": t.total,
                "psnr": psnr(refs[sc], img),
                "ssim": ssim(refs[sc], img),
                "max_abs": max_abs(refs[sc], img),
                "max_diff_vs_first": float(np.max(np.abs(img.astype(np.float64) - first_img))),
                "u8_identical": bool(np.array_equal(to_u8(img), to_u8(first_img))),
            }

    _, _, interactive, still, _, recommended = recommend(grid, results, scs)
    return {
        "path": measure_path(ctx),
        "size": [w, h],
        "n": n,
        "reference": {"depth": REF_DEPTH, "ss": REF_SS},
        "results": {f"{sc}/{k.label}": {**v, "knobs": dataclasses.asdict(k)} for (sc, k), v in results.items()},
        "exact": {f"{sc}/{lab}": v for (sc, lab), v in exact.items()},
        "exact_at": dataclasses.asdict(ek),
        "exact_variants": [lab for lab, _ in exact_variants],
        "method": base.method,
        "max_prims": base.max_prims,
        "recommended": recommended,
        "recommended_knobs": {"interactive": dataclasses.asdict(interactive), "still": dataclasses.asdict(still)},
    }


def measure_path(ctx: Context) -> dict:
    """The path integrator's points: the Cornell box at samples per pixel × depth with the default
    method, PSNR against the path experiment's Mitsuba reference (depth ``path.DEPTH``), time to image."""
    import os
    import time

    from renderer.oracle.path_scenes import path_scene

    from . import path

    w, h = path.SCENES_QUICK[PATH_SCENE] if ctx.quick else path.SCENES[PATH_SCENE]
    ref_spp = path.REF_SPP_QUICK if ctx.quick else path.REF_SPP
    scene = path_scene(PATH_SCENE)
    ref, _ = path.reference(PATH_SCENE, scene, w, h, ref_spp)
    method = default_settings().method
    points = []
    for spp in ctx.bar(PATH_SPPS_QUICK if ctx.quick else PATH_SPPS, desc="pareto: path"):
        for depth in PATH_DEPTHS_QUICK if ctx.quick else PATH_DEPTHS:
            st = path.ours_settings(method, w, h, spp, depth)
            t = ctx.time_render(scene, st, runs=min(ctx.runs, PATH_RUNS), post=lambda res: res.image, budget_s=None)
            points.append({"spp": spp, "depth": depth, "time": t.total, "psnr": psnr(ref, t.result)})
    return {
        "scene": PATH_SCENE,
        "size": [w, h],
        "ref_spp": ref_spp,
        "ref_depth": path.DEPTH,
        "method": method,
        "points": points,
        "measured": time.strftime("%Y-%m-%d %H:%M %Z"),
        "load": [round(x, 2) for x in os.getloadavg()],
    }


def path_front_md(data: dict, run: RunInfo) -> str:
    """The path integrator's points and their Pareto front (empty for data measured before it)."""
    p = data.get("path")
    if not p:
        return ""
    pts = p["points"]
    front = set(pareto_front([(q["time"]["median"], q["psnr"]) for q in pts]))
    rows = [
        [
            f"{q['spp']} spp, depth {q['depth']}" + (" ◆" if i in front else ""),
            Stat.from_json(q["time"]).fmt(1),
            fmt_db(q["psnr"]),
        ]
        for i, q in sorted(enumerate(pts), key=lambda iq: iq[1]["time"]["median"])
    ]
    w, h = p["size"]
    load = f", load average {' / '.join(map(str, p['load']))} (1, 5, 15 min)" if "load" in p else ""
    return f"""**The path integrator** (`integrator=path`, its own panel: it estimates light transport, so its
reference is Mitsuba 3's `path` at {p["ref_spp"]:,} samples, depth {p["ref_depth"]}, of the {p["scene"]} box
at {w} × {h} — the path experiment's — not the Whitted reference above). Knobs: samples per pixel and
max_recursion_depth (shorter paths: faster, darker — biased); method `{p["method"]}`; ◆ = on the front.
Measured {p["measured"]}{load}.

{md_table(["setting", "time ms", "PSNR dB"], rows, "lrr")}

{run.caption(runs=min(run.runs, PATH_RUNS))}
"""


def exact_variants_of_the_code() -> list[tuple[str, dict]]:
    """(label, settings) of the methods and MAX_PRIMS compared at one knob setting."""
    out = []
    for m in method_names(dispatchers=True):
        if m == "bih":
            out += [(f"bih, MAX_PRIMS {mp}", dict(method="bih", max_prims=mp)) for mp in EXACT_MAX_PRIMS]
        else:
            out.append((m, dict(method=m)))
    return out


def as_settings(k: Knobs) -> dict:
    """A recommended profile as settings (``resolution_scale`` is the client's, not RenderSettings')."""
    d = {"max_recursion_depth": k.depth}
    if has_setting("samples_per_pixel"):
        d["samples_per_pixel"] = k.spp
    if has_setting("min_weight"):
        d["min_weight"] = k.eps
    d["resolution_scale"] = f"1/{k.scale}" if k.scale != 1 else "1"
    return d


def recommend(grid: list[Knobs], results: dict, scs) -> tuple[dict, float, Knobs, Knobs, Knobs, dict]:
    """The recommendation over all scenarios (worst PSNR / SSIM, mean time): per setting its
    aggregate, the best worst-scenario PSNR, the interactive and still settings, the baseline,
    and both as settings."""
    agg = {}
    for k in grid:
        agg[k] = {
            "time": float(np.mean([results[(sc, k)]["time"].median for sc in scs])),
            "psnr": min(results[(sc, k)]["psnr"] for sc in scs),
            "ssim": min(results[(sc, k)]["ssim"] for sc in scs),
        }
    best_psnr = max(v["psnr"] for v in agg.values())
    still_ok = [k for k in grid if agg[k]["psnr"] >= best_psnr - STILL_WITHIN_DB]
    still = min(still_ok, key=lambda k: agg[k]["time"])
    baseline = Knobs(**BASELINE)
    b = agg[baseline]
    inter_ok = [
        k
        for k in grid
        if agg[k]["psnr"] >= b["psnr"] - INTERACTIVE_MAX_PSNR_LOSS_DB
        and agg[k]["ssim"] >= b["ssim"] - INTERACTIVE_MAX_SSIM_LOSS
    ]  # the baseline itself qualifies
    interactive = min(inter_ok, key=lambda k: agg[k]["time"])
    recommended = {"interactive": as_settings(interactive), "still": as_settings(still)}
    return agg, best_psnr, interactive, still, baseline, recommended


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    n = data["n"]
    scs = (1, 2, 3)
    results: dict[tuple[int, Knobs], dict] = {}
    for key, v in data["results"].items():  # in the order measured: scenario, then the knob grid
        k = Knobs(**v["knobs"])
        results[(int(key.split("/", 1)[0]), k)] = {**v, "time": Stat.from_json(v["time"])}
    grid = list(dict.fromkeys(k for _, k in results))
    exact = {}
    for key, v in data["exact"].items():
        sc, lab = key.split("/", 1)
        exact[(int(sc), lab)] = {**v, "time": Stat.from_json(v["time"])}
    # Older data did not keep the variants it tried: those of the code.
    exact_variants = (
        [(lab, None) for lab in data["exact_variants"]] if "exact_variants" in data else exact_variants_of_the_code()
    )
    ek = Knobs(**data.get("exact_at", EXACT_AT))
    defaults = default_settings()
    method, max_prims = data.get("method", defaults.method), data.get("max_prims", defaults.max_prims)

    agg, best_psnr, interactive, still, baseline, recommended = recommend(grid, results, scs)
    b = agg[baseline]
    inter_rule = (
        f"the fastest setting at most {INTERACTIVE_MAX_PSNR_LOSS_DB:g} dB PSNR and "
        f"{INTERACTIVE_MAX_SSIM_LOSS:g} SSIM below the baseline frame ({baseline.label}, full resolution, "
        f"1 spp: {b['time']:,.1f} ms, worst PSNR {fmt_db(b['psnr'])} dB, worst SSIM {b['ssim']:.4f})"
    )
    run.note(
        f"pareto: interactive = {json.dumps(recommended['interactive'])}; still = {json.dumps(recommended['still'])}"
    )

    # ---- chart

    # ---- tables
    front_rows = []
    per_sc_fronts = {
        sc: {grid[i] for i in pareto_front([(results[(sc, k)]["time"].median, results[(sc, k)]["psnr"]) for k in grid])}
        for sc in scs
    }
    agg_front = {grid[i] for i in pareto_front([(agg[k]["time"], agg[k]["psnr"]) for k in grid])}
    for k in sorted(agg_front, key=lambda k: agg[k]["time"]):
        mark = " **(interactive)**" if k == interactive else (" **(still)**" if k == still else "")
        front_rows.append(
            [
                k.label + mark,
                f"{agg[k]['time']:,.1f}",
                fmt_db(agg[k]["psnr"]),
                f"{agg[k]['ssim']:.4f}",
                ", ".join(str(sc) for sc in scs if k in per_sc_fronts[sc]) or "—",
            ]
        )
    front_table = md_table(
        ["setting", "mean time (ms)", "worst PSNR (dB)", "worst SSIM", "on the front of scenario"], front_rows, "lrrrl"
    )
    all_tables = []
    for sc in scs:
        rows = []
        for k in sorted(grid, key=lambda k: results[(sc, k)]["time"].median):
            r = results[(sc, k)]
            rows.append(
                [
                    k.label + (" ◆" if k in per_sc_fronts[sc] else ""),
                    r["time"].fmt(1),
                    fmt_db(r["psnr"]),
                    f"{r['max_abs']:.4f}",
                    f"{r['ssim']:.4f}",
                ]
            )
        all_tables.append(
            details(
                f"Scenario {sc}: all {len(grid)} settings (◆ = on this scenario's Pareto front)",
                md_table(["setting", "time ms", "PSNR dB", "max abs err", "SSIM"], rows, "lrrrr")
                + "\n\n"
                + run.caption(),
            )
        )
    ex_rows = []
    for sc in scs:
        for lab, _ in exact_variants:
            if (sc, lab) not in exact:
                ex_rows.append([str(sc), lab, "not measured (see below)", "", "", "", "", ""])
                continue
            e = exact[(sc, lab)]
            ex_rows.append(
                [
                    str(sc),
                    lab,
                    e["time"].fmt(1),
                    fmt_db(e["psnr"]),
                    f"{e['max_abs']:.4f}",
                    f"{e['ssim']:.4f}",
                    f"{e['max_diff_vs_first']:.2e}",
                    "yes" if e["u8_identical"] else "**no**",
                ]
            )
    ex_table = md_table(
        [
            "scenario",
            "method",
            "time ms",
            "PSNR dB",
            "max abs err",
            "SSIM",
            f"max |Δ| vs {exact_variants[0][0]}",
            "same 8-bit image",
        ],
        ex_rows,
        "rlrrrrrc",
    )
    by_sc = {sc: [v for (s2, _), v in exact.items() if s2 == sc] for sc in scs}
    spread = max(max(v["psnr"] for v in by_sc[sc]) - min(v["psnr"] for v in by_sc[sc]) for sc in scs)
    tspread = max(max(v["time"].median for v in by_sc[sc]) / min(v["time"].median for v in by_sc[sc]) for sc in scs)
    same_image = all(v["max_diff_vs_first"] == 0.0 for v in exact.values())
    same_u8 = all(v["u8_identical"] for v in exact.values())
    skipped_md = run.skipped_md()

    missing = [name for name in ("samples_per_pixel", "min_weight") if not has_setting(name)]
    missing_txt = (
        f"\n\n**Not measured:** RenderSettings of this build has no {', '.join(f'`{m}`' for m in missing)}."
        if missing
        else ""
    )
    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    return f"""## {TITLE}

Thesis scenarios 1–3 with n = {n} spheres of radius 1 at {w} × {h}, colour. Reference: the float64
reference tracer at recursion depth {REF_DEPTH} with {REF_SS} × {REF_SS} supersampling (box filter). Every
setting is a combination of the knobs: recursion depth; ½ or ¼ resolution upscaled bilinearly (upscale
timed); samples per pixel; the weight cut-off ε (`min_weight`). Other settings at the defaults
(method `{method}`, `MAX_PRIMS` {max_prims}). Time to image = whole frame, wall clock.{missing_txt}

{img}

**Pareto front over the three scenarios** (mean time, worst-scenario PSNR / SSIM):

{front_table}

{run.caption()}

**Recommended defaults** (from the table above; the rules are fixed in `bench/experiments/pareto.py`):

- *interactive*: **{interactive.label}** — {inter_rule}: {agg[interactive]["time"]:,.1f} ms mean,
  worst PSNR {fmt_db(agg[interactive]["psnr"])} dB, worst SSIM {agg[interactive]["ssim"]:.4f}.
- *still*: **{still.label}** — the fastest setting within {STILL_WITHIN_DB:g} dB of the best worst-scenario
  PSNR measured ({fmt_db(best_psnr)} dB): {agg[still]["time"]:,.1f} ms mean, worst PSNR
  {fmt_db(agg[still]["psnr"])} dB, worst SSIM {agg[still]["ssim"]:.4f}.

```json
{json.dumps(recommended, indent=2)}
```

**Exact knobs land on the same error.** Methods and `MAX_PRIMS` at {ek.label} (red stars on the chart):
the PSNR differs by at most {spread:.2e} dB between them in any scenario while the time differs up to
{tspread:.2f}×; the float images are {"bit-identical" if same_image else "not all bit-identical"}, the 8-bit
images {"identical" if same_u8 else "NOT all identical"} (last two columns).

{ex_table}

{run.caption()}

{path_front_md(data, run)}
{skipped_md}

{chr(10).join(t + chr(10) for t in all_tables)}
Raw data: [`{path}`]({path}).
"""


def _knobs_of(settings: dict) -> Knobs:
    """The Knobs of a recommended profile as saved (``as_settings``)."""
    scale = settings.get("resolution_scale", "1")
    return Knobs(
        depth=settings["max_recursion_depth"],
        scale=int(scale.split("/")[-1]) if "/" in scale else 1,
        spp=settings.get("samples_per_pixel", 1),
        eps=settings.get("min_weight", 0.0),
    )


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``pareto.png`` from ``pareto.json``: PSNR and SSIM against time per scenario, knob families
    as colours (a palette of their own: they are not methods), the Pareto front, and the methods
    at one knob setting in their method colours; the legend outside the panels."""
    pyplot = plt()
    w, h = data["size"]
    n = data["n"]
    results = {}
    grid: list[Knobs] = []
    for key, v in data["results"].items():
        sc, _ = key.split("/", 1)
        k = Knobs(**v["knobs"])
        results[(int(sc), k)] = v
        if k not in grid:
            grid.append(k)
    scs = sorted({sc for sc, _ in results})
    exact = {(int(key.split("/", 1)[0]), key.split("/", 1)[1]): v for key, v in data["exact"].items()}
    exact_labels = list(dict.fromkeys(lab for _, lab in exact))
    ek = Knobs(**data["exact_at"]) if "exact_at" in data else Knobs(**EXACT_AT)
    marks = (
        {name: Knobs(**kn) for name, kn in data["recommended_knobs"].items()}
        if "recommended_knobs" in data
        else {name: _knobs_of(st) for name, st in data["recommended"].items()}
    )
    families = list(dict.fromkeys(k.family for k in grid))
    family_colour = {
        f: c
        for f, c in zip(
            families,
            (
                "#4c72b0",
                "#dd8452",
                "#55a868",
                "#c44e52",
                "#8172b3",
                "#937860",
                "#da8bc3",
                "#8c8c8c",
                "#ccb974",
                "#64b5cd",
            ),
            strict=False,  # a palette, not a list per family: families past its end are grey (.get below)
        )
    }
    fig, axes = pyplot.subplots(
        2, len(scs), figsize=(5.2 * len(scs) + 3, 9), sharex="col", layout="constrained", squeeze=False
    )
    for j, sc in enumerate(scs):
        for row, metric in enumerate(("psnr", "ssim")):
            ax = axes[row, j]
            pts = [(results[(sc, k)]["time"]["median"], results[(sc, k)][metric]) for k in grid]
            finite = [(x, y if y is not None and math.isfinite(y) else 100.0) for x, y in pts]
            for fam in families:
                idx = [i for i, k in enumerate(grid) if k.family == fam]
                ax.scatter(
                    [finite[i][0] for i in idx],
                    [finite[i][1] for i in idx],
                    s=22,
                    color=family_colour.get(fam, "#8c8c8c"),
                    label=f"knobs: {fam}",
                )
            front = step_front(ax, finite)
            ax.scatter(
                [finite[i][0] for i in front],
                [finite[i][1] for i in front],
                s=70,
                facecolors="none",
                edgecolors="black",
            )
            labs = [lab for lab in exact_labels if (sc, lab) in exact]
            bih_labs = [lab for lab in labs if lab.startswith("bih")]
            for lab in labs:
                e = exact[(sc, lab)]
                y = e[metric] if e[metric] is not None and math.isfinite(e[metric]) else 100.0
                st = line_style(
                    lab.replace("bih, MAX_PRIMS ", "BIH "), variant=bih_labs.index(lab) if lab in bih_labs else 0
                )
                ax.scatter(
                    [e["time"]["median"]],
                    [y],
                    marker=st["marker"],
                    s=60,
                    color=st["color"],
                    edgecolors="black",
                    linewidths=0.4,
                    zorder=5,
                    label=f"{st['label']} at {ek.label}",
                )
            for name, k in marks.items():
                if (sc, k) in results:
                    ax.annotate(
                        name,
                        (results[(sc, k)]["time"]["median"], results[(sc, k)][metric]),
                        fontsize=8,
                        xytext=(-10, -16),
                        textcoords="offset points",
                        weight="bold",
                    )
            log_axis(ax, "x")
            ax.grid(True, which="both", alpha=0.3)
            if row == 0:
                ax.set_title(f"scenario {sc}, n = {n}")
            else:
                ax.set_xlabel("time to image (ms, median)")
            if j == 0:
                ax.set_ylabel({"psnr": "PSNR vs reference (dB)", "ssim": "SSIM vs reference"}[metric])
    legend_outside(fig, axes)
    ref = data.get("reference", {"depth": REF_DEPTH, "ss": REF_SS})
    fig.suptitle(
        f"Error against time, {w} × {h}; reference: float64, depth {ref['depth']}, "
        f"{ref['ss']}×{ref['ss']} supersampling"
    )
    save(fig, figures, "pareto", quick)
    charts = {"pareto": "Error against time to image with the Pareto front, per scenario"}
    if data.get("path"):
        charts["pareto_path"] = plot_path(data["path"], figures, quick)
    return charts


def plot_path(p: dict, figures: Path, quick: bool) -> str:
    """``pareto_path.png``: the path integrator's PSNR against time, one line per depth, the front."""
    pyplot = plt()
    fig, ax = pyplot.subplots(figsize=(7.5, 4.4), layout="constrained")
    pts = p["points"]
    depths = sorted({q["depth"] for q in pts})
    for i, depth in enumerate(depths):
        qs = sorted((q for q in pts if q["depth"] == depth), key=lambda q: q["spp"])
        st = line_style(f"{p['method']}: depth {depth}", variant=i, method=p["method"])
        ax.plot([q["time"]["median"] for q in qs], [q["psnr"] for q in qs], **st)
        for q in qs:
            ax.annotate(
                f"{q['spp']}", (q["time"]["median"], q["psnr"]), fontsize=7, xytext=(3, 3), textcoords="offset points"
            )
    step_front(ax, [(q["time"]["median"], q["psnr"]) for q in pts])
    log_axis(ax, "x")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_xlabel("time to image (ms, median)")
    ax.set_ylabel(f"PSNR vs Mitsuba {p['ref_spp']:,} spp, depth {p['ref_depth']} (dB)")
    legend_outside(fig, ax, title="spp marked")
    w, h = p["size"]
    fig.suptitle(f"Path integrator, {p['scene']} {w} × {h}")
    save(fig, figures, "pareto_path", quick)
    return "The path integrator's PSNR against time: samples per pixel and depth, with the Pareto front"
