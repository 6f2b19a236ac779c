"""Triangle meshes: tree builds over a million triangles, and primary rays on a
~100,000-triangle teapot through our GPU path, Embree (embreex) and Mitsuba 3.

(a) Build: the scene is a grid of level-5 icospheres (20,480 triangles each; 49 of them:
1,003,520 triangles). Timed: each method's ``prepare`` (the triangles' AABBs, the tree build
over them, its statistics and the packing of its GPU records: what a request pays before the draw),
with the default ``max_prims`` / ``max_tree_depth`` of ``RenderSettings``. BIH and BVH:
median of a few runs, against the targets (BIH ≤ 3 s, BVH ≤ 6 s). The kd-tree and the
two-level method: one run under a deadline; past it they are listed as not measured.

(b) Primary rays: Newell's teapot tessellated to ~100k triangles, flat, no plane. Every engine
traces the same float64 primary rays (``reference.primary_rays``; float32 for the peers):

- ours: bih, bvh (bruteforce is refused past 65,533 triangles: llvmpipe's loop limit), mode
  ``depth`` at recursion 1, no frame-budget prediction (the point budget caps the runs);
  build = the method's ``prepare``, trace = the trace stage (draw + finish);
- Embree through embreex: one ``TriangleMesh`` of the same float32 vertices and indices;
  build = the commit (first query of one ray), embreex's copying of the mesh shown apart;
- Mitsuba 3 (``llvm_ad_rgb``): one ``mesh`` shape made from the same arrays
  (``mi.Mesh`` + ``traverse`` / ``update``), traced with ``ray_intersect_preliminary``;
  build = making the mesh + ``mi.load_dict`` of the scene (its BVH).

Agreement with a float64 reference: the nearest triangle and t of every ray from the CPU BIH
traversal (``bih_traverse.traverse``, the same result as a float64 brute force; checked here
against ``bih_traverse.brute_force`` on a random subset of the rays): the share of rays whose
nearest triangle id equals the reference's (a miss counts as id −1), and max |Δt| where they agree.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import time
from pathlib import Path

import numpy as np

from renderer.accel.bih import build_for_scene as bih_build
from renderer.accel.bih_traverse import brute_force, traverse
from renderer.config.methods import METHODS
from renderer.geometry.meshes import icosphere, teapot
from renderer.geometry.scene import Camera, Light, Mesh, Scene
from renderer.limits import MAX_LOOP_PRIMITIVES
from renderer.oracle.reference import primary_rays
from renderer.scenes.scenarios import RED

from .context import Context, RunInfo
from .markdown import md_table
from .peers import MITSUBA_VARIANT, Result, _warm_mitsuba, available, ours_settings, versions
from .scenes import default_settings
from .style import image_line, plt, save
from .timing import Stat, measure as time_it

NAME = "meshes"
TITLE = "Triangle meshes — a million-triangle build, and primary rays beside Embree and Mitsuba 3"

BUILD_COPIES, BUILD_COPIES_QUICK = 49, 1  # level-5 icospheres: 1,003,520 triangles (quick: 20,480)
BUILD_LEVEL, BUILD_LEVEL_QUICK = 5, 4
TARGETS_S = {"bih": 3.0, "bvh": 6.0}
OTHER_BUILDS = ("kdtree", "twolevel")
OTHER_DEADLINE_S = 60.0
TEAPOT_SEGMENTS, TEAPOT_SEGMENTS_QUICK = 40, 6  # 32 patches × n² × 2 triangles (+ caps)
SIZE, SIZE_QUICK = (640, 1088), (64, 108)
OURS = ("bih", "bvh", "bruteforce")
BF_LOOP_LIMIT = MAX_LOOP_PRIMITIVES  # brute force refuses more (renderer/limits.py: llvmpipe's loop limiter)
CHECK_RAYS = 4096


class Deadline(Exception):
    pass


@contextlib.contextmanager
def deadline(seconds: float):
    def on_alarm(signum, frame):
        raise Deadline(f"still running after {seconds:g} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def _scene(meshes, camera: Camera) -> Scene:
    return Scene(
        camera,
        (Light((40.0, 60.0, 80.0), (1.0, 1.0, 1.0)),),
        (RED,),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        (),
        tuple(meshes),
    )


def icosphere_grid(copies: int, level: int) -> Scene:
    """``copies`` unit icospheres of ``level`` on a square grid, spacing 2.5 (no overlap)."""
    one = icosphere(level, smooth=False)
    k = math.ceil(math.sqrt(copies))
    offsets = [(2.5 * (i % k), 2.5 * (i // k), 0.0) for i in range(copies)]
    meshes = [Mesh(one.vertices + np.asarray(o), one.triangles, 0) for o in offsets]
    c = 1.25 * (k - 1)
    return _scene(meshes, Camera((c, c, 4.0 * k), (c, c, 0.0), (0.0, 1.0, 0.0), 40.0))


def teapot_scene(segments: int) -> Scene:
    m = teapot(segments, smooth=False)
    lo, hi = m.vertices.min(axis=0), m.vertices.max(axis=0)
    c, ext = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    return _scene([m], Camera(tuple(c + (0.0, 0.35 * ext, 1.6 * ext)), tuple(c), (0.0, 1.0, 0.0), 40.0))


# --------------------------------------------------------------------------- (a) builds


def builds(ctx: Context) -> tuple[dict, int]:
    copies, level = (BUILD_COPIES_QUICK, BUILD_LEVEL_QUICK) if ctx.quick else (BUILD_COPIES, BUILD_LEVEL)
    scene = icosphere_grid(copies, level)
    scene.triangle_corners  # noqa: B018 — flattened once, not part of any build
    st = default_settings()
    width = ctx.renderer.max_texture_width
    runs = 1 if ctx.quick else max(1, min(ctx.runs, 3))
    out: dict[str, dict] = {}
    for m in ("bih", "bvh"):
        prep = lambda m=m: METHODS[m].prepare(scene, st.max_prims, st.max_tree_depth, width)
        s, _ = time_it(prep, runs, warmup=0)
        out[m] = {"build": s, "target_s": TARGETS_S[m], "runs": runs}
    for m in OTHER_BUILDS:
        if ctx.quick:
            out[m] = {"skipped": "not measured in quick mode"}
            continue
        try:
            t0 = time.perf_counter()
            with deadline(OTHER_DEADLINE_S):
                METHODS[m].prepare(scene, st.max_prims, st.max_tree_depth, width)
            out[m] = {"build": Stat([(time.perf_counter() - t0) * 1e3]), "runs": 1}
        except Deadline as e:
            out[m] = {"skipped": f"not measured: its build was {e} (one attempt, stopped)"}
    return out, scene.n_triangles


# --------------------------------------------------------------------------- (b) primary rays


def reference_hits(scene: Scene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """float64 nearest triangle index (−1: miss) and t per ray, and a check of it."""
    corners = scene.triangle_corners
    none_c, none_r = np.zeros((0, 3)), np.zeros(0)
    tr = traverse(bih_build(scene, 8), none_c, none_r, o, d, triangles=corners)
    ids = np.asarray(tr.prim, dtype=np.int64)
    t = np.where(ids >= 0, np.asarray(tr.t, dtype=np.float64), np.inf)
    rng = np.random.default_rng(0)
    pick = rng.choice(len(o), size=min(CHECK_RAYS, len(o)), replace=False)
    bt, bp = brute_force(none_c, none_r, o[pick], d[pick], triangles=corners)
    bp = np.asarray(bp, dtype=np.int64)
    check = {
        "rays": len(pick),
        "ids_differ": int(np.sum(bp != ids[pick])),
        "t_differ": int(np.sum((bp >= 0) & (np.asarray(bt) != t[pick]))),
    }
    return ids, t, check


def run_ours(ctx: Context, scene: Scene, st) -> Result:
    tm = ctx.time_render(scene, st)
    res = tm.result
    base = scene.triangle_id_base
    pid = res.primid.reshape(-1).astype(np.int64)
    tri = pid >= base
    depth = res.depth.reshape(-1).astype(np.float64)
    return Result(tm.stages["build"], tm.stages["trace"], np.where(tri, depth, np.inf), np.where(tri, pid - base, -1))


def run_embree(v32: np.ndarray, f32: np.ndarray, o: np.ndarray, d: np.ndarray, runs: int) -> Result:
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    o32, d32 = np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)
    holder: dict = {"mesh_ms": []}

    def build():
        t0 = time.perf_counter()
        sc = rtcs.EmbreeScene()
        TriangleMesh(sc, v32, f32)
        holder["mesh_ms"].append((time.perf_counter() - t0) * 1e3)
        t1 = time.perf_counter()
        sc.run(o32[:1], d32[:1])  # the first query commits the scene (Embree's BVH build)
        holder["scene"] = sc
        return (time.perf_counter() - t1) * 1e3

    b = Stat([build() for _ in range(max(1, runs))])
    sc = holder["scene"]
    tr, res = time_it(lambda: sc.run(o32, d32, output=1), runs, warmup=1)
    prim = np.asarray(res["primID"]).astype(np.int64)
    t = np.asarray(res["tfar"], dtype=np.float64)
    hit = (prim >= 0) & np.isfinite(t) & (t < 1e30)
    return Result(
        b,
        tr,
        np.where(hit, t, np.inf),
        np.where(hit, prim, -1),
        note=f"build = commit; mesh copy-in {Stat(holder['mesh_ms']).median:,.0f} ms not counted",
    )


def run_mitsuba(v32: np.ndarray, f32: np.ndarray, o: np.ndarray, d: np.ndarray, runs: int) -> Result:
    import drjit as dr
    import mitsuba as mi

    _warm_mitsuba()
    holder = {}

    def build():
        mesh = mi.Mesh(
            "teapot", vertex_count=len(v32), face_count=len(f32), has_vertex_normals=False, has_vertex_texcoords=False
        )
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(np.ascontiguousarray(v32).ravel())
        params["faces"] = mi.UInt32(np.ascontiguousarray(f32, dtype=np.uint32).ravel())
        params.update()
        holder["scene"] = mi.load_dict({"type": "scene", "m": mesh})

    b, _ = time_it(build, runs, warmup=0)
    scene = holder["scene"]
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    ray = mi.Ray3f(
        mi.Point3f(*(mi.Float(o32[:, k]) for k in range(3))), mi.Vector3f(*(mi.Float(d32[:, k]) for k in range(3)))
    )
    dr.eval(ray)

    def trace():
        pi = scene.ray_intersect_preliminary(ray)
        dr.eval(pi.t, pi.prim_index)
        dr.sync_thread()
        return pi

    tr, pi = time_it(trace, runs, warmup=1)
    t = np.array(pi.t, dtype=np.float64)
    hit = np.isfinite(t)
    return Result(
        b,
        tr,
        np.where(hit, t, np.inf),
        np.where(hit, np.array(pi.prim_index, dtype=np.int64), -1),
        note="build = mi.Mesh from the arrays + mi.load_dict",
    )


def agreement(res: Result, ref_ids: np.ndarray, ref_t: np.ndarray) -> dict:
    same = res.ids == ref_ids
    both = same & (ref_ids >= 0)
    dt = np.abs(res.t[both] - ref_t[both])
    return {
        "agree_pct": 100.0 * float(same.mean()),
        "differ": int((~same).sum()),
        "max_dt": float(dt.max()) if both.any() else math.nan,
        "max_rel_dt": float((dt / ref_t[both]).max()) if both.any() else math.nan,
    }


def primary(ctx: Context) -> dict:
    segments = TEAPOT_SEGMENTS_QUICK if ctx.quick else TEAPOT_SEGMENTS
    w, h = SIZE_QUICK if ctx.quick else SIZE
    runs = ctx.runs
    scene = teapot_scene(segments)
    mesh = scene.meshes[0]
    o, d = primary_rays(scene.camera, w, h)
    t0 = time.perf_counter()
    ref_ids, ref_t, check = reference_hits(scene, o, d)
    check["ms"] = (time.perf_counter() - t0) * 1e3
    v32 = np.ascontiguousarray(mesh.vertices, np.float32)
    f32 = np.ascontiguousarray(mesh.triangles, np.int32)
    why = available()
    rows: dict[str, dict] = {}
    skipped: list[str] = []
    for m in OURS:
        eng = f"ours: {m}"
        st = ours_settings(m, w, h)
        if m == "bruteforce" and scene.n_triangles > BF_LOOP_LIMIT:
            skipped.append(
                f"{eng}: {scene.n_triangles:,} triangles, but on llvmpipe its loop never reaches a "
                f"triangle past id {BF_LOOP_LIMIT - 1:,}, so it refuses more than {BF_LOOP_LIMIT:,} "
                "primitives (renderer/limits.py, MAX_LOOP_PRIMITIVES)"
            )
            continue
        # bih and bvh are what this table is for: no frame-budget prediction (from a frame at
        # 1/8 × 1/8 it scales the fixed per-draw cost by 64 and refused the BIH at 8 s); their
        # runs are capped by the point budget instead
        rows[eng] = {"res": run_ours(ctx, scene, st)}
    for eng, key, fn in (("Embree (embreex)", "embreex", run_embree), ("Mitsuba 3", "mitsuba", run_mitsuba)):
        if why.get(key):
            skipped.append(f"{eng}: {why[key]}")
            continue
        try:
            rows[eng] = {"res": fn(v32, f32, o, d, runs)}
        except Exception as e:  # a peer failing must not end the section
            skipped.append(f"{eng}: {type(e).__name__}: {e}")
    out = {}
    for eng, v in rows.items():
        res = v["res"]
        out[eng] = {
            "build": res.build,
            "trace": res.trace,
            "mrays": w * h / (res.trace.median / 1e3) / 1e6,
            "note": res.note,
            **agreement(res, ref_ids, ref_t),
        }
    return {
        "size": [w, h],
        "triangles": scene.n_triangles,
        "segments": segments,
        "rows": out,
        "skipped": skipped + ctx.take_skipped(),
        "reference_check": check,
        "ref_hit_pct": 100.0 * float((ref_ids >= 0).mean()),
    }


# --------------------------------------------------------------------------- section


def measure(ctx: Context) -> dict:
    b, n_build = builds(ctx)
    p = primary(ctx)
    return {
        "build": {"triangles": n_build, "methods": b},
        "primary": p,
        "versions": versions(),
        "drjit_threads": os.environ.get("DRJIT_NUM_THREADS", "default"),
    }


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    n_build, p = data["build"]["triangles"], data["primary"]
    b = {
        m: {**v, **({"build": Stat.from_json(v["build"])} if "build" in v else {})}
        for m, v in data["build"]["methods"].items()
    }
    for v in p["rows"].values():
        v["build"], v["trace"] = Stat.from_json(v["build"]), Stat.from_json(v["trace"])
    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(k, v) for k, v in charts.items())

    brows = []
    for m in ("bih", "bvh", *OTHER_BUILDS):
        v = b[m]
        if "skipped" in v:
            brows.append([m, "—", "—", v["skipped"]])
            continue
        s = v["build"].median / 1e3
        target = v.get("target_s")
        verdict = (("✓ meets" if s <= target else "✗ misses") + f" ≤ {target:g} s") if target else "no target"
        brows.append([m, f"{s:.2f}", v["runs"], verdict])
    btable = md_table(["method", "build s (median)", "runs", "target"], brows, "lrrl")

    w, h = p["size"]
    ours_ref = {m: p["rows"].get(f"ours: {m}") for m in OURS}
    trows = []
    for eng, v in p["rows"].items():
        ratios = " · ".join(f"{v['mrays'] / r['mrays']:.2f}× {m}" for m, r in ours_ref.items() if r)
        trows.append(
            [
                eng,
                v["build"].fmt(1),
                v["trace"].fmt(1),
                f"{v['mrays']:.2f}",
                ratios,
                f"{v['agree_pct']:.4f} % ({v['differ']:,} of {w * h:,} rays differ)",
                f"{v['max_dt']:.2e}",
                f"{v['max_rel_dt']:.1e}",
                v["note"],
            ]
        )
    ttable = md_table(
        [
            "engine",
            "build ms",
            "trace ms",
            "Mrays/s",
            "Mrays/s ÷ ours",
            "nearest triangle = reference",
            "max |Δt|",
            "max rel. |Δt|",
            "counted / note",
        ],
        trows,
        "lrrrllrrl",
    )
    skipped = "".join(f"\n- {s}" for s in p["skipped"])
    chk = p["reference_check"]
    vers = ", ".join(f"{k} {v}" for k, v in data["versions"].items()) or "no peers installed"
    size_note = "" if run.quick else f" (the peers section's phone portrait size, {w} × {h}: not reduced)"
    return f"""## {TITLE}

**(a) Build over {n_build:,} triangles** (flat level-{BUILD_LEVEL_QUICK if run.quick else BUILD_LEVEL} \
icospheres of 20 · 4^level triangles on a grid):
the method's `prepare` with the default `max_prims` / `max_tree_depth` — the tree over the
triangles' float32 AABBs, its statistics and the packing of its GPU records; the scene's
flattened corners are made before the clock starts. The kd-tree and the
two-level method get one attempt each under a {OTHER_DEADLINE_S:g} s deadline.

{btable}

{run.caption_cpu(b["bih"]["runs"], "median")}

**(b) Primary rays on Newell's teapot, {p["triangles"]:,} triangles** (flat, {p["segments"]} segments
per patch, no plane; {p["ref_hit_pct"]:.1f} % of the rays hit it) at {w} × {h}{size_note}: the same
rays through our GPU path (mode `depth`, recursion 1), Embree through embreex (one `TriangleMesh`
of the same float32 vertices and indices) and Mitsuba 3 (`{MITSUBA_VARIANT}`, one `mesh` shape from
the same arrays, `ray_intersect_preliminary`), in one run. Versions: {vers}; Dr.Jit threads:
{data["drjit_threads"]}. Build = what each needs before the first ray (column "counted");
trace = the rays only. Agreement: the share of rays whose nearest triangle is the float64
reference's (the CPU BIH traversal of `renderer/accel/bih_traverse.py`; checked against its float64
brute force on {chk["rays"]:,} random rays: {chk["ids_differ"]} id(s) and {chk["t_differ"]} t(s)
differ), and |Δt| over the rays where they agree.

{img}

{ttable}

{run.caption(capped=True)}

Not run:{skipped or " —"}

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``meshes.png``: (a) build seconds per method with the targets, (b) Mrays/s per engine."""
    pyplot = plt()
    fig, (a1, a2) = pyplot.subplots(1, 2, figsize=(11, 4), layout="constrained")
    bm = data["build"]["methods"]
    names = [m for m, v in bm.items() if "build" in v]
    secs = [bm[m]["build"]["median"] / 1e3 for m in names]
    a1.bar(names, secs, color="#4c72b0")
    for i, m in enumerate(names):
        if bm[m].get("target_s"):
            a1.plot(
                [i - 0.4, i + 0.4], [bm[m]["target_s"]] * 2, color="#c44e52", lw=2, label="target" if i == 0 else None
            )
    a1.set_ylabel("build s")
    a1.set_title(f"(a) build over {data['build']['triangles']:,} triangles")
    if any(bm[m].get("target_s") for m in names):
        a1.legend()
    rows = data["primary"]["rows"]
    engs = list(rows)
    a2.bar(
        range(len(engs)),
        [rows[e]["mrays"] for e in engs],
        color=["#4c72b0" if e.startswith("ours") else "#dd8452" for e in engs],
    )
    a2.set_xticks(range(len(engs)), engs, rotation=20, ha="right")
    a2.set_yscale("log")
    w, h = data["primary"]["size"]
    a2.set_ylabel("Mrays/s (primary rays)")
    a2.set_title(f"(b) teapot, {data['primary']['triangles']:,} triangles, {w} × {h}")
    save(fig, figures, "meshes", quick)
    return {"meshes": "build seconds over a million triangles; primary-ray throughput, ours and peers"}
