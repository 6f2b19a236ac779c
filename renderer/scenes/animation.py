"""Animated scenes: motion models, posing at a time and a BART-Museum-like generator;
the two-level method that suits them lives in :mod:`renderer.accel.twolevel`.

A frame of an animation is rendered by handing :class:`AnimatedScene` to
``GLRenderer.render`` with the settings ``time``, ``update`` and ``update_threshold``
(:class:`~renderer.config.settings.RenderSettings`): the renderer poses the scene and asks
the method to update its tree (:mod:`renderer.scenes.tree_update`).

Motion models, after Reiter §2.4.1 (Wald et al.'s classes):

- :class:`RigidGroup` — hierarchical motion: a group of spheres moves as one body,
  rotating about an axis through a pivot and oscillating along a vector;
- :class:`Deformable` — coherent local motion with a fixed topology: every sphere is
  displaced by a travelling wave of its rest position, so neighbours move alike;
- :class:`Incoherent` — each sphere flies on its own straight line inside a box
  (reflected at its walls) and respawns at a random place every ``lifetime``
  seconds; with ``absent > 0`` it also *disappears* for that fraction of each
  lifetime (the scene's sphere count changes, which forces a rebuild).

A motion covers a contiguous range of sphere ids ``first … first + count − 1``, or — with
``mesh: m`` instead of ``first``/``count`` — the vertices of mesh ``m``: a rigid motion moves
the mesh as one body (its normals turn with it), a deformable one displaces each vertex by
the wave of its rest position (smooth normals are then recomputed from the deformed
triangles); an incoherent motion moves spheres only (flying vertices would tear a mesh
apart). With ``over: "shapes"`` the range ``first … first + count − 1`` is one of analytic
shapes (:mod:`renderer.geometry.shapes`, in their id order) instead: a rigid motion moves their origins
as it moves sphere centres and turns their axes with the body, a deformable one displaces
each origin by the wave of its rest origin (the shape itself keeps its form and axis); an
incoherent motion moves spheres only here too. Ranges of different motions over the same
kind must not overlap, nor two motions move one mesh; spheres, meshes and shapes no motion
covers are static.
:func:`pose` evaluates all motions at a time ``t ≥ 0`` and returns the posed
:class:`~renderer.geometry.scene.Scene` (absent spheres removed, so later ids shift down) together
with, per posed sphere, its id in the animated scene and whether it moves.

Validation follows the scene model: every bad value raises :class:`SceneError` whose
``field`` names the JSON path (``motions[2].amplitude``, ``time``), and
nothing is applied before everything is valid. A motion is rejected when it could
move a sphere beyond ``MAX_COORDINATE`` or produce a non-finite number at any time.

JSON: a scene JSON (docs/FORMATS.md) may carry ``"motions": [...]``; :func:`animated_scene_from_json`
reads it. Each motion is an object with ``kind`` (``rigid`` | ``deformable`` |
``incoherent``), ``first`` and ``count`` (or ``mesh``) and the fields of its class below.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from .. import limits
from ..geometry.scene import (
    MAX_COORDINATE,
    Camera,
    Light,
    Material,
    Plane,
    Scene,
    SceneError,
    finite_number,
    finite_vec3,
)
from ..geometry.shapes import reach as shape_reach
from ..limits import MAX_TIME  # re-exported: seconds, the largest time a scene can be posed at
from .scenarios import RED, TRANSPARENT


def _num(v: Any, where: str, lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> float:
    """A finite number in [lo, hi] (renderer.geometry.scene's validation, positional bounds)."""
    return finite_number(v, where, lo=lo, hi=hi, lo_open=lo_open)


def _int(v: Any, where: str, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise SceneError(where, f"expected an integer, got {v!r}")
    if not lo <= int(v) <= hi:
        raise SceneError(where, f"must be in {lo} … {hi}, got {v}")
    return int(v)


def _vec(v: Any, where: str, bound: float = MAX_COORDINATE) -> tuple[float, float, float]:
    return finite_vec3(v, where, bound=bound)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def _splitmix(x: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser, vectorised (uint64 in, uint64 out)."""
    with np.errstate(over="ignore"):
        x = (x + np.uint64(0x9E3779B97F4A7C15)).astype(np.uint64)
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


def _uniform(seed: int, i: np.ndarray, k: np.ndarray, salt: int) -> np.ndarray:
    """Deterministic uniforms in [0, 1) from (seed, sphere, cycle, salt)."""
    with np.errstate(over="ignore"):
        h = _splitmix(np.uint64(seed) * np.uint64(0x100000001B3) + np.uint64(salt))  # type: ignore[arg-type]  # a scalar: the same arithmetic
        h = _splitmix(h ^ i.astype(np.uint64))
        h = _splitmix(h ^ (k.astype(np.int64).astype(np.uint64) * np.uint64(0x9E3779B1)))
    return (h >> np.uint64(11)).astype(np.float64) / float(1 << 53)


# ------------------------------------------------------------------------ motions


@dataclass(frozen=True)
class RigidGroup:
    """Spheres ``first … first+count−1`` move as one rigid body.

    centre(t) = pivot + R(axis, angular_velocity · t) (c₀ − pivot) + amplitude · sin(2π t / period)
    """

    first: int
    count: int
    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)
    angular_velocity: float = 0.5
    amplitude: tuple[float, float, float] = (0.0, 0.0, 0.0)
    period: float = 4.0
    mesh: int | None = None
    over: str = "spheres"  # what first … first + count − 1 counts: "spheres" or "shapes"
    kind = "rigid"

    def validate(self, where: str) -> RigidGroup:
        axis = _vec(self.axis, f"{where}.axis")
        if not math.sqrt(sum(a * a for a in axis)) > 1e-12:
            raise SceneError(f"{where}.axis", "must be a non-zero vector")
        return replace(
            self,
            pivot=_vec(self.pivot, f"{where}.pivot"),
            axis=axis,
            angular_velocity=_num(
                self.angular_velocity,
                f"{where}.angular_velocity",
                -limits.MAX_ANGULAR_VELOCITY,
                limits.MAX_ANGULAR_VELOCITY,
            ),
            amplitude=_vec(self.amplitude, f"{where}.amplitude"),
            period=_num(self.period, f"{where}.period", 0.0, limits.MAX_PERIOD, lo_open=True),
        )

    def reach(self, c0: np.ndarray) -> float:
        """The largest coordinate magnitude any sphere centre can take."""
        p = np.asarray(self.pivot)
        r = float(np.linalg.norm(c0 - p, axis=1).max(initial=0.0))
        return float(np.abs(p).max() + r + np.linalg.norm(self.amplitude))

    def rotation(self, t: float) -> np.ndarray:
        """The body's rotation at time t (3 × 3): it also turns a mesh's normals."""
        return _rotation(np.asarray(self.axis, dtype=np.float64), self.angular_velocity * t)

    def centers(self, c0: np.ndarray, t: float, ids: np.ndarray) -> np.ndarray:
        p = np.asarray(self.pivot)
        rot = self.rotation(t)
        return p + (c0 - p) @ rot.T + np.asarray(self.amplitude) * math.sin(2 * math.pi * t / self.period)

    def alive(self, t: float, ids: np.ndarray) -> np.ndarray:
        return np.ones(len(ids), dtype=bool)


@dataclass(frozen=True)
class Deformable:
    """Coherent local motion: a travelling wave displaces each sphere by at most ``amplitude`` per axis.

    centre(t) = c₀ + amplitude · (sin(k(y₀+z₀) − ωt), sin(k(z₀+x₀) − ωt + 2.1), sin(k(x₀+y₀) − ωt + 4.2)),
    k = 2π / wavelength, ω = k · speed.
    """

    first: int
    count: int
    amplitude: float = 1.0
    wavelength: float = 10.0
    speed: float = 4.0
    mesh: int | None = None
    over: str = "spheres"
    kind = "deformable"

    def validate(self, where: str) -> Deformable:
        return replace(
            self,
            amplitude=_num(self.amplitude, f"{where}.amplitude", 0.0, MAX_COORDINATE),
            wavelength=_num(self.wavelength, f"{where}.wavelength", 0.0, limits.MAX_WAVELENGTH, lo_open=True),
            speed=_num(self.speed, f"{where}.speed", -limits.MAX_SPEED, limits.MAX_SPEED),
        )

    def reach(self, c0: np.ndarray) -> float:
        return float(np.abs(c0).max(initial=0.0) + self.amplitude)

    def centers(self, c0: np.ndarray, t: float, ids: np.ndarray) -> np.ndarray:
        k = 2 * math.pi / self.wavelength
        w = k * self.speed * t
        x, y, z = c0[:, 0], c0[:, 1], c0[:, 2]
        d = np.stack([np.sin(k * (y + z) - w), np.sin(k * (z + x) - w + 2.1), np.sin(k * (x + y) - w + 4.2)], axis=1)
        return c0 + self.amplitude * d

    def alive(self, t: float, ids: np.ndarray) -> np.ndarray:
        return np.ones(len(ids), dtype=bool)


@dataclass(frozen=True)
class Incoherent:
    """Each sphere flies alone inside ``[box_min, box_max]`` (reflected at the walls) at ``speed``,
    respawning at a random place and direction every ``lifetime`` seconds (its own phase);
    for the last ``absent`` fraction of each lifetime it is gone from the scene.
    The first lifetime starts at the sphere's rest position."""

    first: int
    count: int
    box_min: tuple[float, float, float] = (-15.0, -15.0, -15.0)
    box_max: tuple[float, float, float] = (15.0, 15.0, 15.0)
    speed: float = 5.0
    lifetime: float = 2.0
    absent: float = 0.0
    seed: int = 0
    mesh: int | None = None
    over: str = "spheres"
    kind = "incoherent"

    def validate(self, where: str) -> Incoherent:
        lo = _vec(self.box_min, f"{where}.box_min")
        hi = _vec(self.box_max, f"{where}.box_max")
        for a in range(3):
            if not lo[a] < hi[a]:
                raise SceneError(f"{where}.box_max[{a}]", f"must be > box_min[{a}] ({lo[a]:g}), got {hi[a]:g}")
        return replace(
            self,
            box_min=lo,
            box_max=hi,
            speed=_num(self.speed, f"{where}.speed", 0.0, limits.MAX_SPEED),
            lifetime=_num(self.lifetime, f"{where}.lifetime", 0.0, limits.MAX_LIFETIME, lo_open=True),
            absent=_num(self.absent, f"{where}.absent", 0.0, limits.MAX_ABSENT),
            seed=_int(self.seed, f"{where}.seed", 0, limits.MAX_MOTION_SEED),
        )

    def reach(self, c0: np.ndarray) -> float:
        return float(max(np.abs(self.box_min).max(), np.abs(self.box_max).max()))

    def centers(self, c0: np.ndarray, t: float, ids: np.ndarray) -> np.ndarray:
        lo, hi = np.asarray(self.box_min), np.asarray(self.box_max)
        phase = _uniform(self.seed, ids, np.zeros(len(ids)), 1) * self.lifetime
        u = t + phase
        cycle = np.floor(u / self.lifetime)
        tau = np.where(cycle == 0, t, u - cycle * self.lifetime)  # time since this lifetime began
        start = lo + (hi - lo) * np.stack([_uniform(self.seed, ids, cycle, 2 + a) for a in range(3)], axis=1)
        start = np.where((cycle == 0)[:, None], c0, start)
        g = np.stack([_uniform(self.seed, ids, cycle, 5 + a) for a in range(3)], axis=1)
        v = np.stack(
            [
                np.sqrt(-2 * np.log(1 - g[:, 0])) * np.cos(2 * math.pi * g[:, 1]),
                np.sqrt(-2 * np.log(1 - g[:, 0])) * np.sin(2 * math.pi * g[:, 1]),
                2 * g[:, 2] - 1,
            ],
            axis=1,
        )
        v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12) * self.speed
        x = start + v * tau[:, None]
        size = hi - lo
        w = np.mod(x - lo, 2 * size)  # reflect at the walls
        return lo + np.where(w <= size, w, 2 * size - w)

    def alive(self, t: float, ids: np.ndarray) -> np.ndarray:
        if self.absent <= 0:
            return np.ones(len(ids), dtype=bool)
        phase = _uniform(self.seed, ids, np.zeros(len(ids)), 1) * self.lifetime
        u = t + phase
        tau = u - np.floor(u / self.lifetime) * self.lifetime
        return tau < (1.0 - self.absent) * self.lifetime


MOTION_KINDS = {"rigid": RigidGroup, "deformable": Deformable, "incoherent": Incoherent}
Motion = RigidGroup | Deformable | Incoherent


def motion_to_json(m: Motion) -> dict:
    """A motion's JSON: ``first``/``count`` for a sphere range (``over: "shapes"``: a range of
    analytic shapes; absent for spheres), ``mesh`` for a mesh (never both)."""
    d: dict[str, Any] = {"kind": m.kind}
    skip = {"first", "count", "over"} if m.mesh is not None else {"mesh"}
    if m.over == "spheres":
        skip.add("over")
    for f in fields(m):
        if f.name in skip:
            continue
        v = getattr(m, f.name)
        d[f.name] = list(v) if isinstance(v, tuple) else v
    return d


def motion_from_json(d: Any, where: str) -> Motion:
    if not isinstance(d, dict):
        raise SceneError(where, "expected an object")
    kind = d.get("kind")
    if kind not in MOTION_KINDS:
        raise SceneError(f"{where}.kind", f"unknown motion kind {kind!r}; one of {', '.join(MOTION_KINDS)}")
    cls = MOTION_KINDS[kind]
    names = {f.name for f in fields(cls)}
    unknown = set(d) - names - {"kind"}
    if unknown:
        raise SceneError(f"{where}.{sorted(unknown)[0]}", f"unknown field (allowed: kind, {', '.join(sorted(names))})")
    if d.get("mesh") is not None:
        both = [k for k in ("first", "count", "over") if k in d]
        if both:
            raise SceneError(
                f"{where}.{both[0]}", "a motion moves either a mesh (mesh) or a sphere range (first, count), not both"
            )
        d = {**d, "first": 0, "count": 0}
    for req in ("first", "count"):
        if req not in d:
            raise SceneError(f"{where}.{req}", "field required (or mesh: the index of a mesh to move)")
    kw = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items() if k != "kind"}
    return cls(**kw)


# ------------------------------------------------------------------ animated scene


@dataclass(frozen=True)
class AnimatedScene:
    """A scene (rest pose) and the motions of some of its spheres; validated on construction."""

    scene: Scene
    motions: tuple = ()

    def __post_init__(self) -> None:
        n = self.scene.n_spheres
        out: list[Motion] = []
        covered = np.zeros(n, dtype=bool)
        meshes = np.zeros(len(self.scene.meshes), dtype=bool)
        shapes = np.zeros(self.scene.n_shapes, dtype=bool)
        for i, m in enumerate(self.motions):
            where = f"motions[{i}]"
            if not isinstance(m, (RigidGroup, Deformable, Incoherent)):
                raise SceneError(where, "expected a motion")
            if m.over not in ("spheres", "shapes"):
                raise SceneError(f"{where}.over", f"one of spheres, shapes; got {m.over!r}")
            if m.over == "shapes" and m.mesh is None:
                out.append(self._shape_motion(m, where, shapes))
                continue
            if m.mesh is not None:
                if not self.scene.meshes:
                    raise SceneError(f"{where}.mesh", "the scene has no meshes")
                k = _int(m.mesh, f"{where}.mesh", 0, len(self.scene.meshes) - 1)
                if isinstance(m, Incoherent):
                    raise SceneError(
                        f"{where}.mesh",
                        "an incoherent motion moves spheres only (its vertices would "
                        "fly apart); use rigid or deformable for a mesh",
                    )
                if meshes[k]:
                    raise SceneError(f"{where}.mesh", f"mesh {k} is moved by another motion")
                meshes[k] = True
                m = m.validate(where)
                reach = m.reach(self.scene.meshes[k].vertices)
                if not reach <= MAX_COORDINATE:
                    raise SceneError(
                        where, f"would move mesh {k} to coordinates of {reach:.3g}, beyond ±{MAX_COORDINATE:g}"
                    )
                out.append(m)
                continue
            first = _int(m.first, f"{where}.first", 0, max(n - 1, 0))
            _int(m.count, f"{where}.count", 0, n - first)
            m = m.validate(where)
            sl = slice(m.first, m.first + m.count)
            if covered[sl].any():
                raise SceneError(f"{where}.first", "the sphere range overlaps another motion's")
            covered[sl] = True
            reach = m.reach(self.scene.sphere_centers[sl]) + float(self.scene.sphere_radii[sl].max(initial=0.0))
            if not reach <= MAX_COORDINATE:
                raise SceneError(where, f"would move spheres to coordinates of {reach:.3g}, beyond ±{MAX_COORDINATE:g}")
            out.append(m)
        object.__setattr__(self, "motions", tuple(out))
        covered.setflags(write=False)
        meshes.setflags(write=False)
        shapes.setflags(write=False)
        object.__setattr__(self, "_moving", covered)
        object.__setattr__(self, "_moving_meshes", meshes)
        object.__setattr__(self, "_moving_shapes", shapes)

    def _shape_motion(self, m: Motion, where: str, covered: np.ndarray) -> Motion:
        """A motion over a range of analytic shapes, validated; marks the range in ``covered``."""
        n = self.scene.n_shapes
        if isinstance(m, Incoherent):
            raise SceneError(
                f"{where}.over", "an incoherent motion moves spheres only; use rigid or deformable for shapes"
            )
        if not n:
            raise SceneError(f"{where}.over", "the scene has no analytic shapes")
        first = _int(m.first, f"{where}.first", 0, n - 1)
        _int(m.count, f"{where}.count", 0, n - first)
        m = m.validate(where)
        sl = slice(m.first, m.first + m.count)
        if covered[sl].any():
            raise SceneError(f"{where}.first", "the shape range overlaps another motion's")
        covered[sl] = True
        origins = self.scene.shapes.params[sl, 0:3]
        reach = m.reach(origins) + float(shape_reach(self.scene.shapes)[sl].max(initial=0.0))
        if not reach <= MAX_COORDINATE:
            raise SceneError(where, f"would move shapes to coordinates of {reach:.3g}, beyond ±{MAX_COORDINATE:g}")
        return m

    @property
    def moving(self) -> np.ndarray:
        """bool (n,): spheres some motion covers."""
        return self._moving  # type: ignore[attr-defined]  # set by __post_init__, not a field

    @property
    def moving_meshes(self) -> np.ndarray:
        """bool (meshes,): meshes some motion moves."""
        return self._moving_meshes  # type: ignore[attr-defined]  # set by __post_init__, not a field

    @property
    def moving_shapes(self) -> np.ndarray:
        """bool (analytic shapes,): shapes some motion moves."""
        return self._moving_shapes  # type: ignore[attr-defined]  # set by __post_init__, not a field

    @property
    def camera(self) -> Camera:
        return self.scene.camera

    @property
    def n_spheres(self) -> int:
        """Spheres at rest (a pose may hide some)."""
        return self.scene.n_spheres

    @property
    def n_tree_primitives(self) -> int:
        """Tree primitives at rest (:attr:`Scene.n_tree_primitives`): what ``method=auto`` chooses by for
        every frame of the animation, whichever spheres a pose hides."""
        return self.scene.n_tree_primitives

    def with_camera(self, camera: Camera) -> AnimatedScene:
        """The same animation seen through ``camera`` (the motions are not validated again)."""
        seen = object.__new__(AnimatedScene)
        object.__setattr__(seen, "scene", self.scene.with_camera(camera))
        object.__setattr__(seen, "motions", self.motions)
        object.__setattr__(seen, "_moving", self._moving)  # type: ignore[attr-defined]  # set by __post_init__, not a field
        object.__setattr__(seen, "_moving_meshes", self._moving_meshes)  # type: ignore[attr-defined]  # set by __post_init__, not a field
        object.__setattr__(seen, "_moving_shapes", self._moving_shapes)  # type: ignore[attr-defined]  # set by __post_init__, not a field
        return seen

    def to_json(self) -> dict:
        d = self.scene.to_json()
        d["motions"] = [motion_to_json(m) for m in self.motions]
        return d


def animated_scene_from_json(d: Any) -> AnimatedScene:
    """Scene JSON with an optional ``motions`` list → :class:`AnimatedScene` (SceneError on bad input)."""
    if not isinstance(d, dict):
        raise SceneError("scene", "expected an object")
    rest = {k: v for k, v in d.items() if k != "motions"}
    scene = Scene.from_json(rest)
    raw = d.get("motions", [])
    if not isinstance(raw, (list, tuple)):
        raise SceneError("motions", "expected a list")
    motions = []
    for i, m in enumerate(raw):
        try:
            motions.append(motion_from_json(m, f"motions[{i}]"))
        except TypeError as e:
            raise SceneError(f"motions[{i}]", str(e)) from None
    return AnimatedScene(scene, tuple(motions))


@dataclass
class PosedFrame:
    """A posed scene, the animated-scene id of each of its spheres, and which of its tree
    primitives move: ``moving`` is bool over the posed spheres, then the triangles, then the
    analytic shapes (:mod:`renderer.accel.primitives`' index space)."""

    scene: Scene
    ids: np.ndarray
    moving: np.ndarray
    time: float
    pose_ms: float


def _posed_mesh(mesh, m: Motion, t: float):
    """A mesh moved by motion ``m`` at time t: rigidly (normals turned), or deformed (smooth
    normals recomputed from the deformed triangles, area-weighted)."""
    from ..geometry.meshes import vertex_normals

    v = m.centers(mesh.vertices, t, np.arange(len(mesh.vertices), dtype=np.int64))
    normals = None
    if mesh.normals is not None:
        normals = mesh.normals @ m.rotation(t).T if isinstance(m, RigidGroup) else vertex_normals(v, mesh.triangles)
    return mesh.with_vertices(v, normals)


def pose(anim: AnimatedScene, t: float) -> PosedFrame:
    """The scene at time ``t`` (seconds, ≥ 0)."""
    t0 = _time.perf_counter()
    t = _num(t, "time", 0.0, MAX_TIME)
    base = anim.scene
    c = base.sphere_centers.copy()
    alive = np.ones(base.n_spheres, dtype=bool)
    meshes = list(base.meshes)
    origins = base.shapes.params[:, 0:3].copy()
    axes = base.shapes.params[:, 4:7].copy()
    for m in anim.motions:
        if m.mesh is not None:
            meshes[m.mesh] = _posed_mesh(base.meshes[m.mesh], m, t)
            continue
        if m.over == "shapes":
            sl = slice(m.first, m.first + m.count)
            origins[sl] = m.centers(base.shapes.params[sl, 0:3], t, np.arange(m.first, m.first + m.count))
            if isinstance(m, RigidGroup):  # the body turns: so do its shapes' axes
                axes[sl] = base.shapes.params[sl, 4:7] @ m.rotation(t).T
            continue
        sl = slice(m.first, m.first + m.count)
        ids = np.arange(m.first, m.first + m.count, dtype=np.int64)
        c[sl] = m.centers(base.sphere_centers[sl], t, ids)
        alive[sl] = m.alive(t, ids)
    keep = np.flatnonzero(alive)
    scene = base.with_geometry(
        c[keep],
        base.sphere_radii[keep],
        base.sphere_materials[keep],
        meshes,
        base.shapes.with_placement(origins, axes) if anim.moving_shapes.any() else base.shapes,
    )
    tri_moving = (
        np.repeat(anim.moving_meshes, [mesh.n_triangles for mesh in base.meshes]) if base.meshes else np.zeros(0, bool)
    )
    moving = np.concatenate([anim.moving[keep], tri_moving, np.asarray(anim.moving_shapes, dtype=bool)])
    return PosedFrame(scene, keep, moving, t, (_time.perf_counter() - t0) * 1e3)


# ---------------------------------------------------------------- Museum generator

WALL = Material(
    color=(0.75, 0.72, 0.65),
    ambient=0.25,
    diffuse=0.6,
    specular=0.05,
    shininess=10.0,
    reflective=0.15,
    transmissive=0.0,
    ior=1.0,
)
SCULPTURE, GLASS = RED, TRANSPARENT  # Table 4.1's materials (renderer.scenes.scenarios)
MUSEUM_KINDS = ("rigid", "deformable", "incoherent", "mixed")


def museum_static(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The static room: a back wall and two side walls of spheres and six pillars (576 spheres)."""
    out_c, out_r = [], []
    u = np.linspace(-18.0, 18.0, 12)
    v = np.linspace(-18.0, 18.0, 12)
    uu, vv = np.meshgrid(u, v)
    out_c.append(np.stack([uu.ravel(), vv.ravel(), np.full(uu.size, -22.0)], axis=1))  # back wall
    out_c.append(np.stack([np.full(uu.size, -22.0), vv.ravel(), uu.ravel()], axis=1))  # left wall
    out_c.append(np.stack([np.full(uu.size, 22.0), vv.ravel(), uu.ravel()], axis=1))  # right wall
    out_r.append(np.full(3 * uu.size, 1.6))
    for x in (-14.0, 14.0):  # pillars
        for z in (-12.0, 0.0, 12.0):
            y = np.linspace(-19.0, 19.0, 24)
            out_c.append(np.stack([np.full(24, x), y, np.full(24, z)], axis=1))
            out_r.append(np.full(24, 0.9))
    return np.concatenate(out_c), np.concatenate(out_r)


MUSEUM_ROOM_SPHERES = len(museum_static()[0])  # 576


def museum(n_moving: int, kind: str = "deformable", seed: int = 0, absent: float = 0.2) -> AnimatedScene:
    """A BART-Museum-like scene: ``n_moving`` animated spheres (a sculpture in a ball of
    radius 8 above the floor's centre) in a static room of 576 spheres and the floor plane.

    ``kind``: ``rigid`` (four groups spinning about different axes and bobbing),
    ``deformable`` (one travelling wave), ``incoherent`` (every sphere flies and respawns,
    absent for the fraction ``absent`` of each lifetime: 0 keeps the count fixed) or
    ``mixed`` (a third of each). Static spheres come first
    (ids 0 … 575), the moving ones after them.
    """
    if kind not in MUSEUM_KINDS:
        raise SceneError("kind", f"unknown motion kind {kind!r}; one of {', '.join(MUSEUM_KINDS)}")
    n_moving = _int(n_moving, "n", 0, limits.MAX_MUSEUM_MOVING)
    rng = np.random.default_rng(seed)
    sc, sr = museum_static(seed)
    ns = len(sc)
    centre = np.array([0.0, -4.0, 0.0])
    g = rng.normal(size=(n_moving, 3))
    g /= np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    mc = centre + g * (8.0 * rng.uniform(0, 1, (n_moving, 1)) ** (1 / 3))
    mr = np.full(n_moving, float(np.clip(5.0 / max(n_moving, 1) ** (1 / 3), 0.03, 1.5)))
    c = np.concatenate([sc, mc])
    r = np.concatenate([sr, mr])
    mats = np.concatenate([np.zeros(ns, np.int32), np.where(np.arange(n_moving) % 4 == 3, 2, 1).astype(np.int32)])
    scene = Scene(
        camera=Camera((0.0, 6.0, 62.0), (0.0, -3.0, 0.0), (0.0, 1.0, 0.0), 55.0),
        lights=(Light((0.0, 40.0, 20.0), (1.0, 1.0, 1.0)),),
        materials=(WALL, SCULPTURE, GLASS),
        sphere_centers=c,
        sphere_radii=r,
        sphere_materials=mats,
        planes=(Plane((0.0, -20.0, 0.0), (0.0, 1.0, 0.0), 0),),
    )

    def rigid(first: int, count: int) -> list:
        out, q = [], max(count // 4, 1)
        axes = [(0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0)]
        for j in range(4):
            a = first + j * q
            b = first + count if j == 3 else min(first + (j + 1) * q, first + count)
            if b > a:
                out.append(
                    RigidGroup(
                        a,
                        b - a,
                        pivot=tuple(centre),
                        axis=axes[j],
                        angular_velocity=0.6 + 0.3 * j,
                        amplitude=(2.0 * (j - 1.5), 1.5, 0.0),
                        period=3.0 + j,
                    )
                )
        return out

    def deformable(first: int, count: int) -> list:
        return [Deformable(first, count, amplitude=1.5, wavelength=9.0, speed=4.0)] if count else []

    def incoherent(first: int, count: int) -> list:
        return (
            [
                Incoherent(
                    first,
                    count,
                    box_min=(-12.0, -16.0, -10.0),
                    box_max=(12.0, 8.0, 10.0),
                    speed=6.0,
                    lifetime=2.5,
                    absent=absent,
                    seed=seed,
                )
            ]
            if count
            else []
        )

    makers = {"rigid": rigid, "deformable": deformable, "incoherent": incoherent}
    if kind == "mixed":
        t = n_moving // 3
        motions = rigid(ns, t) + deformable(ns + t, t) + incoherent(ns + 2 * t, n_moving - 2 * t)
    else:
        motions = makers[kind](ns, n_moving)
    return AnimatedScene(scene, tuple(motions))
