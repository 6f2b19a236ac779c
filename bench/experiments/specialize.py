"""Model no more than a scene needs: time saved, images unchanged.

Three scenes: a diffuse-only scene (scenario 3, nothing reflects or transmits), a
16-sphere scene (scenario 1, n = 16, Table 4.1 materials) and the thesis's scenario 3
(4,096 spheres of radius 1). Each is rendered at the service's default size and depth
with:

- generic: ``method="bih"``, ``specialize=False`` (one shader for every scene, the full
  recursion depth);
- each switch alone: ``method="auto"`` (brute force below ``AUTO_CROSSOVER_N``),
  ``specialize=True`` (shader variant with only the scene's features, depth clamped to
  what its materials can use);
- both (the defaults).

Images must not change: primid identical and colour PSNR ≥ 50 dB against generic.
"""

from __future__ import annotations

import numpy as np

from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .images import psnr
from .markdown import fmt_db, md_table
from .scenes import default_settings, diffuse_only, has_setting, method_names
from .timing import Stat

NAME = "specialize"
TITLE = "Model no more than the scene needs — time saved, images unchanged"

SIZE = (640, 1088)
SIZE_QUICK = (64, 108)
THESIS_N = 4096
THESIS_N_QUICK = 256
MIN_PSNR = 50.0


def scenes(quick: bool):
    n3 = THESIS_N_QUICK if quick else THESIS_N
    return [
        ("diffuse only (scenario 3, n = 256, kr = kt = 0)", diffuse_only(scenario(3, 256, seed=0, radius=1.0))),
        ("16 spheres (scenario 1, n = 16)", scenario(1, 16, seed=0, radius=1.0)),
        (f"thesis scenario 3 (n = {n3:,})", scenario(3, n3, seed=0, radius=1.0)),
    ]


def variants() -> list[tuple[str, dict | None, str]]:
    """(label, settings overrides or None when unavailable, why unavailable)."""
    has_auto = "auto" in method_names(dispatchers=True)
    has_spec = has_setting("specialize")
    out = [("generic (bih, specialize off)", dict(method="bih", **({"specialize": False} if has_spec else {})), "")]
    out.append(
        (
            "method auto only",
            dict(method="auto", **({"specialize": False} if has_spec else {})) if has_auto else None,
            "no method `auto`",
        )
    )
    out.append(
        ("specialize only", dict(method="bih", specialize=True) if has_spec else None, "no setting `specialize`")
    )
    out.append(
        (
            "both (defaults)",
            dict(method="auto", specialize=True) if has_auto and has_spec else None,
            "needs `auto` and `specialize`",
        )
    )
    return out


def measure(ctx: Context) -> dict:
    w, h = SIZE_QUICK if ctx.quick else SIZE
    base = default_settings().with_(width=w, height=h, mode="color")
    data = {}
    measured = scenes(ctx.quick)
    jobs = [(label, scene, v) for label, scene in measured for v in variants()]
    generic = {}
    for label, scene, (vlabel, over, _why) in ctx.bar(jobs, desc="specialize"):
        if over is None:
            continue
        t = ctx.time_render(scene, base.with_(**over))
        res = t.result
        if vlabel.startswith("generic"):
            generic[label] = (t, res)
        g_t, g_res = generic[label]
        same_ids = bool(np.array_equal(res.primid, g_res.primid))
        p = psnr(g_res.image, res.image)
        ok = same_ids and p >= MIN_PSNR
        speed = g_t.total.median / t.total.median
        data[f"{label}/{vlabel}"] = {
            "timing": t.to_json(),
            "speedup": speed,
            "primid_identical": same_ids,
            "psnr_vs_generic": p,
            "ok": ok,
            "stats": {k: v for k, v in (res.stats or {}).items() if isinstance(v, (int, float, str, bool))},
        }
    return {
        "size": [w, h],
        "scenes": [label for label, _ in measured],
        "max_recursion_depth": base.max_recursion_depth,
        "max_prims": base.max_prims,
        "results": data,
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    base = default_settings()  # older data did not keep the defaults it ran with
    depth, max_prims = data.get("max_recursion_depth", base.max_recursion_depth), data.get("max_prims", base.max_prims)
    results = data["results"]
    labels = data.get("scenes") or list(dict.fromkeys(k.split("/")[0] for k in results))
    rows = []
    all_ok = True
    for label in labels:
        for vlabel, _over, why in variants():
            r = results.get(f"{label}/{vlabel}")
            if r is None:
                rows.append([label, vlabel, "—", "—", "—", "—", "—", f"not available: {why}"])
                continue
            t = r["timing"]
            all_ok &= r["ok"]
            rows.append(
                [
                    label,
                    vlabel,
                    Stat.from_json(t["total"]).fmt(1),
                    f"{t['first_ms']:,.0f}",
                    f"{r['speedup']:.2f}×",
                    "yes" if r["primid_identical"] else "**NO**",
                    fmt_db(r["psnr_vs_generic"]),
                    "✓" if r["ok"] else "**✗**",
                ]
            )
    table = md_table(
        [
            "scene",
            "path",
            "frame ms",
            "first frame ms",
            "speed-up vs generic",
            "primid identical",
            "colour PSNR vs generic (dB)",
            f"unchanged (PSNR ≥ {MIN_PSNR:g})",
        ],
        rows,
        "llrrrcrc",
    )
    path = f"figures/{NAME}.json"
    saved = []
    for label in labels:
        key = f"{label}/both (defaults)"
        if key in results:
            gm = results[f"{label}/generic (bih, specialize off)"]["timing"]["total"]["median"]
            bm = results[key]["timing"]["total"]["median"]
            pct = 100 * (1 - bm / gm)
            saved.append(
                f"{label}: {gm:,.1f} → {bm:,.1f} ms "
                + (f"({pct:.1f} % saved)" if pct >= 0 else f"({-pct:.1f} % slower)")
            )
    saved_txt = (
        "\n".join(f"- {s}" for s in saved) if saved else "- not measured: this build lacks `auto` and/or `specialize`"
    )
    return f"""## {TITLE}

Each switch on its own and all together against the generic path, at {w} × {h}, colour, recursion depth
{depth} (the service's default), `MAX_PRIMS` {max_prims}. "First frame" is the untimed warm-up frame: it
includes compiling the shader variant when this run had not compiled it yet (variants are cached by feature
set); frame ms is the median of the following runs.

{table}

{run.caption(capped=True)}

Time saved by the defaults (both switches) against the generic path:

{saved_txt}

Images unchanged in every measured row (primid identical and PSNR ≥ {MIN_PSNR:g} dB): **{"yes" if all_ok else "NO"}**.

Raw data: [`{path}`]({path}).
"""
