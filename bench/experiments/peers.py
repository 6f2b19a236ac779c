"""Peers side by side: the same scenes' primary rays through Mitsuba 3 and Embree (embreex).

Optional: needs the ``peers`` dependency group (``pip install -e .[peers]``: mitsuba,
embreex). Without it the section says so and the run goes on.

Every engine traces the same primary rays (``reference.primary_rays``, float64, cast to
float32 for the peers) against the spheres only (the plane is not part of this race):

- ours: every method of ``METHODS`` on the GPU path, mode ``depth`` at recursion depth 1;
  rays/s from the trace stage (draw + finish), build = the method's ``prepare``;
- Mitsuba 3, variant ``llvm_ad_rgb``: one ``sphere`` shape per sphere, and one
  ``ellipsoids`` shape holding every sphere (scale = radius, ``extent`` 1), traced with
  ``Scene.ray_intersect_preliminary``; build = ``mi.load_dict``;
- Embree 4 through embreex: each sphere as an icosphere (vertices on the sphere),
  ``EmbreeScene.run``; build = the commit (first query of one ray); embreex's copying of
  the mesh into Embree is reported beside it, not counted.

Accuracy against a float64 reference (``bih_traverse.traverse``, checked against
``render_reference`` at the smallest n): the share
of pixels whose nearest sphere differs (a hit on the plane or a miss count as "no
sphere"), and |t − t_ref| over the pixels where the engine hit the reference's sphere.
"""

from __future__ import annotations

import importlib
import math
import os
import time
from pathlib import Path

import numpy as np

from renderer import meshes
from renderer.accel.bih import build_for_spheres
from renderer.accel.bih_traverse import traverse
from renderer.reference import primary_rays, render_reference
from renderer.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings, method_names
from .style import image_line, legend_outside, plt, save, series
from .timing import Stat, measure as time_it

NAME = "peers"
TITLE = "Peers — Mitsuba 3 and Embree beside our tracers"

NS = tuple(64 * 4**k for k in range(6))  # 64 … 65,536
NS_QUICK = (64, 256)
SCENARIOS = (1, 2, 3)
SCENARIOS_QUICK = (2,)
SIZE = (640, 1088)
SIZE_QUICK = (64, 108)
ICO_LEVEL = 2  # 320 triangles per sphere …
ICO_MAX_TRIANGLES = 8 << 20  # … unless the scene would exceed this; then one level fewer
MITSUBA_VARIANT = "llvm_ad_rgb"
INSTALL_HINT = "peers not installed: pip install -e .[peers]"


# --------------------------------------------------------------------------- availability


def available() -> dict[str, str | None]:
    """{'mitsuba': None or why not, 'embreex': None or why not}."""
    why: dict[str, str | None] = {}
    try:
        mi = importlib.import_module("mitsuba")
        try:
            mi.set_variant(MITSUBA_VARIANT)
            why["mitsuba"] = None
        except Exception as e:  # e.g. no libLLVM: set DRJIT_LIBLLVM_PATH
            why["mitsuba"] = (
                f"mitsuba {getattr(mi, '__version__', '?')} is installed but variant "
                f"{MITSUBA_VARIANT} failed: {e}. Install a libLLVM (Debian: libllvm19) and "
                "point DRJIT_LIBLLVM_PATH at it."
            )
    except ImportError as e:
        why["mitsuba"] = f"not importable ({e})"
    try:
        importlib.import_module("embreex.rtcore_scene")
        why["embreex"] = None
    except ImportError as e:
        why["embreex"] = f"not importable ({e})"
    return why


def versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for p in ("mitsuba", "drjit", "embreex"):
        try:
            out[p] = version(p)
        except PackageNotFoundError:
            pass
    return out


# --------------------------------------------------------------------------- geometry


def icosphere(level: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit icosphere: vertices (V, 3) on the sphere, faces (F, 3); F = 20 · 4^level (the scene
    module's, so the peers trace the very triangles our meshes would)."""
    mesh = meshes.icosphere(level, smooth=False)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.triangles, dtype=np.int64)


# --------------------------------------------------------------------------- engines


class Result:
    def __init__(self, build: Stat, trace: Stat, t: np.ndarray, ids: np.ndarray, note: str = ""):
        self.build, self.trace, self.t, self.ids, self.note = build, trace, t, ids, note


_MITSUBA_WARM = False


def _warm_mitsuba() -> None:
    """Load each plugin once (a one-sphere scene of each kind), so no build pays for plugin loading."""
    global _MITSUBA_WARM
    if _MITSUBA_WARM:
        return
    import mitsuba as mi

    mi.set_variant(MITSUBA_VARIANT)
    mi.load_dict({"type": "scene", "s": {"type": "sphere", "center": [0, 0, 0], "radius": 1.0}})
    one = lambda *v: mi.TensorXf(np.array([v], dtype=np.float32))
    mi.load_dict(
        {
            "type": "scene",
            "e": {
                "type": "ellipsoids",
                "centers": one(0, 0, 0),
                "scales": one(1, 1, 1),
                "quaternions": one(0, 0, 0, 1),
                "extent": 1.0,
            },
        }
    )
    _MITSUBA_WARM = True


def run_mitsuba(kind: str, centers, radii, o, d, runs: int, budget_s: float | None = 30.0) -> Result:
    import drjit as dr
    import mitsuba as mi

    _warm_mitsuba()
    n = len(centers)
    if kind == "spheres":
        width = len(str(max(n - 1, 0)))
        desc = {"type": "scene"}
        for i in range(n):
            desc[f"s{i:0{width}d}"] = {"type": "sphere", "center": centers[i].tolist(), "radius": float(radii[i])}
    else:
        f32 = lambda a: mi.TensorXf(np.ascontiguousarray(a, dtype=np.float32))
        desc = {
            "type": "scene",
            "e": {
                "type": "ellipsoids",
                "centers": f32(centers),
                "scales": f32(np.repeat(radii[:, None], 3, 1)),
                "quaternions": f32(np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))),
                "extent": 1.0,
            },
        }
    holder = {}

    def build():
        holder["scene"] = mi.load_dict(desc)

    b, _ = time_it(build, runs, warmup=0, budget_s=budget_s)
    scene = holder["scene"]
    if kind == "spheres":
        index_of_shape = np.array([int(s.id()[1:]) for s in scene.shapes()], dtype=np.int64)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(o32[:, k]) for k in range(3))), mi.Vector3f(*(mi.Float(d32[:, k]) for k in range(3)))
    )
    dr.eval(ray)

    def trace():
        pi = scene.ray_intersect_preliminary(ray)
        dr.eval(pi.t, pi.prim_index, pi.shape_index)
        dr.sync_thread()
        return pi

    tr, pi = time_it(trace, runs, warmup=1)
    t = np.array(pi.t, dtype=np.float64)
    hit = np.isfinite(t)
    if kind == "spheres":
        ids = np.where(
            hit, index_of_shape[np.minimum(np.array(pi.shape_index, dtype=np.int64), len(index_of_shape) - 1)], -1
        )
    else:
        ids = np.where(hit, np.array(pi.prim_index, dtype=np.int64), -1)
    return Result(b, tr, np.where(hit, t, np.inf), ids)


def run_embree(centers, radii, o, d, runs: int, budget_s: float | None = 30.0) -> Result:
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    n = len(centers)
    level = ICO_LEVEL
    while level > 0 and n * 20 * 4**level > ICO_MAX_TRIANGLES:
        level -= 1
    uv, uf = icosphere(level)
    verts = (centers[:, None, :] + radii[:, None, None] * uv[None]).reshape(-1, 3).astype(np.float32)
    faces = (uf[None] + len(uv) * np.arange(n)[:, None, None]).reshape(-1, 3).astype(np.int32)
    per = len(uf)
    o32, d32 = np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)
    holder: dict = {"mesh_ms": []}

    def build():
        # Timed: the commit (Embree's BVH build). Not timed: embreex copying the mesh in.
        t0 = time.perf_counter()
        sc = rtcs.EmbreeScene()
        TriangleMesh(sc, verts, faces)
        holder["mesh_ms"].append((time.perf_counter() - t0) * 1e3)
        t1 = time.perf_counter()
        sc.run(o32[:1], d32[:1])  # the first query commits the scene
        holder["scene"] = sc
        return (time.perf_counter() - t1) * 1e3

    samples = []
    spent = 0.0
    for _ in range(max(1, runs)):
        t0 = time.perf_counter()
        samples.append(build())
        spent += time.perf_counter() - t0
        if budget_s is not None and spent > budget_s:
            break
    b = Stat(samples)
    sc = holder["scene"]
    tr, res = time_it(lambda: sc.run(o32, d32, output=1), runs, warmup=1)
    prim = np.asarray(res["primID"]).astype(np.int64)
    t = np.asarray(res["tfar"], dtype=np.float64)
    hit = (prim >= 0) & np.isfinite(t) & (t < 1e30)
    ids = np.where(hit, prim // per, -1)
    mesh = Stat(holder["mesh_ms"]).median
    return Result(
        b,
        tr,
        np.where(hit, t, np.inf),
        ids,
        note=f"{per} triangles per sphere; build = commit, mesh copy-in {mesh:,.0f} ms not counted",
    )


def ours_settings(method: str, w: int, h: int):
    return default_settings().with_(width=w, height=h, mode="depth", max_recursion_depth=1, method=method)


def run_ours(ctx: Context, scene, st) -> Result:
    t = ctx.time_render(scene, st)
    res = t.result
    n = scene.n_spheres
    ids = res.primid.reshape(-1).astype(np.int64)
    sphere = (ids >= 0) & (ids < n)
    depth = res.depth.reshape(-1).astype(np.float64)
    return Result(t.stages["build"], t.stages["trace"], np.where(sphere, depth, np.inf), np.where(sphere, ids, -1))


def reference_hits(scene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest sphere and its t per ray in float64: the CPU BIH traversal of ``bih_traverse``.

    It returns bit for bit what a float64 brute force returns (its docstring and
    tests/test_bih.py), and is fast enough for 65,536 spheres × 700k rays; it is checked
    against ``render_reference`` at the smallest n of every scenario (see the table).
    """
    bih = build_for_spheres(scene.sphere_centers, scene.sphere_radii, 8)
    tr = traverse(bih, scene.sphere_centers, scene.sphere_radii, o, d)
    ids = np.asarray(tr.prim, dtype=np.int64)
    return ids, np.where(ids >= 0, np.asarray(tr.t, dtype=np.float64), np.inf)


def check_reference(scene, w: int, h: int, ref_ids: np.ndarray, ref_t: np.ndarray) -> dict:
    """Compare the CPU traversal with ``render_reference`` (mode depth): ids and max |Δt|."""
    ref = render_reference(
        scene, default_settings().with_(width=w, height=h, mode="depth", max_recursion_depth=1, method="bruteforce")
    )
    n = scene.n_spheres
    ids = ref.primid.reshape(-1).astype(np.int64)
    ids = np.where(ids < n, ids, -1)
    same = (ids == ref_ids) & (ids >= 0)
    # render_reference returns depth as float32: compare at that precision.
    dt = np.abs(ref.depth.reshape(-1).astype(np.float64)[same] - ref_t[same])
    return {
        "n": n,
        "ids_differ": int(np.sum(ids != ref_ids)),
        "max_rel_dt": float((dt / ref_t[same]).max()) if same.any() else 0.0,
    }


def errors(res: Result, ref_ids: np.ndarray, ref_t: np.ndarray) -> dict[str, float]:
    mismatch = float(np.mean(res.ids != ref_ids)) * 100.0
    same = (res.ids == ref_ids) & (ref_ids >= 0)
    if same.any():
        dt = np.abs(res.t[same] - ref_t[same])
        return {
            "mismatch_pct": mismatch,
            "max_dt": float(dt.max()),
            "median_dt": float(np.median(dt)),
            "max_rel_dt": float((dt / ref_t[same]).max()),
        }
    return {"mismatch_pct": mismatch, "max_dt": math.nan, "median_dt": math.nan, "max_rel_dt": math.nan}


# --------------------------------------------------------------------------- experiment


def measure(ctx: Context) -> dict:
    why = available()
    ok = [k for k, v in why.items() if v is None]
    if not ok:
        ctx.log(INSTALL_HINT)
        return {"unavailable": why}
    ns = NS_QUICK if ctx.quick else NS
    scs = SCENARIOS_QUICK if ctx.quick else SCENARIOS
    w, h = SIZE_QUICK if ctx.quick else SIZE
    runs = ctx.runs
    ours = method_names()
    engines = [f"ours: {m}" for m in ours]
    if "mitsuba" in ok:
        engines += ["Mitsuba 3: sphere shapes", "Mitsuba 3: ellipsoids"]
    if "embreex" in ok:
        engines += ["Embree: icospheres"]
    rows: dict[tuple[int, int, str], dict] = {}
    ref_check: dict[int, dict] = {}
    skipped: list[str] = []
    too_slow: set[tuple[str, int]] = set()
    jobs = [(sc, n) for sc in scs for n in ns]
    bar = ctx.bar(total=len(jobs) * (len(engines) + 1), desc="peers")
    for sc, n in jobs:
        scene = scenario(sc, n, seed=0, radius=1.0)
        o, d = primary_rays(scene.camera, w, h)
        ref_ids, ref_t = reference_hits(scene, o, d)
        if n == ns[0]:
            ref_check[sc] = check_reference(scene, w, h, ref_ids, ref_t)
        bar.update(1)
        c, r = scene.sphere_centers, scene.sphere_radii
        for eng in engines:
            try:
                if eng.startswith("ours: "):
                    m = eng[6:]
                    st = ours_settings(m, w, h)
                    if (m, sc) in too_slow:
                        ctx.skipped.append(f"{eng}, scenario {sc}, n = {n:,}: over the budget at a smaller n")
                        continue
                    if not ctx.within_budget(scene, st, f"{eng}, scenario {sc}, n = {n:,}"):
                        too_slow.add((m, sc))
                        continue
                    res = run_ours(ctx, scene, st)
                elif eng == "Mitsuba 3: sphere shapes":
                    res = run_mitsuba("spheres", c, r, o, d, runs, ctx.point_budget_s)
                elif eng == "Mitsuba 3: ellipsoids":
                    res = run_mitsuba("ellipsoids", c, r, o, d, runs, ctx.point_budget_s)
                else:
                    res = run_embree(c, r, o, d, runs, ctx.point_budget_s)
            except Exception as e:  # a peer failing at one size must not end the section
                skipped.append(f"{eng}, scenario {sc}, n = {n:,}: {type(e).__name__}: {e}")
                continue
            finally:
                bar.update(1)
            err = errors(res, ref_ids, ref_t)
            rows[(sc, n, eng)] = {
                "build": res.build,
                "trace": res.trace,
                "mrays": w * h / (res.trace.median / 1e3) / 1e6,
                "note": res.note,
                **err,
            }
    bar.close()

    return {
        "size": [w, h],
        "ns": ns,
        "scenarios": scs,
        "versions": versions(),
        "rows": {f"{sc}/{n}/{eng}": v for (sc, n, eng), v in rows.items()},
        "skipped": skipped,
        "reference_check": ref_check,
        "unavailable": {k: v for k, v in why.items() if v},
        "drjit_threads": os.environ.get("DRJIT_NUM_THREADS", "default"),
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    if "rows" not in data:
        lines = "\n".join(f"- `{k}`: {v}" for k, v in data["unavailable"].items())
        return f"""## {TITLE}

**{INSTALL_HINT}** — the peers are an optional dependency group; this section was skipped.

{lines}
"""
    w, h = data["size"]
    scs, skipped, ref_check = data["scenarios"], data["skipped"], data["reference_check"]
    rows = {}
    for key, v in data["rows"].items():  # in the order measured: scenario, n, engine
        sc, n, eng = key.split("/", 2)
        rows[(int(sc), int(n), eng)] = {**v, "build": Stat.from_json(v["build"]), "trace": Stat.from_json(v["trace"])}
    tables = []
    for sc in scs:
        trs = []
        for (sc2, n, eng), v in rows.items():
            if sc2 != sc:
                continue
            trs.append(
                [
                    f"{n:,}",
                    eng + (f" ({v['note']})" if v["note"] else ""),
                    v["build"].fmt(1),
                    v["trace"].fmt(1),
                    f"{v['mrays']:.2f}",
                    f"{v['mismatch_pct']:.3f} %",
                    f"{v['max_dt']:.2e}",
                    f"{v['median_dt']:.2e}",
                ]
            )
        tables.append(
            f"**Scenario {sc}**\n\n"
            + md_table(
                [
                    "n",
                    "engine",
                    "build ms",
                    "trace ms",
                    "Mrays/s",
                    "nearest sphere ≠ reference",
                    "max |Δt|",
                    "median |Δt|",
                ],
                trs,
                "rlrrrrrr",
            )
            + "\n\n"
            + run.caption(capped=True)
        )

    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(name, alt) for name, alt in charts.items())
    vers = ", ".join(f"{k} {v}" for k, v in data["versions"].items())
    missing = "".join(f"\n- `{k}` not run: {v}" for k, v in data["unavailable"].items() if v)
    skipped_txt = ("\n\nNot run (errors): " + "; ".join(skipped) + ".") if skipped else ""
    skipped_txt += "\n\n" + run.skipped_md()
    check_txt = "; ".join(
        f"scenario {sc}, n = {v['n']:,}: {v['ids_differ']} ray(s) with a different sphere, "
        f"max relative |Δt| {v['max_rel_dt']:.1e} (float32 output of render_reference)"
        for sc, v in ref_check.items()
    )
    threads = data.get("drjit_threads", "default")
    return f"""## {TITLE}

The same primary rays of the thesis's scenes ({w} × {h}, spheres of radius 1, plane left out),
traced by our GPU path (every method of `METHODS`), by Mitsuba 3 (`{MITSUBA_VARIANT}`; one `sphere`
shape per sphere, and one `ellipsoids` shape holding them all, via `ray_intersect_preliminary`) and
by Embree through embreex (spheres as icospheres: {20 * 4**ICO_LEVEL} triangles each, one level
fewer where a scene would pass {ICO_MAX_TRIANGLES:,} triangles). Versions: {vers}. Dr.Jit threads:
{threads}. Build = what each needs before the first ray (our BIH build; `mi.load_dict`; Embree's
commit — embreex's copying of the mesh is shown apart); trace = the rays only. \
Hit distances are compared with a float64 reference: the CPU
BIH traversal of `renderer/bih_traverse.py` (exact: the same `t` as a float64 brute force), itself
checked against `render_reference` at the smallest n — {check_txt}.{missing}

{img}

{chr(10).join(t + chr(10) for t in tables)}{skipped_txt}

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``peers.png`` from ``peers.json``: Mrays/s, build ms and max |Δt| against n, the median over
    the scenarios per engine; one colour and marker per engine in all three panels."""
    if "rows" not in data:  # the peers were not installed: nothing to draw
        return {}
    pyplot = plt()
    w, h = data["size"]
    ns, scs = data["ns"], data["scenarios"]
    rows = {tuple(k.split("/", 2)): v for k, v in data["rows"].items()}
    engines = list(dict.fromkeys(k[2] for k in rows))

    def med(key: str, n: int, eng: str) -> float:
        vals = [rows[(str(sc), str(n), eng)] for sc in scs if (str(sc), str(n), eng) in rows]
        return float(np.median([v[key]["median"] if isinstance(v[key], dict) else v[key] for v in vals]))

    fig, axes = pyplot.subplots(1, 3, figsize=(16, 4.6), layout="constrained")
    for eng in engines:
        xs = [n for n in ns if any((str(sc), str(n), eng) in rows for sc in scs)]
        if not xs:
            continue
        ours = eng.startswith("ours")
        style = series(eng, ls="-" if ours else "--")
        axes[0].plot(xs, [med("mrays", n, eng) for n in xs], **style)
        bx = [n for n in xs if med("build", n, eng) > 0]  # brute force builds nothing: no line, same colours
        if bx:
            axes[1].plot(bx, [med("build", n, eng) for n in bx], **style)
        axes[2].plot(xs, [max(med("max_dt", n, eng), 1e-9) for n in xs], **style)
    for ax, yl in zip(
        axes,
        ("Mrays/s (primary rays)", "build ms (brute force builds nothing)", "max |t − t_ref| (world units)"),
        strict=True,
    ):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("spheres n")
        ax.set_ylabel(yl)
        ax.grid(True, which="both", alpha=0.3)
    legend_outside(fig, axes, title="engine (solid: ours)")
    fig.suptitle(f"Primary rays at {w} × {h}, median over scenarios {', '.join(map(str, scs))}")
    save(fig, figures, "peers", quick)
    return {"peers": "Mrays/s, build time and hit-distance error against n, ours and peers"}
