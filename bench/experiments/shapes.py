"""Analytic shapes against their tessellations: what each costs and how far it is from the exact surface.

For each kind (torus, cylinder with caps, cone frustum with caps, disk) one object filling a
good part of a 640 × 1088 frame, and 64 tori on a grid (a tree over many shapes), traced as
the analytic primitive and as triangle meshes from coarse to fine. Every tessellation has its
vertices ON the exact surface and the exact normals there (smooth shading: the mesh a modeller
would export); caps and the disk are flat, their normals the axis.

Each is traced by two methods (``bih``, ``bvh``), mode ``normal`` (whose result also has the
primary hit's id and depth), at recursion 1, one sample per pixel. Measured per row:

- memory: the bytes of the prepared method's packed textures (``PreparedMethod.packed``:
  tree nodes, leaf records, triangle records, shape records), and the tree's own ``bytes``
  statistic (the build's node layout);
- build ms: the frame's ``build`` stage (the tree and the packing of its records); trace ms:
  its ``trace`` stage (draw and finish); frame ms: the whole frame (build, upload, trace,
  read). Repetitions are interleaved: every configuration once per round, after one untimed
  round (shader compiles), so the machine's load falls on all rows alike;
- error against the exact surface: the float64 reference (``renderer/oracle/reference.py``
  ``render_reference``) of the ANALYTIC scene, one ray per pixel centre. Silhouette pixels:
  those whose hit/miss differs from it; normal error: the angle between the normals over the
  pixels both hit (mean and max, degrees). The analytic row's error is float32 (GPU) against
  float64.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from renderer.config.methods import METHODS
from renderer.geometry.scene import Camera, Light, Mesh, Scene
from renderer.geometry.shapes import CONE, CYLINDER, DISK, TORUS, Shapes, bounds
from renderer.oracle.reference import render_reference
from renderer.scenes.scenarios import RED

from .context import Context, RunInfo
from .markdown import md_table
from .scenes import default_settings
from .style import image_line, legend_outside, log_axis, plt, save
from .timing import Stat

NAME = "shapes"
TITLE = "Analytic shapes against their tessellations — memory, build, trace and error"

SIZE, SIZE_QUICK = (640, 1088), (64, 108)
METHODS_MEASURED = ("bih", "bvh")
FOV_Y = 40.0
FILL = 0.8  # of the frame's width the object's bounding sphere spans
# Tessellation levels, coarse to fine: segments around the axis (cylinder, cone, disk) or
# the torus's tube segments (segments around its axis: twice as many).
ROUND_LEVELS, ROUND_LEVELS_QUICK = (8, 32, 128, 512, 2048, 8192), (8, 64)
TORUS_LEVELS, TORUS_LEVELS_QUICK = (6, 12, 24, 48, 96, 192, 384, 512), (6, 24)
MANY_LEVELS, MANY_LEVELS_QUICK = (6, 12, 24, 48), (6,)
MANY_GRID, MANY_GRID_QUICK = 8, 2  # tori per side of the square grid (8 × 8 = 64)

KIND_LABELS = {"torus": "torus", "cylinder": "cylinder, caps", "cone": "cone frustum, caps", "disk": "disk"}
MANY_LABEL = "64 tori"


# --------------------------------------------------------------------------- geometry


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def frame_of(axis) -> np.ndarray:
    """(3, 3) rows e1, a, e2: a right-handed basis whose second row is the unit ``axis``
    (local x, y = along the axis, z)."""
    a = _unit(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    e1 = _unit(np.cross(a, helper))
    e2 = np.cross(e1, a)
    return np.stack([e1, a, e2])


def _place(local: np.ndarray, origin, axis) -> np.ndarray:
    """Local points (x, along the axis, z) into the world."""
    return np.asarray(origin, dtype=np.float64) + local @ frame_of(axis)


def _ring(radius: float, y: float, n: int) -> np.ndarray:
    """``n`` points of a circle of ``radius`` at height ``y`` (local), angle increasing from x towards −z."""
    u = 2.0 * math.pi * np.arange(n) / n
    return np.stack([radius * np.cos(u), np.full(n, y), -radius * np.sin(u)], axis=-1)


def _fan(centre_y: float, radius: float, n: int, up: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A flat disk of ``n`` triangles around the axis at height ``centre_y`` (local), wound
    and shaded towards +axis (``up``) or −axis: vertices, triangles, normals."""
    v = np.concatenate([[[0.0, centre_y, 0.0]], _ring(radius, centre_y, n)])
    i = np.arange(n)
    t = np.stack([np.zeros(n, np.int64), 1 + i, 1 + (i + 1) % n], axis=-1)
    if not up:
        t = t[:, [0, 2, 1]]
    nrm = np.tile([0.0, 1.0 if up else -1.0, 0.0], (len(v), 1))
    return v, t, nrm


def _side(r0: float, r1: float, h: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The side of a cone frustum (a cylinder when r0 = r1) of ``2n`` triangles: two rings of
    ``n`` vertices on the exact surface (the side is ruled: straight along the axis), the
    exact normals there, wound outwards."""
    v = np.concatenate([_ring(r0, 0.0, n), _ring(r1, h, n)])
    u = 2.0 * math.pi * np.arange(n) / n
    k = (r1 - r0) / h
    radial = np.stack([np.cos(u), np.zeros(n), -np.sin(u)], axis=-1)
    nrm = (radial - k * np.array([0.0, 1.0, 0.0])) / math.sqrt(1.0 + k * k)
    i = np.arange(n)
    j = (i + 1) % n
    t = np.concatenate([np.stack([i, j, n + j], -1), np.stack([i, n + j, n + i], -1)])
    return v, t, np.concatenate([nrm, nrm])


def _join(parts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vs, ts, ns, off = [], [], [], 0
    for v, t, n in parts:
        vs.append(v)
        ts.append(t + off)
        ns.append(n)
        off += len(v)
    return np.concatenate(vs), np.concatenate(ts), np.concatenate(ns)


def tess_frustum(r0: float, r1: float, h: float, n: int, caps: bool = True):
    """A cone frustum (cylinder: r0 = r1) along local +y from 0 to ``h``: side and caps, ``n``
    segments (4n triangles with both caps); separate vertices at the rims, so the caps stay flat."""
    parts = [_side(r0, r1, h, n)]
    if caps:
        if r0 > 0.0:
            parts.append(_fan(0.0, r0, n, up=False))
        if r1 > 0.0:
            parts.append(_fan(h, r1, n, up=True))
    return _join(parts)


def tess_torus(major: float, minor: float, n_tube: int):
    """A torus about local +y: ``2 n_tube`` segments around the axis × ``n_tube`` around the
    tube (4 n_tube² triangles), vertices on the surface, exact normals, wound outwards."""
    nu, nv = 2 * n_tube, n_tube
    u = 2.0 * math.pi * np.arange(nu) / nu
    w = 2.0 * math.pi * np.arange(nv) / nv
    uu, ww = np.meshgrid(u, w, indexing="ij")
    ring = major + minor * np.cos(ww)
    pos = np.stack([ring * np.cos(uu), minor * np.sin(ww), -ring * np.sin(uu)], axis=-1).reshape(-1, 3)
    nrm = np.stack([np.cos(ww) * np.cos(uu), np.sin(ww), -np.cos(ww) * np.sin(uu)], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    t = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return pos, t, nrm


def _oriented(v: np.ndarray, t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``t`` with every triangle whose winding normal opposes its corners' normals flipped."""
    g = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    flip = np.einsum("ij,ij->i", g, n[t].sum(axis=1)) < 0.0
    out = t.copy()
    out[flip] = out[flip][:, [0, 2, 1]]
    return out


# One object per kind: (shape kind, origin, axis, r0, r1, height, caps). Local frames as
# renderer/geometry/shapes.py's records: a cylinder or cone rises from its base along the axis.
OBJECTS = {
    "torus": (TORUS, (0.0, 0.0, 0.0), (0.3, 0.65, 0.7), 1.0, 0.35, 0.0, 0.0),
    "cylinder": (CYLINDER, (0.0, -1.0, 0.0), (0.3, 1.0, 0.35), 0.6, 0.6, 2.0, 1.0),
    "cone": (CONE, (0.0, -1.0, 0.0), (0.3, 1.0, 0.35), 0.8, 0.3, 2.0, 1.0),
    "disk": (DISK, (0.0, 0.0, 0.0), (0.25, 0.45, 1.0), 1.2, 0.0, 0.0, 0.0),
}


def shape_row(kind: int, origin, axis, r0: float, r1: float, h: float, caps: float) -> list[float]:
    return [*origin, r0, *_unit(axis), r1, h, caps, float(kind), 0.0]


def tessellate(row, level: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The world-space tessellation of the shape record ``row`` at ``level``: vertices, triangles, normals."""
    kind, origin, axis = int(row[10]), row[0:3], row[4:7]
    r0, r1, h, caps = row[3], row[7], row[8], row[9] != 0.0
    if kind == TORUS:
        v, t, n = tess_torus(r0, r1, level)
    elif kind == DISK:
        v, t, n = _fan(0.0, r0, level, up=True)
    else:
        v, t, n = tess_frustum(r0, r1, h, level, caps)
    basis = frame_of(axis)
    v, n = _place(v, origin, axis), n @ basis
    return v, _oriented(v, t, n), n


def _camera(centre: np.ndarray, radius: float, w: int, h: int) -> Camera:
    """A camera on +z that frames a sphere of ``radius`` about ``centre`` at FILL of the width."""
    half_x = math.atan(math.tan(math.radians(FOV_Y) / 2) * w / h)
    dist = radius / (FILL * math.tan(half_x))
    c = tuple(float(x) for x in centre)
    return Camera((c[0], c[1] + 0.15 * dist, c[2] + dist), c, (0.0, 1.0, 0.0), FOV_Y)


def _scene(camera: Camera, shapes: Shapes | None = None, meshes: tuple[Mesh, ...] = ()) -> Scene:
    return Scene(
        camera,
        (Light((4.0, 6.0, 8.0), (1.0, 1.0, 1.0)),),
        (RED,),
        np.zeros((0, 3)),
        np.zeros(0),
        np.zeros(0, np.int32),
        (),
        meshes,
        shapes=shapes if shapes is not None else Shapes.empty(),
    )


def rows_of(name: str, quick: bool) -> np.ndarray:
    """The shape records of the object (or objects) ``name``."""
    if name != "many":
        return np.array([shape_row(*OBJECTS[name])])
    k = MANY_GRID_QUICK if quick else MANY_GRID
    rng = np.random.default_rng(7)
    out = []
    for i in range(k * k):
        x, y = 1.5 * (i % k - (k - 1) / 2), 1.5 * (i // k - (k - 1) / 2)
        out.append(shape_row(TORUS, (x, y, 0.0), rng.normal(size=3) + (0.0, 0.0, 1.5), 0.5, 0.17, 0.0, 0.0))
    return np.array(out)


def scenes_of(name: str, levels, size: tuple[int, int], quick: bool) -> tuple[Scene, dict[int, Scene]]:
    """The analytic scene and, per level, its tessellation (one mesh per object)."""
    rows = rows_of(name, quick)
    shapes = Shapes(rows[:, 10].astype(np.int8), rows, np.zeros(len(rows), np.int32))
    box = bounds(shapes)
    lo, hi = box[:, 0].min(axis=0), box[:, 1].max(axis=0)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2
    cam = _camera(centre, radius, *size)
    tess = {}
    for level in levels:
        meshes = tuple(Mesh(*_vtn(row, level)) for row in rows)
        tess[level] = _scene(cam, meshes=meshes)
    return _scene(cam, shapes=shapes), tess


def _vtn(row, level):
    v, t, n = tessellate(row, level)
    return v, t, 0, n


# --------------------------------------------------------------------------- measuring


def errors(res, ref) -> dict:
    """Silhouette pixels (hit/miss differs) and the normal angle over the pixels both hit."""
    hit, ref_hit = res.primid >= 0, ref.primid >= 0
    both = hit & ref_hit
    cos = np.einsum("...k,...k->...", res.normal[both].astype(np.float64), ref.normal[both].astype(np.float64))
    n = np.linalg.norm(res.normal[both].astype(np.float64), axis=-1)
    ang = np.degrees(np.arccos(np.clip(cos / np.where(n > 0, n, 1.0), -1.0, 1.0)))
    return {
        "silhouette_px": int((hit != ref_hit).sum()),
        "extra_px": int((hit & ~ref_hit).sum()),
        "missing_px": int((~hit & ref_hit).sum()),
        "ref_hit_px": int(ref_hit.sum()),
        "normal_mean_deg": float(ang.mean()) if both.any() else math.nan,
        "normal_max_deg": float(ang.max()) if both.any() else math.nan,
    }


def measure(ctx: Context) -> dict:
    quick = ctx.quick
    w, h = SIZE_QUICK if quick else SIZE
    st = default_settings().with_(width=w, height=h, mode="normal", max_recursion_depth=1)
    width = ctx.renderer.max_texture_width
    groups = [
        ("torus", TORUS_LEVELS_QUICK if quick else TORUS_LEVELS),
        ("cylinder", ROUND_LEVELS_QUICK if quick else ROUND_LEVELS),
        ("cone", ROUND_LEVELS_QUICK if quick else ROUND_LEVELS),
        ("disk", ROUND_LEVELS_QUICK if quick else ROUND_LEVELS),
        ("many", MANY_LEVELS_QUICK if quick else MANY_LEVELS),
    ]
    configs = []  # (group, level or None, method, scene)
    refs, out = {}, {}
    for name, levels in groups:
        analytic, tess = scenes_of(name, levels, (w, h), quick)
        t0 = time.perf_counter()
        refs[name] = render_reference(analytic, st)
        ctx.log(f"shapes: reference of {name} in {time.perf_counter() - t0:,.1f} s")
        out[name] = {"levels": list(levels), "rows": {}, "reference_ms": (time.perf_counter() - t0) * 1e3}
        for m in METHODS_MEASURED:
            configs.append((name, None, m, analytic))
            for level in levels:
                configs.append((name, level, m, tess[level]))
    samples: dict[int, dict[str, list[float]]] = {i: {} for i in range(len(configs))}
    errs: dict[int, dict] = {}
    rounds = 1 + max(1, ctx.runs)
    for r in ctx.bar(range(rounds), desc="shapes rounds"):
        for i, (name, _level, m, scene) in enumerate(ctx.bar(configs, desc=f"round {r}")):
            t0 = time.perf_counter()
            res = ctx.renderer.render(scene, st.with_(method=m))
            wall = (time.perf_counter() - t0) * 1e3
            if r == 0:  # the untimed round (shader compiles): the images, compared once
                errs[i] = errors(res, refs[name])
                continue
            s = samples[i]
            s.setdefault("frame", []).append(wall)
            for k, v in res.timings.items():
                s.setdefault(k, []).append(float(v))
    for i, (name, level, m, scene) in enumerate(configs):
        prep = METHODS[m].prepare(scene, st.max_prims, st.max_tree_depth, width)
        key = f"{m}/{'analytic' if level is None else level}"
        out[name]["rows"][key] = {
            "method": m,
            "level": level,
            "triangles": scene.n_triangles,
            "shapes": scene.n_shapes,
            "packed_bytes": int(prep.packed.nbytes),
            "tree_bytes": int(prep.stats.get("bytes", 0)),
            "timings": {k: Stat(v).to_json() for k, v in samples[i].items()},
            **errs[i],
        }
    return {"size": [w, h], "groups": out, "methods": list(METHODS_MEASURED)}


# --------------------------------------------------------------------------- section


def _level_label(name: str, level: int | None) -> str:
    if level is None:
        return "analytic"
    if name in ("torus", "many"):
        return f"{2 * level} × {level}"
    return f"{level}"


def _rows(group: dict, method: str) -> list[dict]:
    """The group's rows of ``method``: the analytic one first, then the levels coarse to fine."""
    return [group["rows"][f"{method}/{k}"] for k in ["analytic", *group["levels"]] if f"{method}/{k}" in group["rows"]]


def _ms(row: dict, stage: str) -> float:
    return Stat.from_json(row["timings"][stage]).median if stage in row["timings"] else math.nan


def group_table(name: str, group: dict, methods) -> str:
    rows = []
    for m in methods:
        for r in _rows(group, m):
            t = {k: Stat.from_json(v) for k, v in r["timings"].items()}
            rows.append(
                [
                    m,
                    _level_label(name, r["level"]),
                    f"{r['triangles']:,}" if r["level"] is not None else f"{r['shapes']} shape(s)",
                    f"{r['packed_bytes']:,}",
                    f"{r['tree_bytes']:,}",
                    t["build"].fmt(1),
                    t["trace"].fmt(1),
                    t["frame"].fmt(1),
                    f"{r['silhouette_px']:,} ({r['missing_px']:,} / {r['extra_px']:,})",
                    f"{r['normal_mean_deg']:.3f}",
                    f"{r['normal_max_deg']:.3f}",
                ]
            )
    return md_table(
        [
            "method",
            "level",
            "triangles",
            "packed bytes",
            "tree bytes",
            "build ms",
            "trace ms",
            "frame ms",
            "silhouette px (missing / extra)",
            "normal mean °",
            "normal max °",
        ],
        rows,
        "llrrrrrrrrr",
    )


def _mib(n: int) -> str:
    return f"{n / 2**20:,.2f} MiB" if n >= 2**20 else f"{n:,} bytes"


def first_below(levels: list[dict]) -> dict | None:
    """The coarsest level whose silhouette error is below one pixel (and stays there)."""
    for i, r in enumerate(levels):
        if all(x["silhouette_px"] < 1 for x in levels[i:]):
            return r
    return None


def summary_table(groups: dict, methods, quick: bool) -> str:
    """Per kind and method: the analytic primitive against the coarsest level below one pixel."""
    rows = []
    for name, g in groups.items():
        label = KIND_LABELS.get(name, MANY_LABEL if not quick else "tori on a grid")
        for m in methods:
            ana, *levels = _rows(g, m)
            b = first_below(levels)
            if b is None:
                finest = levels[-1]
                rows.append(
                    [label, m, f"{_ms(ana, 'trace'):,.1f}", f"none measured (finest: {finest['silhouette_px']:,} px)"]
                    + ["—"] * 4
                )
                continue
            rows.append(
                [
                    label,
                    m,
                    f"{_ms(ana, 'trace'):,.1f}",
                    f"{_level_label(name, b['level'])} ({b['triangles']:,} triangles)",
                    f"{_ms(b, 'trace'):,.1f}",
                    f"{_ms(b, 'trace') / _ms(ana, 'trace'):.2f}×",
                    f"{_ms(b, 'frame') / _ms(ana, 'frame'):.1f}×",
                    f"{b['packed_bytes'] / ana['packed_bytes']:,.0f}×",
                ]
            )
    return md_table(
        [
            "kind",
            "method",
            "analytic trace ms",
            "coarsest level below 1 px",
            "its trace ms",
            "trace ÷ analytic",
            "frame ÷ analytic",
            "packed bytes ÷ analytic",
        ],
        rows,
        "llrlrrrr",
    )


def torus_target(group: dict, methods) -> tuple[str, list[dict]]:
    """The target's paragraph and its numbers per method: the coarsest level whose silhouette
    error is below one pixel, whether the analytic torus's trace costs less than it, and where
    the two traces' costs cross."""
    lines, out = [], []
    for m in methods:
        ana, *levels = _rows(group, m)
        a_ms = _ms(ana, "trace")
        below = first_below(levels)
        dearer = next((i for i, r in enumerate(levels) if all(_ms(x, "trace") > a_ms for x in levels[i:])), None)
        cross = (
            f"every measured tessellation traces slower than the analytic torus, the coarsest "
            f"({_level_label('torus', levels[0]['level'])} segments, {levels[0]['triangles']:,} triangles, "
            f"{_ms(levels[0], 'trace'):,.1f} ms, silhouette {levels[0]['silhouette_px']:,} px) included"
            if dearer == 0
            else f"the tessellation's trace costs more than the analytic torus's from "
            f"{_level_label('torus', levels[dearer]['level'])} segments on ({levels[dearer]['triangles']:,} "
            f"triangles, {_ms(levels[dearer], 'trace'):,.1f} ms, silhouette {levels[dearer]['silhouette_px']:,} px)"
            if dearer is not None
            else f"no measured level traces slower than the analytic torus ({a_ms:,.1f} ms) at every finer level"
        )
        if below is not None:
            t_ms = _ms(below, "trace")
            met = a_ms < t_ms
            out.append({"method": m, "met": met, "level": below["level"], "analytic_ms": a_ms, "tess_ms": t_ms})
            lines.append(
                f"- **{m}: {'met' if met else 'NOT met'}.** The coarsest level with a silhouette error below one "
                f"pixel is {_level_label('torus', below['level'])} segments ({below['triangles']:,} triangles: "
                f"{below['silhouette_px']} px); it traces in {t_ms:,.1f} ms (frame {_ms(below, 'frame'):,.1f} ms, "
                f"{_mib(below['packed_bytes'])} packed), the analytic torus in {a_ms:,.1f} ms (frame "
                f"{_ms(ana, 'frame'):,.1f} ms, {_mib(ana['packed_bytes'])}; its own float32 error "
                f"{ana['silhouette_px']} px): the tessellation takes {t_ms / a_ms:.2f}× the analytic torus's trace "
                f"time and {_ms(below, 'frame') / _ms(ana, 'frame'):,.0f}× its frame time. Crossover: {cross}."
            )
            continue
        finest = levels[-1]
        out.append({"method": m, "met": None, "level": None, "analytic_ms": a_ms, "tess_ms": math.nan})
        lines.append(
            f"- **{m}: not reached.** No measured level gets the silhouette below one pixel: the finest, "
            f"{_level_label('torus', finest['level'])} segments ({finest['triangles']:,} triangles), is "
            f"{finest['silhouette_px']:,} px off at {_ms(finest, 'trace'):,.1f} ms. Crossover: {cross}."
        )
    return "\n".join(lines), out


def report(data: dict, run: RunInfo, charts: dict[str, str]) -> str:
    w, h = data["size"]
    methods = data["methods"]
    groups = data["groups"]
    path = f"figures/{NAME}.json"
    img = "\n".join(image_line(k, v) for k, v in charts.items())
    target, _ = torus_target(groups["torus"], methods)
    caption = run.caption(what="median, spread min–max; interleaved rounds after one untimed round")
    tables = []
    for name, g in groups.items():
        label = KIND_LABELS.get(name, MANY_LABEL if not run.quick else "tori on a grid")
        n_ref = next(iter(g["rows"].values()))["ref_hit_px"]
        levels = "segments around the axis" + (" × around the tube" if name in ("torus", "many") else "")
        tables.append(
            f"**{label}** ({n_ref:,} pixels of {w * h:,} hit in the reference; levels: {levels})"
            f"\n\n{group_table(name, g, methods)}\n\n{caption}"
        )
    body = "\n\n".join(tables)
    return f"""## {TITLE}

Each analytic primitive against triangle meshes of it from coarse to fine, at {w} × {h}: one object
filling about {FILL:.0%} of the frame's width per kind (a torus of radii 1 and 0.35; a cylinder of radius
0.6 and height 2 with both caps; a cone frustum of radii 0.8 and 0.3, height 2, with both caps; a disk of
radius 1.2, seen obliquely), and {MANY_LABEL if not run.quick else "tori"} of radii 0.5 and 0.17 on a grid,
their axes random (a tree over many shapes). The meshes have their vertices on the exact surface and
the exact normals there (smooth shading); caps and the disk are flat fans. Every scene is traced by
{" and ".join(f"`{m}`" for m in methods)}, mode `normal` (its result has the primary hit's id, depth
and normal), recursion 1, one ray per pixel centre (`bench/experiments/shapes.py`).

- **memory**: packed bytes = the bytes of the prepared method's packed textures
  (`PreparedMethod.packed`: tree nodes, leaf records, triangle records, shape records); tree bytes = the
  build's own node layout (`stats["bytes"]`);
- **time**: build ms = the frame's `build` stage (tree and record packing), trace ms = its `trace`
  stage (draw and finish), frame ms = the whole `render` call; every configuration once per round;
- **error** against the float64 reference of the ANALYTIC scene (`renderer/oracle/reference.py`,
  `render_reference`): silhouette px = pixels whose hit/miss differs (missing: the reference hits, the
  row does not; extra: the reverse), normal ° = the angle between the normals over the pixels both
  hit. The analytic rows' error is their float32 against float64.

{img}

Tessellated as here — fans for caps and disks, strips of the full height for sides — the meshes are
also the hard case for a tree: every triangle of a fan touches its centre and every strip spans the
height, so their boxes overlap and the trace time of the cylinder, cone and disk grows with the
triangle count; the torus's small quads do not, and its trace grows slowly with its triangles.

**Summary**: each analytic primitive against the coarsest of its tessellations whose silhouette error is
below one pixel (and stays below at every finer level measured); the ratios are of medians.

{summary_table(groups, methods, run.quick)}

{caption}

{body}

**Target** (a torus traced analytically costs less than its tessellation at the level whose
silhouette error is below one pixel at {w} × {h}):

{target}

Raw data: [`{path}`]({path}).
"""


def plot(data: dict, figures: Path, quick: bool = False) -> dict[str, str]:
    """``shapes.png``: silhouette pixels against trace ms, a line per kind through its
    tessellation levels and the analytic primitive as one marker; a panel per method."""
    pyplot = plt()
    methods = data["methods"]
    groups = data["groups"]
    fig, axes = pyplot.subplots(1, len(methods), figsize=(6 * len(methods), 4.5), layout="constrained", squeeze=False)
    colours = dict(zip(groups, ("#1f77b4", "#2ca02c", "#d62728", "#9467bd", "#8c564b"), strict=False))
    for ax, m in zip(axes[0], methods, strict=True):
        for name, g in groups.items():
            rows = _rows(g, m)
            ana, levels = rows[0], rows[1:]
            label = KIND_LABELS.get(name, MANY_LABEL if not quick else "tori on a grid")
            xs = [_ms(r, "trace") for r in levels]
            ys = [r["silhouette_px"] for r in levels]
            ax.plot(xs, ys, "-o", color=colours[name], ms=4, label=f"{label}: triangles")
            for x, y, r in zip(xs, ys, levels, strict=True):
                ax.annotate(f"{r['triangles']:,}", (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
            ax.plot(
                [_ms(ana, "trace")],
                [ana["silhouette_px"]],
                "*",
                color=colours[name],
                ms=14,
                mec="black",
                label=f"{label}: analytic",
            )
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_ylim(bottom=-0.1)
        ax.axhline(1.0, color="#7f7f7f", lw=0.8, ls=":")
        ax.set_xlabel("trace ms (median)")
        ax.set_ylabel("silhouette pixels that differ from the float64 reference")
        ax.set_title(f"{m}: error against cost", fontsize=10)
    log_axis(axes[0][0], "x")
    for ax in axes[0][1:]:
        log_axis(ax, "x")
    legend_outside(fig, axes)
    save(fig, figures, NAME, quick)
    return {
        NAME: "silhouette pixels against trace ms: a line per kind through its tessellations, "
        "the analytic primitive as a star"
    }
