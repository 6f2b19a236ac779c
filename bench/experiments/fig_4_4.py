"""Fig. 4.4: frames per second against n for brute force and the BIH with MAX_PRIMS 1…16.

Primary rays only (recursion depth 1), radius 1, three scenarios, 640 × 1088. A frame
is what the thesis's render loop does per frame: rebuild the BIH, upload, draw, and here
also read the image back; fps = 1000 / median frame time. The trace stage alone is in
the table too.
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path

from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings, method_names
from .style import image_line, legend_outside, log_axis, plt, save, series as line_style

NAME = "fig_4_4"
TITLE = "Fig. 4.4 — frames per second against n, primary rays"

NS = (16, 32, 64, 128, 256)
NS_QUICK = (16, 64)
BIH_MAX_PRIMS = (1, 2, 4, 8, 16)
SIZE = (640, 1088)
SIZE_QUICK = (64, 108)
THESIS_NS = (64, 128, 256)  # the sizes the thesis's "7 out of 9" and speed-ups refer to

# What the thesis states about its Fig. 4.4 (iPhone 5s). Speed-ups are BIH fps / BF fps.
THESIS = {
    "bf_fps_128": 2.14,
    "bf_fps_256": 1.87,
    "max_speedup": (14.95, "scenario 2, 128 spheres, MAX_PRIMS 16"),
    "s2_speedup": (8.59, 12.12, 14.95),  # min (BIH 8, 64 spheres), mean, max
    "s3_speedup": (7.87, None, 10.74),  # min, -, max
    "mp8_best": "7 of 9",
    "best_fps": (60, "BIH 8, scenario 1, 64 spheres (display-capped at 60 fps)"),
}


def series() -> list[tuple[str, str, int]]:
    """(label, method, max_prims) of every series: the BIH once per MAX_PRIMS, other methods once."""
    out = []
    default_mp = default_settings().max_prims
    for m in method_names():
        if m == "bih":
            out += [(f"BIH {mp}", "bih", mp) for mp in BIH_MAX_PRIMS]
        elif m == "bruteforce":
            out.append(("BF", "bruteforce", default_mp))
        else:
            out.append((m, m, default_mp))
    return out


def measure(ctx: Context) -> dict:
    ns = NS_QUICK if ctx.quick else NS
    w, h = SIZE_QUICK if ctx.quick else SIZE
    ser = series()
    base = default_settings().with_(width=w, height=h, mode="color", max_recursion_depth=1)
    data: dict[str, dict] = {}
    jobs = [(sc, n, s) for sc in (1, 2, 3) for n in ns for s in ser]
    scenes = {}
    too_slow: set[tuple[int, str]] = set()
    for sc, n, (label, method, mp) in ctx.bar(jobs, desc="Fig 4.4"):
        scene = scenes.setdefault((sc, n), scenario(sc, n, seed=0, radius=1.0))
        st = base.with_(method=method, max_prims=mp)
        if (sc, label) in too_slow:  # slower still at a larger n
            ctx.skipped.append(f"{label}, scenario {sc}, n = {n:,}: slower than the budget at a smaller n")
            continue
        if not ctx.within_budget(scene, st, f"{label}, scenario {sc}, n = {n:,}"):
            too_slow.add((sc, label))
            continue
        t = ctx.time_render(scene, st)
        data[f"{sc}/{n}/{label}"] = {
            "scenario": sc,
            "n": n,
            "series": label,
            "method": method,
            "max_prims": mp,
            "timing": t.to_json(),
        }
    return {"size": [w, h], "ns": ns, "runs": ctx.runs, "points": data, "gl": ctx.gl, "labels": [s[0] for s in ser]}


def report(saved: dict, run: RunInfo, charts: dict[str, str]) -> str:
    ns, data = saved["ns"], saved["points"]
    # Older data did not keep its series: every series measured, in the order measured.
    labels = saved.get("labels") or list(dict.fromkeys(p["series"] for p in data.values()))
    w, h = saved["size"]
    skipped_md = run.skipped_md()

    def fps(sc, n, label, stage="total"):
        """Frames/s of one point; NaN where it was not measured."""
        if f"{sc}/{n}/{label}" not in data:
            return math.nan
        d = data[f"{sc}/{n}/{label}"]["timing"]
        ms = d["total"]["median"] if stage == "total" else d["stages"]["trace"]["median"]
        return 1000.0 / ms

    def best_of(sc, n, labs):
        """The fastest measured series among ``labs`` at (sc, n), or None."""
        have = [lab for lab in labs if not math.isnan(fps(sc, n, lab))]
        return max(have, key=lambda lab: fps(sc, n, lab)) if have else None

    def cell(x):
        return "—" if math.isnan(x) else f"{x:.2f}"

    bih_labels = [lab for lab in labels if lab.startswith("BIH ")]
    has_bf = "BF" in labels

    # Tables: one per scenario, fps per series (frame), then trace-only fps.
    tables = []
    for sc in (1, 2, 3):
        rows = []
        for n in ns:
            cells = [f"{n:,}"] + [cell(fps(sc, n, lab)) for lab in labels]
            if has_bf:
                best = best_of(sc, n, bih_labels)
                sp = fps(sc, n, best) / fps(sc, n, "BF") if best else math.nan
                cells.append("—" if math.isnan(sp) else f"{sp:.2f}× ({best})")
            rows.append(cells)
        hdr = ["n"] + labels + (["best BIH / BF"] if has_bf else [])
        tables.append(
            f"**Scenario {sc}** — frames/s (whole frame: build + upload + trace + read back)\n\n"
            + md_table(hdr, rows)
            + "\n\n"
            + run.caption(capped=True)
        )
    trace_rows = []
    for sc in (1, 2, 3):
        for n in ns:
            trace_rows.append([str(sc), f"{n:,}"] + [cell(fps(sc, n, lab, "trace")) for lab in labels])
    trace_table = md_table(["scenario", "n"] + labels, trace_rows)

    # Sweet spot: which MAX_PRIMS is fastest how often (all scenarios and n measured).
    wins = {lab: 0 for lab in bih_labels}
    cases = 0
    for sc in (1, 2, 3):
        for n in ns:
            b = best_of(sc, n, bih_labels)
            if b:
                wins[b] += 1
                cases += 1
    # Ties go to the higher geometric-mean frame rate over all cases.
    gmean = {
        lab: statistics.geometric_mean(
            [x for sc in (1, 2, 3) for n in ns if not math.isnan(x := fps(sc, n, lab))] or [1e-9]
        )
        for lab in bih_labels
    }
    sweet = max(bih_labels, key=lambda lab: (wins[lab], gmean[lab]))
    sweet_mp = int(sweet.split()[1])
    run.note(
        f"fig_4_4: MAX_PRIMS sweet spot = {sweet_mp} (fastest in {wins[sweet]} of {cases} "
        f"scenario × n cases) -> RenderSettings.max_prims default"
    )

    # Thesis comparison (only with the sizes the thesis used, where we measured them).
    th_ns = [n for n in THESIS_NS if n in ns]
    comp = []
    if has_bf:
        for n in (128, 256):
            if n in ns:
                ours = statistics.mean(fps(sc, n, "BF") for sc in (1, 2, 3))
                if not math.isnan(ours):
                    comp.append(
                        [
                            f"BF frames/s at n = {n} (mean of the 3 scenarios)",
                            f"{THESIS[f'bf_fps_{n}']:.2f}",
                            f"{ours:.2f}",
                        ]
                    )
        sp = {
            (sc, n, lab): fps(sc, n, lab) / fps(sc, n, "BF")
            for sc in (1, 2, 3)
            for n in ns
            for lab in bih_labels
            if not math.isnan(fps(sc, n, lab) / fps(sc, n, "BF"))
        }
        best = max((k for k in sp if k[1] in th_ns), key=sp.get, default=None)
        if best:
            comp.append(
                [
                    "largest BIH / BF speed-up (n ∈ 64, 128, 256)",
                    f"{THESIS['max_speedup'][0]:.2f}× ({THESIS['max_speedup'][1]})",
                    f"{sp[best]:.2f}× (scenario {best[0]}, {best[1]} spheres, MAX_PRIMS {best[2].split()[1]})",
                ]
            )
        for sc, key in ((2, "s2_speedup"), (3, "s3_speedup")):
            per_n = [
                max(v for (s2, n2, _), v in sp.items() if (s2, n2) == (sc, n))
                for n in th_ns
                if any((s2, n2) == (sc, n) for (s2, n2, _) in sp)
            ]
            if per_n:
                th = THESIS[key]
                th_txt = f"{th[0]:.2f}× / " + (f"{th[1]:.2f}×" if th[1] else "—") + f" / {th[2]:.2f}×"
                comp.append(
                    [
                        f"scenario {sc}: best-BIH speed-up, min / mean / max over n ∈ {', '.join(map(str, th_ns))}",
                        th_txt,
                        f"{min(per_n):.2f}× / {statistics.mean(per_n):.2f}× / {max(per_n):.2f}×",
                    ]
                )
    if th_ns:
        mp8 = sum(best_of(sc, n, bih_labels) == "BIH 8" for sc in (1, 2, 3) for n in th_ns)
        comp.append(
            [
                f"MAX_PRIMS 8 fastest (scenario × n ∈ {', '.join(map(str, th_ns))})",
                THESIS["mp8_best"],
                f"{mp8} of {3 * len(th_ns)}",
            ]
        )
    top = max(
        ((sc, n, lab) for sc in (1, 2, 3) for n in ns for lab in labels if not math.isnan(fps(sc, n, lab))),
        key=lambda k: fps(*k),
    )
    comp.append(
        [
            "fastest configuration",
            f"{THESIS['best_fps'][0]} fps ({THESIS['best_fps'][1]})",
            f"{fps(*top):.1f} fps ({top[2]}, scenario {top[0]}, {top[1]} spheres)",
        ]
    )
    comp_table = md_table(["", "thesis (iPhone 5s)", "ours"], comp, "lll")

    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(k, v) for k, v in charts.items())

    return f"""## {TITLE}

Frames per second at {w} × {h}, primary rays only (`max_recursion_depth` 1), spheres of radius 1,
every method in `renderer.config.methods.METHODS` (the BIH with `MAX_PRIMS` 1, 2, 4, 8, 16). A frame is
what the thesis's render loop does: rebuild the BIH, upload, draw; we also read the image back.

{img}

{chr(10).join(t + chr(10) for t in tables)}
Trace stage only (draw + finish, no build/upload/read), frames/s:

{trace_table}

{run.caption(capped=True)}

{skipped_md}
**MAX_PRIMS sweet spot:** {sweet} is fastest in {wins[sweet]} of {cases} scenario × n cases
({", ".join(f"{k}: {v}" for k, v in wins.items())}).

**Thesis against ours** (the thesis quotes these numbers in its text; its chart is not reproduced):

{comp_table}

{run.caption(capped=True)} (Thesis column: iPhone 5s, as quoted.)

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``fig_4_4_fps.png`` from ``fig_4_4.json``: frames/s against n per scenario; a method's
    colour and marker as in every chart (the BIH's MAX_PRIMS as line styles), legend outside."""
    pyplot = plt()
    w, h = data["size"]
    ns = data["ns"]
    points = data["points"]
    labels = data.get("labels") or list(dict.fromkeys(p["series"] for p in points.values()))
    method = {p["series"]: p["method"] for p in points.values()}

    def fps(sc: int, n: int, label: str) -> float:
        p = points.get(f"{sc}/{n}/{label}")
        return math.nan if p is None else 1000.0 / p["timing"]["total"]["median"]

    bih = [lab for lab in labels if method.get(lab) == "bih"]
    fig, axes = pyplot.subplots(1, 3, figsize=(15, 4.6), sharey=True, layout="constrained")
    for j, sc in enumerate((1, 2, 3)):
        ax = axes[j]
        for lab in labels:
            xs = [n for n in ns if not math.isnan(fps(sc, n, lab))]
            if xs:
                variant = bih.index(lab) if lab in bih else 0
                ax.plot(
                    xs,
                    [fps(sc, n, lab) for n in xs],
                    **line_style(
                        lab, method=method.get(lab), variant=variant, lw=2.2 if method.get(lab) == "bruteforce" else 1.5
                    ),
                )
        if "BF" in labels:
            ax.plot(
                [128, 256],
                [THESIS["bf_fps_128"], THESIS["bf_fps_256"]],
                ls="none",
                **{k: v for k, v in line_style("thesis BF (iPhone 5s)", method="thesis").items() if k != "ls"},
                mew=2,
            )
        ax.set_xscale("log", base=2)
        log_axis(ax, "y")
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.set_title(f"scenario {sc}")
        ax.set_xlabel("spheres n")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("frames / s")
    legend_outside(fig, axes, title="method (BIH: MAX_PRIMS)")
    gl = data.get("gl")
    fig.suptitle(f"Fig. 4.4 reproduced: {w} × {h}, primary rays only" + (f" ({gl.split(',')[0]})" if gl else ""))
    save(fig, figures, "fig_4_4_fps", quick)
    return {"fig_4_4_fps": "Frames per second against n, per scenario and method"}
