"""Peers side by side: the same primary rays through our tracers, Mitsuba 3 and Embree (embreex).

Optional: needs the ``peers`` dependency group (``pip install -e .[peers]``: mitsuba,
embreex). Without it the section says so and the run goes on.

Every engine traces the same primary rays (``reference.primary_rays``, float64, cast to
float32 for the peers) against the same geometry: the scenario's spheres, its floor plane left
out (``without_planes``: the peers are given the spheres only, so ours is too):

- ours: :func:`ours_engines`, a list of (label, method, settings): every method of ``METHODS``
  and :data:`OURS_VARIANTS` (a variant of ours is one line there); the GPU path, mode ``depth``
  at recursion depth 1; trace = the frame's trace stage (draw + finish), build = its build stage;
- Mitsuba 3, variant ``llvm_ad_rgb``: one ``sphere`` shape per sphere, and one
  ``ellipsoids`` shape holding every sphere (scale = radius, ``extent`` 1), traced with
  ``Scene.ray_intersect_preliminary``; build = ``mi.load_dict``;
- Embree 4 through embreex: each sphere as an icosphere (vertices on the sphere),
  ``EmbreeScene.run``; build = the commit (first query of one ray); embreex's copying of
  the mesh into Embree is reported beside it, not counted.

The engines of one point run interleaved (:func:`race`): each repetition traces every engine
once in turn, so the ratios ours / peer come from one run under one load.

Accuracy against a float64 reference (``bih_traverse.traverse``, checked against
``render_reference`` at the smallest n): the share of pixels whose nearest sphere differs (a
miss counts as "no sphere"), and |t − t_ref| over the pixels where the engine hit the
reference's sphere.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer.accel.bih import build_for_spheres
from renderer.accel.bih_traverse import traverse
from renderer.geometry import meshes
from renderer.oracle.reference import primary_rays, render_reference
from renderer.scenes.scenarios import scenario

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings, method_names
from .style import image_line, legend_outside, plt, save, series
from .timing import Stat

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
MITSUBA_LABELS = {"spheres": "Mitsuba 3: sphere shapes", "ellipsoids": "Mitsuba 3: ellipsoids"}
EMBREE_LABEL = "Embree: icospheres"
# Our engines beyond one per method: (label, method, RenderSettings fields to change), one line each.
OURS_VARIANTS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("ours: bih, first hits auto", "bih", {"first_hits": "auto"}),  # what a frame gets by default
    ("ours: first hits raster", "bih", {"first_hits": "raster"}),
    ("ours: first hits tiles", "bih", {"first_hits": "tiles"}),
)
# The targets: ours (TARGET_ENGINE) / the faster Mitsuba engine, rays per second, in one scenario.
TARGET_ENGINE = "ours: bih, first hits auto"
TARGET_SCENARIO = 2
TARGET_NS = (256, 4096, 65536)
TARGET_RATIO = 0.5
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
    """What meshes.py's engines return: build and trace times, and per ray the hit's t and id."""

    def __init__(self, build: Stat, trace: Stat, t: np.ndarray, ids: np.ndarray, note: str = ""):
        self.build, self.trace, self.t, self.ids, self.note = build, trace, t, ids, note


def ours_engines() -> list[tuple[str, str, dict[str, Any]]]:
    """Our engines of the race: (label, method, settings beyond ``ours_settings``), every method of
    ``METHODS`` and then :data:`OURS_VARIANTS`."""
    return [(f"ours: {m}", m, {"first_hits": "trace"}) for m in method_names()] + [
        (lab, m, dict(x)) for lab, m, x in OURS_VARIANTS
    ]


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


class Engine:
    """One engine of a point's race. A peer builds in its own step (:meth:`build`, repeated); ours
    builds inside every frame (its ``build`` stage). Then one untimed :meth:`warm` trace (kernels,
    shader variants) and timed :meth:`trace` calls, one per interleaved repetition."""

    label = ""
    note = ""

    def __init__(self) -> None:
        self.builds: list[float] = []  # ms
        self.traces: list[float] = []  # ms
        self.spent_build_s = 0.0
        self.spent_trace_s = 0.0  # wall clock of the timed calls (ours: whole frames)

    def build(self) -> None:
        """One timed build (a peer's; ours builds in its frames)."""

    def warm(self) -> None:
        self._trace()

    def trace(self) -> None:
        t0 = time.perf_counter()
        self.traces.append(self._trace())
        self.spent_trace_s += time.perf_counter() - t0

    def _trace(self) -> float:
        """Trace every ray once: ms of the trace alone."""
        raise NotImplementedError

    def hits(self) -> tuple[np.ndarray, np.ndarray]:
        """Of the last trace, per ray: t (inf: no sphere) and the sphere's index (−1: none)."""
        raise NotImplementedError


class Ours(Engine):
    """Our GPU path, mode ``depth`` at recursion depth 1: trace = the frame's ``trace`` stage (draw + finish)."""

    def __init__(self, ctx: Context, label: str, scene, settings) -> None:
        super().__init__()
        self.label, self.ctx, self.scene, self.st = label, ctx, scene, settings
        self.res: Any = None

    def warm(self) -> None:
        self.ctx.renderer.render(self.scene, self.st)

    def _trace(self) -> float:
        self.res = self.ctx.renderer.render(self.scene, self.st)
        self.builds.append(float(self.res.timings["build"]))
        return float(self.res.timings["trace"])

    def hits(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.scene.n_spheres
        ids = self.res.primid.reshape(-1).astype(np.int64)
        sphere = (ids >= 0) & (ids < n)
        depth = self.res.depth.reshape(-1).astype(np.float64)
        return np.where(sphere, depth, np.inf), np.where(sphere, ids, -1)


class Mitsuba(Engine):
    """Mitsuba 3 (``MITSUBA_VARIANT``): ``kind`` ``spheres`` = one ``sphere`` shape per sphere,
    ``ellipsoids`` = one shape of them all; build = ``mi.load_dict``; trace =
    ``ray_intersect_preliminary`` evaluated and synchronised."""

    def __init__(self, kind: str, centers: np.ndarray, radii: np.ndarray, o: np.ndarray, d: np.ndarray) -> None:
        import mitsuba as mi

        super().__init__()
        _warm_mitsuba()
        self.kind = kind
        self.label = MITSUBA_LABELS[kind]
        n = len(centers)
        if kind == "spheres":
            width = len(str(max(n - 1, 0)))
            self.desc: dict[str, Any] = {"type": "scene"}
            for i in range(n):
                self.desc[f"s{i:0{width}d}"] = {
                    "type": "sphere",
                    "center": centers[i].tolist(),
                    "radius": float(radii[i]),
                }
        else:
            f32 = lambda a: mi.TensorXf(np.ascontiguousarray(a, dtype=np.float32))
            self.desc = {
                "type": "scene",
                "e": {
                    "type": "ellipsoids",
                    "centers": f32(centers),
                    "scales": f32(np.repeat(radii[:, None], 3, 1)),
                    "quaternions": f32(np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))),
                    "extent": 1.0,
                },
            }
        self.o32, self.d32 = o.astype(np.float32), d.astype(np.float32)
        self.scene: Any = None
        self.pi: Any = None

    def build(self) -> None:
        import mitsuba as mi

        self.scene = None  # the previous build's memory goes first
        t0 = time.perf_counter()
        self.scene = mi.load_dict(self.desc)
        dt = time.perf_counter() - t0
        self.builds.append(dt * 1e3)
        self.spent_build_s += dt

    def warm(self) -> None:
        import drjit as dr
        import mitsuba as mi

        o32, d32 = self.o32, self.d32
        self.ray = mi.Ray3f(
            mi.Point3f(*(mi.Float(o32[:, k]) for k in range(3))), mi.Vector3f(*(mi.Float(d32[:, k]) for k in range(3)))
        )
        dr.eval(self.ray)
        self._trace()

    def _trace(self) -> float:
        import drjit as dr

        t0 = time.perf_counter()
        pi = self.scene.ray_intersect_preliminary(self.ray)
        dr.eval(pi.t, pi.prim_index, pi.shape_index)
        dr.sync_thread()
        ms = (time.perf_counter() - t0) * 1e3
        self.pi = pi
        return ms

    def hits(self) -> tuple[np.ndarray, np.ndarray]:
        pi = self.pi
        t = np.array(pi.t, dtype=np.float64)
        hit = np.isfinite(t)
        if self.kind == "spheres":
            index_of_shape = np.array([int(s.id()[1:]) for s in self.scene.shapes()], dtype=np.int64)
            shape = np.minimum(np.array(pi.shape_index, dtype=np.int64), len(index_of_shape) - 1)
            ids = np.where(hit, index_of_shape[shape], -1)
        else:
            ids = np.where(hit, np.array(pi.prim_index, dtype=np.int64), -1)
        return np.where(hit, t, np.inf), ids


class Embree(Engine):
    """Embree 4 through embreex, each sphere an icosphere (vertices on the sphere); build = the
    commit (the first query, of one ray); embreex's copying of the mesh in is noted, not counted."""

    label = EMBREE_LABEL

    def __init__(self, centers: np.ndarray, radii: np.ndarray, o: np.ndarray, d: np.ndarray) -> None:
        super().__init__()
        n = len(centers)
        level = ICO_LEVEL
        while level > 0 and n * 20 * 4**level > ICO_MAX_TRIANGLES:
            level -= 1
        uv, uf = icosphere(level)
        self.verts = (centers[:, None, :] + radii[:, None, None] * uv[None]).reshape(-1, 3).astype(np.float32)
        self.faces = (uf[None] + len(uv) * np.arange(n)[:, None, None]).reshape(-1, 3).astype(np.int32)
        self.per = len(uf)
        self.o32, self.d32 = np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)
        self.mesh_ms: list[float] = []
        self.sc: Any = None
        self.res: Any = None

    def build(self) -> None:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh

        self.sc = None
        t0 = time.perf_counter()
        sc = rtcs.EmbreeScene()
        TriangleMesh(sc, self.verts, self.faces)
        t1 = time.perf_counter()
        sc.run(self.o32[:1], self.d32[:1])  # the first query commits the scene
        t2 = time.perf_counter()
        self.sc = sc
        self.mesh_ms.append((t1 - t0) * 1e3)
        self.builds.append((t2 - t1) * 1e3)
        self.spent_build_s += t2 - t0
        self.note = (
            f"{self.per} triangles per sphere; build = commit, mesh copy-in {Stat(self.mesh_ms).median:,.0f} ms "
            "not counted"
        )

    def _trace(self) -> float:
        t0 = time.perf_counter()
        self.res = self.sc.run(self.o32, self.d32, output=1)
        return (time.perf_counter() - t0) * 1e3

    def hits(self) -> tuple[np.ndarray, np.ndarray]:
        prim = np.asarray(self.res["primID"]).astype(np.int64)
        t = np.asarray(self.res["tfar"], dtype=np.float64)
        hit = (prim >= 0) & np.isfinite(t) & (t < 1e30)
        return np.where(hit, t, np.inf), np.where(hit, prim // self.per, -1)


def race(engines: list[Engine], runs: int, budget_s: float | None) -> dict[str, str]:
    """Build, warm and trace ``engines`` interleaved: each repetition runs every engine once in turn,
    so a change of the machine's load falls on all of them alike. An engine stops taking
    repetitions once its timed calls passed ``budget_s`` (≥ 1 kept). {label: error} of those that failed."""
    failed: dict[str, str] = {}

    def step(e: Engine, what: str) -> None:
        if e.label in failed:
            return
        try:
            getattr(e, what)()
        except Exception as ex:  # a peer failing at one size must not end the section
            failed[e.label] = f"{what}: {type(ex).__name__}: {ex}"

    def more(spent_s: float, rep: int) -> bool:
        return rep == 0 or budget_s is None or spent_s <= budget_s

    for rep in range(max(1, runs)):
        for e in engines:
            if more(e.spent_build_s, rep):
                step(e, "build")
    for e in engines:
        step(e, "warm")
    for rep in range(max(1, runs)):
        for e in engines:
            if more(e.spent_trace_s, rep):
                step(e, "trace")
    return failed


def ours_settings(method: str, w: int, h: int):
    return default_settings().with_(width=w, height=h, mode="depth", max_recursion_depth=1, method=method)


def without_planes(scene):
    """The scene as the peers trace it: its spheres only (a scenario's floor plane left out)."""
    return dataclasses.replace(scene, planes=())


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


def errors(t: np.ndarray, ids: np.ndarray, ref_ids: np.ndarray, ref_t: np.ndarray) -> dict[str, float]:
    """Share of rays (%) whose nearest sphere differs from the reference's, and |t − t_ref| where it is the same."""
    mismatch = float(np.mean(ids != ref_ids)) * 100.0
    same = (ids == ref_ids) & (ref_ids >= 0)
    if same.any():
        dt = np.abs(t[same] - ref_t[same])
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
    ours = ours_engines()
    rows: dict[tuple[int, int, str], dict] = {}
    ref_check: dict[int, dict] = {}
    skipped: list[str] = []
    too_slow: set[tuple[str, int]] = set()
    jobs = [(sc, n) for sc in scs for n in ns]
    for sc, n in ctx.bar(jobs, desc="peers"):
        scene = without_planes(scenario(sc, n, seed=0, radius=1.0))
        o, d = primary_rays(scene.camera, w, h)
        ref_ids, ref_t = reference_hits(scene, o, d)
        if n == ns[0]:
            ref_check[sc] = check_reference(scene, w, h, ref_ids, ref_t)
        c, r = scene.sphere_centers, scene.sphere_radii
        engines: list[Engine] = []
        for label, method, extra in ours:
            st = ours_settings(method, w, h).with_(**extra)
            what = f"{label}, scenario {sc}, n = {n:,}"
            if (label, sc) in too_slow:
                ctx.skipped.append(f"{what}: over the budget at a smaller n")
                continue
            if not ctx.within_budget(scene, st, what):
                too_slow.add((label, sc))
                continue
            engines.append(Ours(ctx, label, scene, st))
        if "mitsuba" in ok:
            engines += [Mitsuba("spheres", c, r, o, d), Mitsuba("ellipsoids", c, r, o, d)]
        if "embreex" in ok:
            engines.append(Embree(c, r, o, d))
        failed = race(engines, ctx.runs, ctx.point_budget_s)
        skipped += [f"{lab}, scenario {sc}, n = {n:,}: {err}" for lab, err in failed.items()]
        for e in engines:
            if e.label in failed:
                continue
            trace = Stat(e.traces)
            rows[(sc, n, e.label)] = {
                "build": Stat(e.builds),
                "trace": trace,
                "mrays": w * h / (trace.median / 1e3) / 1e6,
                "note": e.note,
                **errors(*e.hits(), ref_ids, ref_t),
            }
        del engines  # the peers' scenes before the next point's

    return {
        "size": [w, h],
        "ns": ns,
        "scenarios": scs,
        "ours": [[label, method, extra] for label, method, extra in ours],
        "versions": versions(),
        "rows": {f"{sc}/{n}/{eng}": v for (sc, n, eng), v in rows.items()},
        "skipped": skipped,
        "reference_check": ref_check,
        "unavailable": {k: v for k, v in why.items() if v},
        "drjit_threads": os.environ.get("DRJIT_NUM_THREADS", "default"),
    }


def _rows(data: dict) -> dict[tuple[int, int, str], dict]:
    """The saved rows by (scenario, n, engine), their Stats read back, in the order measured."""
    rows = {}
    for key, v in data["rows"].items():
        sc, n, eng = key.split("/", 2)
        rows[(int(sc), int(n), eng)] = {**v, "build": Stat.from_json(v["build"]), "trace": Stat.from_json(v["trace"])}
    return rows


def faster_mitsuba(rows: dict, sc: int, n: int) -> tuple[str, float] | None:
    """The Mitsuba engine with the most rays per second at (sc, n) and that rate (Mrays/s)."""
    mit = [(rows[(sc, n, lab)]["mrays"], lab) for lab in MITSUBA_LABELS.values() if (sc, n, lab) in rows]
    if not mit:
        return None
    mrays, lab = max(mit)
    return lab, mrays


def ratio_to(rows: dict, sc: int, n: int, eng: str, peer: str | None) -> float:
    """Ours / peer, rays per second of the same interleaved run (nan when either is missing)."""
    if peer is None or (sc, n, eng) not in rows or (sc, n, peer) not in rows:
        return math.nan
    return rows[(sc, n, eng)]["mrays"] / rows[(sc, n, peer)]["mrays"]


def targets_md(data: dict, rows: dict) -> str:
    """The targets paragraph: TARGET_ENGINE / the faster Mitsuba engine in TARGET_SCENARIO at TARGET_NS."""
    parts = []
    for n in TARGET_NS:
        best = faster_mitsuba(rows, TARGET_SCENARIO, n)
        ratio = ratio_to(rows, TARGET_SCENARIO, n, TARGET_ENGINE, best[0] if best else None)
        if best is None or not math.isfinite(ratio):
            parts.append(f"n = {n:,}: not measured in this run")
            continue
        ours = rows[(TARGET_SCENARIO, n, TARGET_ENGINE)]["mrays"]
        verdict = "met" if ratio >= TARGET_RATIO else "NOT met"
        parts.append(
            f"n = {n:,}: {ours:.2f} / {best[1]:.2f} Mrays/s ({best[0]}) = **{ratio:.3f}×**, "
            f"target ≥ {TARGET_RATIO:g}× {verdict}"
        )
    w, h = data["size"]
    return (
        f"**Targets** (primary rays, {w} × {h}, scenario {TARGET_SCENARIO}, `{TARGET_ENGINE.split(': ', 1)[-1]}` "
        "against the faster of the two Mitsuba engines at that n, rays per second of the same interleaved run): "
        + "; ".join(parts)
        + "."
    )


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    if "rows" not in data:
        lines = "\n".join(f"- `{k}`: {v}" for k, v in data["unavailable"].items())
        return f"""## {TITLE}

**{INSTALL_HINT}** — the peers are an optional dependency group; this section was skipped.

{lines}
"""
    w, h = data["size"]
    scs, skipped, ref_check = data["scenarios"], data["skipped"], data["reference_check"]
    rows = _rows(data)
    tables = []
    for sc in scs:
        trs = []
        for (sc2, n, eng), v in rows.items():
            if sc2 != sc:
                continue
            ours = eng.startswith("ours")
            best = faster_mitsuba(rows, sc, n)
            r_mit = ratio_to(rows, sc, n, eng, best[0] if best else None) if ours else math.nan
            r_emb = ratio_to(rows, sc, n, eng, EMBREE_LABEL) if ours else math.nan
            trs.append(
                [
                    f"{n:,}",
                    eng + (f" ({v['note']})" if v["note"] else ""),
                    v["build"].fmt(1),
                    v["trace"].fmt(1),
                    f"{v['mrays']:.2f}",
                    f"{r_mit:.2f}×" if math.isfinite(r_mit) else "",
                    f"{r_emb:.2f}×" if math.isfinite(r_emb) else "",
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
                    "ours / faster Mitsuba",
                    "ours / Embree",
                    "nearest sphere ≠ reference",
                    "max |Δt|",
                    "median |Δt|",
                ],
                trs,
                "rlrrrrrrrr",
            )
            + "\n\n"
            + run.caption(what="median, spread min–max; engines interleaved", capped=True)
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
    extra = [f"`{lab}` (`{m}`, {', '.join(f'{k}={v!r}' for k, v in x.items())})" for lab, m, x in data["ours"] if x]
    variants = f" and {', '.join(extra)}" if extra else ""
    threads = data.get("drjit_threads", "default")
    return f"""## {TITLE}

The same primary rays ({w} × {h}) against the same geometry in every engine: the spheres of the
thesis's scenes (radius 1) **without the scenario's floor plane** — the peers are given the spheres
only, so our tracer is given the scene with its planes removed. Ours: our GPU path, every method of
`METHODS`{variants}, mode `depth` at recursion depth 1; Mitsuba 3 (`{MITSUBA_VARIANT}`; one `sphere`
shape per sphere, and one `ellipsoids` shape holding them all, via `ray_intersect_preliminary`);
Embree through embreex (spheres as icospheres: {20 * 4**ICO_LEVEL} triangles each, one level fewer where
a scene would pass {ICO_MAX_TRIANGLES:,} triangles). Versions: {vers}. Dr.Jit threads: {threads}.

**Interleaved.** At every point (scenario, n) the engines run in one process, in turn: the peers'
builds repeated in rounds, one untimed warm-up trace each (kernels, shader variants), then each
repetition traces every engine once, so a change of the machine's load falls on all of them alike;
the ratios ours / peer are of the medians of that one run. Build = what each needs before the first
ray (ours: the method's build stage of each frame; `mi.load_dict`; Embree's commit — embreex's
copying of the mesh is shown apart); trace = the rays only (ours: the frame's trace stage, draw and
finish). Hit distances are compared with a float64 reference: the CPU BIH traversal of
`renderer/bih_traverse.py` (exact: the same `t` as a float64 brute force), itself checked against
`render_reference` at the smallest n — {check_txt}.{missing}

{targets_md(data, rows)}

{img}

{chr(10).join(t + chr(10) for t in tables)}{skipped_txt}

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``peers.png`` from ``peers.json``: top row Mrays/s against n per scenario; bottom row build ms
    and max |Δt| (median over the scenarios) and ours / faster Mitsuba in the targets' scenario.
    One colour and marker per engine in every panel."""
    if "rows" not in data:  # the peers were not installed: nothing to draw
        return {}
    pyplot = plt()
    w, h = data["size"]
    ns, scs = data["ns"], data["scenarios"]
    rows = _rows(data)
    engines = list(dict.fromkeys(k[2] for k in rows))

    def value(v: dict, key: str) -> float:
        return v[key].median if isinstance(v[key], Stat) else float(v[key])

    def med(key: str, n: int, eng: str) -> float:
        return float(np.median([value(rows[(sc, n, eng)], key) for sc in scs if (sc, n, eng) in rows]))

    fig, axes = pyplot.subplots(2, max(3, len(scs)), figsize=(16, 9), layout="constrained", squeeze=False)
    for ax in axes[0][len(scs) :]:
        ax.set_visible(False)
    ratio_sc = TARGET_SCENARIO if TARGET_SCENARIO in scs else scs[0]
    for eng in engines:
        ours = eng.startswith("ours")
        style = series(eng, ls="-" if ours else "--")
        for ax, sc in zip(axes[0], scs, strict=False):
            xs = [n for n in ns if (sc, n, eng) in rows]
            if xs:
                ax.plot(xs, [rows[(sc, n, eng)]["mrays"] for n in xs], **style)
        xs = [n for n in ns if any((sc, n, eng) in rows for sc in scs)]
        bx = [n for n in xs if med("build", n, eng) > 0]  # brute force builds nothing: no line, same colours
        if bx:
            axes[1][0].plot(bx, [med("build", n, eng) for n in bx], **style)
        if xs:
            axes[1][1].plot(xs, [max(med("max_dt", n, eng), 1e-9) for n in xs], **style)
        if ours:
            pts = []
            for n in ns:
                best = faster_mitsuba(rows, ratio_sc, n)
                r = ratio_to(rows, ratio_sc, n, eng, best[0] if best else None)
                if math.isfinite(r):
                    pts.append((n, r))
            if pts:
                axes[1][2].plot(*zip(*pts, strict=True), **style)
    axes[1][2].axhline(TARGET_RATIO, color="grey", lw=1.0, ls=":", label=f"target {TARGET_RATIO:g}×")
    labels = [f"Mrays/s, scenario {sc}" for sc in scs]
    labels += [
        "build ms, median over scenarios",
        "max |t − t_ref| (world units), median over scenarios",
        f"ours / faster Mitsuba, rays/s, scenario {ratio_sc}",
    ]
    for ax, yl in zip([*axes[0][: len(scs)], *axes[1][:3]], labels, strict=True):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("spheres n")
        ax.set_ylabel(yl, fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    legend_outside(fig, axes, title="engine (solid: ours)")
    fig.suptitle(f"Primary rays at {w} × {h}, spheres only, engines interleaved")
    save(fig, figures, NAME, quick)
    return {NAME: "Mrays/s against n per scenario, build time, hit-distance error and ours / Mitsuba, ours and peers"}
