"""The scene model: camera, point lights, materials, spheres, planes and triangle meshes.

One contract for renderer, server, client and tests: the scene JSON of
``docs/FORMATS.md``. Everything is validated on construction, so a ``Scene``
that exists is renderable; a bad value raises :class:`SceneError` whose
``field`` names the offending JSON path (the server turns it into a 422).

Conventions (docs/FORMATS.md):
- right-handed world, the camera is a pinhole at ``position`` looking at
  ``target``; ``fov_y`` is the vertical field of view in degrees;
- primitive ids: spheres ``0 … n-1`` in scene order, then the planes, then the
  triangles of each mesh in mesh order, then the analytic shapes (cylinders, cones, disks,
  tori: :mod:`renderer.geometry.shapes`); -1 = no hit (:attr:`Scene.triangle_id_base`,
  :attr:`Scene.shape_id_base`);
- a mesh is kept in world space: its optional ``transform`` is applied when it is made,
  so every tracer and tree sees the same float64 vertices (:class:`Mesh`).
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import limits
from ..errors import SceneError, construct, finite_number, json_object  # SceneError, finite_number: re-exported

# Largest coordinate magnitude accepted (float32 resolves a unit sphere up to it; limits.py).
from ..limits import MAX_COORDINATE  # re-exported
from ..materials.kinds import AnyMaterial, material_from_json
from ..materials.phong import Material as Material  # re-exported: where the scene's callers import it
from ..materials.texture import Texture
from .shapes import KINDS as SHAPE_KINDS, Shapes

if TYPE_CHECKING:
    from ..materials.envmap import EnvironmentMap

Vec3 = tuple[float, float, float]


def finite_vec3(value: Any, where: str, *, bound: float = MAX_COORDINATE) -> Vec3:
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 3:
        raise SceneError(where, "expected a list of 3 numbers")
    x, y, z = (finite_number(v, f"{where}[{i}]", lo=-bound, hi=bound) for i, v in enumerate(value))
    return (x, y, z)


def _norm(v: Sequence[float]) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def _unit(v: Sequence[float], where: str) -> Vec3:
    n = _norm(v)
    if not (n > 1e-12) or not math.isfinite(n):
        raise SceneError(where, "must be a non-zero vector")
    return (v[0] / n, v[1] / n, v[2] / n)


@dataclass(frozen=True)
class Camera:
    position: Vec3 = (0.0, 0.0, 100.0)
    target: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov_y: float = 60.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", finite_vec3(self.position, "camera.position"))
        object.__setattr__(self, "target", finite_vec3(self.target, "camera.target"))
        object.__setattr__(self, "up", finite_vec3(self.up, "camera.up"))
        object.__setattr__(
            self, "fov_y", finite_number(self.fov_y, "camera.fov_y", lo=0.0, hi=180.0, lo_open=True, hi_open=True)
        )
        _unit(self.up, "camera.up")
        fwd = tuple(t - p for t, p in zip(self.target, self.position, strict=True))
        if not (_norm(fwd) > 0.0):
            raise SceneError("camera.target", "must differ from camera.position")
        f = _unit(fwd, "camera.target")
        u = _unit(self.up, "camera.up")
        c = np.cross(f, u)
        if not (np.linalg.norm(c) > 1e-9):
            raise SceneError("camera.up", "must not be parallel to the viewing direction")

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Orthonormal (right, true_up, forward), float64. Rays: forward + x·right + y·up."""
        p = np.array(self.position, dtype=np.float64)
        t = np.array(self.target, dtype=np.float64)
        forward = (t - p) / np.linalg.norm(t - p)
        right = np.cross(forward, np.array(self.up, dtype=np.float64))
        right /= np.linalg.norm(right)
        true_up = np.cross(right, forward)
        return right, true_up, forward

    def to_json(self) -> dict:
        return {"position": list(self.position), "target": list(self.target), "up": list(self.up), "fov_y": self.fov_y}

    @staticmethod
    def from_json(d: Any, where: str = "camera") -> Camera:
        d = json_object(d, where, {"position", "target", "up", "fov_y"})
        kw = {k: d[k] for k in ("position", "target", "up", "fov_y") if k in d}
        return construct(Camera, kw, where)


@dataclass(frozen=True)
class Light:
    """A point light. ``color`` is its RGB intensity (white = 1, 1, 1)."""

    position: Vec3 = (0.0, 40.0, 0.0)
    color: Vec3 = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", finite_vec3(self.position, "position"))
        col = finite_vec3(self.color, "color")
        for i, c in enumerate(col):
            finite_number(c, f"color[{i}]", lo=0.0, hi=limits.MAX_LIGHT_INTENSITY)
        object.__setattr__(self, "color", col)

    def to_json(self) -> dict:
        return {"position": list(self.position), "color": list(self.color)}

    @staticmethod
    def from_json(d: Any, where: str) -> Light:
        d = json_object(d, where, {"position", "color"})
        return construct(Light, {k: d[k] for k in ("position", "color") if k in d}, where)


@dataclass(frozen=True)
class Plane:
    point: Vec3 = (0.0, -20.0, 0.0)
    normal: Vec3 = (0.0, 1.0, 0.0)
    material: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", finite_vec3(self.point, "point"))
        object.__setattr__(self, "normal", _unit(finite_vec3(self.normal, "normal"), "normal"))

    def to_json(self) -> dict:
        return {"point": list(self.point), "normal": list(self.normal), "material": self.material}


def _material_index(v: Any, where: str, count: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) and not (isinstance(v, float) and v.is_integer()):
        raise SceneError(where, "expected an integer material index")
    i = int(v)
    if not 0 <= i < count:
        raise SceneError(where, f"material index {i} out of range (scene has {count} materials)")
    return i


# ---- meshes ---------------------------------------------------------------------------------
_NUMBER_TYPES = (int, float, np.floating, np.integer)


def _first_bad_row(value: Sequence, where: str, what: str) -> None:
    """Raise for the first row of ``value`` that is not a list of 3 numbers (the slow path
    that names the culprit; the fast path found that one exists)."""
    for i, row in enumerate(value):
        if not isinstance(row, (list, tuple, np.ndarray)) or len(row) != 3:
            raise SceneError(f"{where}[{i}]", f"expected a list of 3 {what}")
        for j, x in enumerate(row):
            if isinstance(x, bool) or not isinstance(x, _NUMBER_TYPES):
                raise SceneError(f"{where}[{i}][{j}]", f"expected a number, got {type(x).__name__}")
    raise SceneError(where, "expected a list of [x, y, z] rows")  # not reached: a caller saw a bad row


def rows3(value: Any, where: str, what: str = "numbers") -> np.ndarray:
    """A list of ``[a, b, c]`` rows (or an (n, 3) array) as a float64 (n, 3) array; SceneError
    names the first bad row (``where[i]``) — not finite numbers are checked by the caller.

    The common case (a well-formed JSON list) is converted at C speed: row lengths and
    element types are collected with ``map``, and only a malformed input is walked in Python.
    """
    if isinstance(value, np.ndarray):
        if value.size == 0:
            return np.zeros((0, 3))
        if value.ndim != 2 or value.shape[1] != 3 or value.dtype.kind not in "iuf":
            raise SceneError(where, f"expected an array of shape (n, 3) of numbers, got {value.dtype} {value.shape}")
        return np.ascontiguousarray(value, dtype=np.float64)
    if not isinstance(value, (list, tuple)):
        raise SceneError(where, "expected a list")
    if not value:
        return np.zeros((0, 3))
    try:
        lengths = set(map(len, value))
        types = set(map(type, itertools.chain.from_iterable(value)))
    except TypeError:
        _first_bad_row(value, where, what)
    if lengths != {3} or bool in types or not all(issubclass(t, _NUMBER_TYPES) for t in types):
        _first_bad_row(value, where, what)
    try:
        return np.array(value, dtype=np.float64).reshape(-1, 3)
    except OverflowError:  # an integer beyond float64 (JSON allows any)
        for i, row in enumerate(value):
            try:
                np.array(row, dtype=np.float64)
            except OverflowError:
                raise SceneError(f"{where}[{i}]", "a number too large for float64") from None
        raise


def _bad_rows(mask: np.ndarray) -> int:
    """Index of the first True row of a (n,) mask."""
    return int(np.argmax(mask))


# A mesh's optional vertex attributes: name, numbers per vertex, bounds of each number.
VERTEX_ATTRIBUTES = (
    ("uvs", 2, -MAX_COORDINATE, MAX_COORDINATE),
    ("uvs1", 2, -MAX_COORDINATE, MAX_COORDINATE),
    ("colors", 4, 0.0, 1.0),
    ("tangents", 4, -MAX_COORDINATE, MAX_COORDINATE),
)


def vertex_attribute(value: Any, where: str, n_vertices: int, width: int, lo: float, hi: float) -> np.ndarray:
    """float64 (n_vertices, width), read-only: a vertex attribute checked for its shape, finite
    numbers and bounds (SceneError names the first bad row)."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(where, f"expected a list of {n_vertices} rows of {width} numbers") from None
    if a.shape != (n_vertices, width):
        raise SceneError(where, f"{width} numbers per vertex: expected ({n_vertices}, {width}), got {a.shape}")
    bad = np.asarray(~np.isfinite(a).all(axis=1) | (a < lo).any(axis=1) | (a > hi).any(axis=1))
    if bad.any():
        i = _bad_rows(bad)
        raise SceneError(f"{where}[{i}]", f"must be finite numbers within {lo:g} … {hi:g}, got {a[i].tolist()}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh in world space. Validated on construction; arrays are made read-only.

    ``vertices`` float64 (V, 3), world units. ``triangles`` int32 (T, 3), indices into
    ``vertices``; a triangle ``(i, j, k)`` faces the side from which it is seen
    counter-clockwise: its geometric normal is ``(v_j − v_i) × (v_k − v_i)``, outward for a
    closed mesh wound that way (OBJ, STL, glTF convention). ``material`` indexes the scene's
    materials. ``normals`` float64 (V, 3) or None: per-vertex shading normals (smooth
    shading, interpolated barycentrically); non-zero, normalised when shading. None: flat
    shading by the geometric normal. Vertex attributes for materials, each optional:
    ``uvs`` / ``uvs1`` float64 (V, 2), texture coordinate sets 0 and 1 (glTF's TEXCOORD_0/1: U
    right, V down the image); ``colors`` float64 (V, 4), linear RGBA in [0, 1] multiplying the
    base colour (glTF's COLOR_0, PLY's and OBJ's vertex colours); ``tangents`` float64 (V, 4),
    xyz the direction of +U, w = ±1 the handedness of the bitangent ``w · (n × t)`` (glTF's
    TANGENT; generated for normal maps where absent).

    A triangle of exactly zero area (float64 cross product of its edges = 0, e.g. a repeated
    index) is kept, so that ids do not move, and is never hit; :attr:`n_degenerate` counts
    them. Build one from JSON-like input, with a transform, with :func:`make_mesh`.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    material: int = 0
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    uvs1: np.ndarray | None = None
    colors: np.ndarray | None = None
    tangents: np.ndarray | None = None

    def __post_init__(self) -> None:
        v = rows3(self.vertices, "vertices")
        bad = ~np.isfinite(v).all(axis=1) | (np.abs(v) > MAX_COORDINATE).any(axis=1)
        if bad.any():
            i = _bad_rows(bad)
            raise SceneError(
                f"vertices[{i}]", f"must be finite numbers within ±{MAX_COORDINATE:g}, got {v[i].tolist()}"
            )
        if len(v) > limits.MAX_MESH_VERTICES:
            raise SceneError("vertices", f"at most {limits.MAX_MESH_VERTICES} vertices per mesh, got {len(v)}")
        t = rows3(self.triangles, "triangles", "vertex indices")
        if len(t) > limits.MAX_TRIANGLES:
            raise SceneError("triangles", f"at most {limits.MAX_TRIANGLES} triangles allowed, got {len(t)}")
        bad = ~(
            np.isfinite(t).all(axis=1)
            & (t == np.round(t)).all(axis=1)
            & (t >= 0).all(axis=1)
            & (t < len(v)).all(axis=1)
        )
        if bad.any():
            i = _bad_rows(bad)
            got = [int(x) if math.isfinite(x) and float(x).is_integer() else x for x in t[i].tolist()]
            raise SceneError(
                f"triangles[{i}]",
                f"vertex indices must be integers in 0 … {len(v) - 1} (the mesh has {len(v)} vertices), got {got}",
            )
        t = t.astype(np.int32)
        n = None
        if self.normals is not None:
            n = rows3(self.normals, "normals")
            if len(n) != len(v):
                raise SceneError("normals", f"one normal per vertex: expected {len(v)}, got {len(n)}")
            bad = ~np.isfinite(n).all(axis=1) | (np.abs(n) > MAX_COORDINATE).any(axis=1) | ~(n != 0.0).any(axis=1)
            if bad.any():
                i = _bad_rows(bad)
                raise SceneError(f"normals[{i}]", f"must be a finite non-zero vector, got {n[i].tolist()}")
            n.setflags(write=False)
        if isinstance(self.material, bool) or not isinstance(self.material, (int, np.integer)) or self.material < 0:
            raise SceneError("material", f"expected a material index (an integer ≥ 0), got {self.material!r}")
        for a in (v, t):
            a.setflags(write=False)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", t)
        object.__setattr__(self, "normals", n)
        object.__setattr__(self, "material", int(self.material))
        for name, width, lo, hi in VERTEX_ATTRIBUTES:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, vertex_attribute(value, name, len(v), width, lo, hi))
        if self.tangents is not None and not np.isin(self.tangents[:, 3], (-1.0, 1.0)).all():
            i = _bad_rows(~np.isin(self.tangents[:, 3], (-1.0, 1.0)))
            raise SceneError(f"tangents[{i}][3]", f"the handedness w must be 1 or -1, got {self.tangents[i, 3]}")

    @property
    def attributes(self) -> dict[str, np.ndarray]:
        """The vertex attributes it has, by name (``uvs``, ``uvs1``, ``colors``, ``tangents``)."""
        return {name: getattr(self, name) for name, *_ in VERTEX_ATTRIBUTES if getattr(self, name) is not None}

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    @property
    def smooth(self) -> bool:
        return self.normals is not None

    @cached_property
    def corners(self) -> np.ndarray:
        """float64 (T, 3, 3): the world-space vertices of each triangle (corner k = vertex k)."""
        return self.vertices[self.triangles]

    @cached_property
    def degenerate(self) -> np.ndarray:
        """bool (T,): triangles of exactly zero area (never hit)."""
        c = self.corners
        cross = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
        return ~(cross != 0.0).any(axis=1)

    @property
    def n_degenerate(self) -> int:
        return int(self.degenerate.sum())

    def with_vertices(self, vertices: np.ndarray, normals: np.ndarray | None = None) -> Mesh:
        """The same triangles, material and attributes on moved vertices (an animation's pose)."""
        return Mesh(vertices, self.triangles, self.material, normals, **self.attributes)

    def to_json(self) -> dict:
        """World-space JSON (the transform it was made with is already applied)."""
        d = {"vertices": self.vertices.tolist(), "triangles": self.triangles.tolist(), "material": self.material}
        if self.normals is not None:
            d["normals"] = self.normals.tolist()
        d.update({name: a.tolist() for name, a in self.attributes.items()})
        return d

    @staticmethod
    def from_json(d: Any, where: str) -> Mesh:
        d = json_object(
            d,
            where,
            {"vertices", "triangles", "material", "normals", "transform", *(a for a, *_ in VERTEX_ATTRIBUTES)},
        )
        for k in ("vertices", "triangles"):
            if k not in d:
                raise SceneError(f"{where}.{k}", "field required")
        m = d.get("material", 0)
        if (
            isinstance(m, bool)
            or not isinstance(m, (int, np.integer))
            and not (isinstance(m, float) and m.is_integer())
        ):
            raise SceneError(f"{where}.material", "expected an integer material index")
        try:
            return make_mesh(
                d["vertices"],
                d["triangles"],
                int(m),
                d.get("normals"),
                d.get("transform"),
                **{a: d[a] for a, *_ in VERTEX_ATTRIBUTES if a in d},
            )
        except SceneError as e:
            raise SceneError(f"{where}.{e.field}", e.message) from None


def affine_transform(value: Any, where: str = "transform") -> np.ndarray:
    """A 4 × 4 row-major affine transform (last row ``[0, 0, 0, 1]``, invertible 3 × 3 part) as
    float64 (4, 4); SceneError names the bad entry."""
    m = np.asarray(value, dtype=object) if not isinstance(value, np.ndarray) else value
    if m.shape != (4, 4):
        raise SceneError(where, "expected 4 rows of 4 numbers (row-major, last row [0, 0, 0, 1])")
    out = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            out[i, j] = finite_number(m[i, j], f"{where}[{i}][{j}]")
    if not np.array_equal(out[3], [0.0, 0.0, 0.0, 1.0]):
        raise SceneError(f"{where}[3]", f"the last row must be [0, 0, 0, 1] (an affine map), got {out[3].tolist()}")
    det = float(np.linalg.det(out[:3, :3]))
    if not (math.isfinite(det) and det != 0.0):
        raise SceneError(where, "the 3 × 3 part must be invertible (it flattens the mesh)")
    return out


def make_mesh(
    vertices: Any,
    triangles: Any,
    material: int = 0,
    normals: Any = None,
    transform: Any = None,
    **attributes: Any,
) -> Mesh:
    """A :class:`Mesh` from JSON-like lists or arrays, ``transform`` (4 × 4 row-major affine)
    applied: ``v' = A v + b``, normals by the inverse transpose of ``A``, and — when ``A``
    mirrors (det < 0) — every triangle's winding reversed, so that a closed mesh stays
    wound outwards. Bounds (±MAX_COORDINATE) hold for the transformed vertices. SceneError
    fields are relative to the mesh (``vertices[3]``, ``transform[0][2]``). ``attributes``: the
    vertex attributes of :class:`Mesh` by name; tangents turn with ``A`` (their handedness flips
    where ``A`` mirrors)."""
    if transform is None:
        return Mesh(vertices, triangles, material, normals, **attributes)
    m = affine_transform(transform)
    v = rows3(vertices, "vertices")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = _bad_rows(bad)
        raise SceneError(f"vertices[{i}]", f"must be finite numbers, got {v[i].tolist()}")
    a, b = m[:3, :3], m[:3, 3]
    with np.errstate(over="ignore", invalid="ignore"):
        moved = v @ a.T + b
    n = None
    if normals is not None:
        n = rows3(normals, "normals")
        with np.errstate(over="ignore", invalid="ignore"):
            n = n @ np.linalg.inv(a)  # (A⁻ᵀ n)ᵀ = nᵀ A⁻¹
    t = triangles
    mirrors = np.linalg.det(a) < 0
    if mirrors:
        t = rows3(triangles, "triangles", "vertex indices")[:, [0, 2, 1]]
    if attributes.get("tangents") is not None:
        tan = vertex_attribute(attributes["tangents"], "tangents", len(v), 4, -MAX_COORDINATE, MAX_COORDINATE)
        with np.errstate(over="ignore", invalid="ignore"):
            turned = np.concatenate([tan[:, :3] @ a.T, tan[:, 3:] * (-1.0 if mirrors else 1.0)], axis=1)
        attributes = {**attributes, "tangents": turned}
    try:
        return Mesh(moved, t, material, n, **attributes)
    except SceneError as e:
        if e.field.startswith("vertices["):
            raise SceneError(e.field, f"{e.message} after the transform") from None
        raise


@dataclass(frozen=True)
class Scene:
    """A whole scene. Spheres are stored as arrays (they can number a million).

    ``sphere_centers`` float64 (n, 3), ``sphere_radii`` float64 (n,),
    ``sphere_materials`` int32 (n,). Arrays are made read-only. ``meshes``: world-space
    :class:`Mesh` es; their triangles, flattened in id order, are :attr:`triangle_corners`
    (and the per-triangle arrays beside it).

    Ids (docs/FORMATS.md): spheres ``0 … n−1``, planes ``n … n+P−1``, then triangle ``j``
    of the flattened list is ``triangle_id_base + j`` (``triangle_id_base = n + P``), then
    analytic shape ``k`` of ``shapes`` is ``shape_id_base + k`` (``shape_id_base = n + P + T``).
    """

    camera: Camera
    lights: tuple[Light, ...]
    materials: tuple[AnyMaterial, ...]
    sphere_centers: np.ndarray
    sphere_radii: np.ndarray
    sphere_materials: np.ndarray
    planes: tuple[Plane, ...] = field(default_factory=tuple)
    meshes: tuple[Mesh, ...] = field(default_factory=tuple)
    environment: Vec3 = (0.0, 0.0, 0.0)  # the radiance a ray that meets nothing sees (black: none)
    environment_map: EnvironmentMap | None = None  # … or an image (renderer/materials/envmap.py; the colour black)
    shapes: Shapes = field(default_factory=Shapes.empty)  # cylinders, cones, disks, tori (renderer/geometry/shapes.py)
    textures: tuple[Texture, ...] = ()  # the images materials read (renderer/materials/texture.py)

    # Upper bounds that keep one scene from exhausting the service.
    MAX_SPHERES = limits.MAX_SPHERES
    MAX_PLANES = limits.MAX_PLANES
    MAX_LIGHTS = limits.MAX_LIGHTS
    MAX_MATERIALS = limits.MAX_MATERIALS
    MAX_MESHES = limits.MAX_MESHES
    MAX_TRIANGLES = limits.MAX_TRIANGLES

    def __post_init__(self) -> None:
        if not self.materials:
            raise SceneError("materials", "at least one material is required")
        for name, items, cap in (
            ("lights", self.lights, self.MAX_LIGHTS),
            ("planes", self.planes, self.MAX_PLANES),
            ("materials", self.materials, self.MAX_MATERIALS),
            ("meshes", self.meshes, self.MAX_MESHES),
            ("textures", self.textures, limits.MAX_TEXTURES),
        ):
            if len(items) > cap:
                raise SceneError(name, f"at most {cap} allowed, got {len(items)}")
        c = np.ascontiguousarray(self.sphere_centers, dtype=np.float64).reshape(-1, 3)
        r = np.ascontiguousarray(self.sphere_radii, dtype=np.float64).reshape(-1)
        m = np.ascontiguousarray(self.sphere_materials).reshape(-1)
        if not (len(c) == len(r) == len(m)):
            raise SceneError("spheres", "centres, radii and materials differ in length")
        if len(c) > self.MAX_SPHERES:
            raise SceneError("spheres", f"at most {self.MAX_SPHERES} spheres allowed, got {len(c)}")
        if len(c):
            bad = ~np.isfinite(c).all(axis=1) | (np.abs(c) > MAX_COORDINATE).any(axis=1)
            if bad.any():
                i = int(np.argmax(bad))
                raise SceneError(f"spheres[{i}].center", f"must be finite numbers within ±{MAX_COORDINATE:g}")
            bad = ~(np.isfinite(r) & (r > 0) & (r <= MAX_COORDINATE))
            if bad.any():
                i = int(np.argmax(bad))
                raise SceneError(f"spheres[{i}].radius", f"must be a finite number > 0, got {r[i]}")
            if m.dtype.kind not in "iu":
                if m.dtype.kind != "f" or not np.all(np.isfinite(m)) or not np.all(m == np.round(m)):
                    raise SceneError("spheres.material", "expected integer material indices")
            m = m.astype(np.int64)
            bad = (m < 0) | (m >= len(self.materials))
            if bad.any():
                i = int(np.argmax(bad))
                raise SceneError(
                    f"spheres[{i}].material",
                    f"material index {int(m[i])} out of range (scene has {len(self.materials)} materials)",
                )
        for i, p in enumerate(self.planes):
            _material_index(p.material, f"planes[{i}].material", len(self.materials))
        for i, mesh in enumerate(self.meshes):
            if not isinstance(mesh, Mesh):
                raise SceneError(f"meshes[{i}]", f"expected a Mesh, got {type(mesh).__name__}")
            _material_index(mesh.material, f"meshes[{i}].material", len(self.materials))
        n_tri = sum(mesh.n_triangles for mesh in self.meshes)
        if n_tri > self.MAX_TRIANGLES:
            raise SceneError("meshes", f"at most {self.MAX_TRIANGLES} triangles per scene, got {n_tri}")
        if not isinstance(self.shapes, Shapes):
            raise SceneError("shapes", f"expected Shapes, got {type(self.shapes).__name__}")
        bad = self.shapes.material >= len(self.materials)
        if bad.any():
            i = int(np.argmax(bad))
            raise SceneError(
                f"{self.shapes.where(i)}.material",
                f"material index {int(self.shapes.material[i])} out of range "
                f"(scene has {len(self.materials)} materials)",
            )
        bad = self.shapes.material < 0
        if bad.any():
            i = int(np.argmax(bad))
            raise SceneError(f"{self.shapes.where(i)}.material", f"must be >= 0, got {int(self.shapes.material[i])}")
        m = m.astype(np.int32)
        for a in (c, r, m):
            a.setflags(write=False)
        object.__setattr__(self, "sphere_centers", c)
        object.__setattr__(self, "sphere_radii", r)
        object.__setattr__(self, "sphere_materials", m)
        object.__setattr__(self, "lights", tuple(self.lights))
        object.__setattr__(self, "materials", tuple(self.materials))
        object.__setattr__(self, "planes", tuple(self.planes))
        object.__setattr__(self, "meshes", tuple(self.meshes))
        env = finite_vec3(self.environment, "environment.color")
        for i, x in enumerate(env):
            finite_number(x, f"environment.color[{i}]", lo=0.0, hi=limits.MAX_EMISSION)
        object.__setattr__(self, "environment", env)
        if self.environment_map is not None:
            from ..materials.envmap import EnvironmentMap

            if not isinstance(self.environment_map, EnvironmentMap):
                raise SceneError(
                    "environment.image", f"expected an EnvironmentMap, got {type(self.environment_map).__name__}"
                )
            if any(env):
                raise SceneError("environment", "a color or an image, not both")
        self._check_textures()

    def _check_textures(self) -> None:
        """Textures are Texture objects within MAX_TEXTURE_TEXELS together, and every texture a
        material names exists."""
        object.__setattr__(self, "textures", tuple(self.textures))
        for i, t in enumerate(self.textures):
            if not isinstance(t, Texture):
                raise SceneError(f"textures[{i}]", f"expected a Texture, got {type(t).__name__}")
        texels = sum(t.width * t.height for t in self.textures)
        if texels > limits.MAX_TEXTURE_TEXELS:
            raise SceneError(
                "textures",
                f"{texels:,} texels in all; at most {limits.MAX_TEXTURE_TEXELS:,} per scene (MAX_TEXTURE_TEXELS)",
            )
        for i, m in enumerate(self.materials):
            for slot in getattr(m, "texture_slots", lambda: ())():
                index = getattr(m, f"{slot}_texture")
                if index >= len(self.textures):
                    raise SceneError(
                        f"materials[{i}].{slot}_texture",
                        f"texture index {index} out of range (scene has {len(self.textures)} textures)",
                    )

    @property
    def n_spheres(self) -> int:
        return len(self.sphere_radii)

    @property
    def n_triangles(self) -> int:
        """Triangles of all meshes (degenerate ones included: they keep their ids)."""
        return sum(m.n_triangles for m in self.meshes)

    @property
    def n_degenerate_triangles(self) -> int:
        return sum(m.n_degenerate for m in self.meshes)

    @property
    def n_shapes(self) -> int:
        """Analytic shapes (cylinders, cones, disks, tori)."""
        return len(self.shapes)

    @property
    def n_tree_primitives(self) -> int:
        """Spheres + triangles + analytic shapes: what an acceleration tree holds (planes are traced
        beside it), and what ``method=auto`` chooses by (:func:`renderer.frame.plan.plan_method`)."""
        return self.n_spheres + self.n_triangles + self.n_shapes

    @property
    def n_primitives(self) -> int:
        """Spheres + planes + triangles + analytic shapes: one past the largest primitive id."""
        return self.n_spheres + len(self.planes) + self.n_triangles + self.n_shapes

    @property
    def shape_id_base(self) -> int:
        """The id of the first analytic shape: after the spheres, the planes and the triangles."""
        return self.n_spheres + len(self.planes) + self.n_triangles

    @property
    def triangle_id_base(self) -> int:
        """The id of the first triangle: after the spheres and the planes."""
        return self.n_spheres + len(self.planes)

    def _flat(self, per_mesh, shape: tuple, dtype) -> np.ndarray:
        parts = [per_mesh(m) for m in self.meshes]
        out = np.concatenate(parts) if parts else np.zeros((0, *shape), dtype)
        out = np.ascontiguousarray(out, dtype=dtype)
        out.setflags(write=False)
        return out

    @cached_property
    def triangle_corners(self) -> np.ndarray:
        """float64 (T, 3, 3): every triangle's world-space vertices, in id order."""
        return self._flat(lambda m: m.corners, (3, 3), np.float64)

    @cached_property
    def triangle_materials(self) -> np.ndarray:
        """int32 (T,): each triangle's material."""
        return self._flat(lambda m: np.full(m.n_triangles, m.material), (), np.int32)

    @cached_property
    def triangle_mesh(self) -> np.ndarray:
        """int32 (T,): the mesh each triangle belongs to."""
        counts = [m.n_triangles for m in self.meshes]
        out = np.repeat(np.arange(len(counts), dtype=np.int32), counts) if counts else np.zeros(0, np.int32)
        out.setflags(write=False)
        return out

    @cached_property
    def triangle_smooth(self) -> np.ndarray:
        """bool (T,): the triangle's mesh has vertex normals (smooth shading)."""
        return self._flat(lambda m: np.full(m.n_triangles, m.smooth), (), bool)

    @cached_property
    def triangle_normals(self) -> np.ndarray:
        """float64 (T, 3, 3): the vertex normals at each corner as given (0 for flat meshes)."""
        return self._flat(
            lambda m: m.normals[m.triangles] if m.smooth else np.zeros((m.n_triangles, 3, 3)), (3, 3), np.float64
        )

    @cached_property
    def triangle_degenerate(self) -> np.ndarray:
        """bool (T,): zero-area triangles (never hit)."""
        return self._flat(lambda m: m.degenerate, (), bool)

    def mesh_triangle_range(self, i: int) -> range:
        """Positions in the flattened triangle list of mesh ``i``'s triangles."""
        start = sum(m.n_triangles for m in self.meshes[:i])
        return range(start, start + self.meshes[i].n_triangles)

    def with_geometry(
        self,
        sphere_centers: np.ndarray,
        sphere_radii: np.ndarray,
        sphere_materials: np.ndarray,
        meshes: Sequence[Mesh] | None = None,
        shapes: Shapes | None = None,
    ) -> Scene:
        """The same camera, lights, materials and planes with other spheres (and meshes and
        analytic shapes: the same ones unless given), validated."""
        return Scene(
            self.camera,
            self.lights,
            self.materials,
            sphere_centers,
            sphere_radii,
            sphere_materials,
            self.planes,
            tuple(self.meshes if meshes is None else meshes),
            self.environment,
            self.environment_map,
            self.shapes if shapes is None else shapes,
            self.textures,
        )

    def with_camera(self, camera: Camera) -> Scene:
        """The same scene seen through ``camera`` (a validated Camera): everything else is shared,
        already validated and read-only, so nothing is checked again (O(1), not O(n))."""
        if not isinstance(camera, Camera):
            raise SceneError("camera", f"expected a Camera, got {type(camera).__name__}")
        seen = copy.copy(self)
        object.__setattr__(seen, "camera", camera)
        return seen

    # ---- JSON (docs/FORMATS.md) -------------------------------------------------
    def to_json(self) -> dict:
        spheres = [
            {"center": c, "radius": r, "material": m}
            for c, r, m in zip(
                self.sphere_centers.tolist(), self.sphere_radii.tolist(), self.sphere_materials.tolist(), strict=True
            )
        ]
        out = {
            "camera": self.camera.to_json(),
            "lights": [light.to_json() for light in self.lights],
            "materials": [m.to_json() for m in self.materials],
            "spheres": spheres,
            "planes": [p.to_json() for p in self.planes],
        }
        if self.meshes:  # absent when there are none: a sphere scene's JSON is as it always was
            out["meshes"] = [m.to_json() for m in self.meshes]
        out.update(self.shapes.to_json())  # each kind's key only when it has shapes
        if any(self.environment):  # absent when black, as it was before environments
            out["environment"] = {"color": list(self.environment)}
        if self.environment_map is not None:
            out["environment"] = self.environment_map.to_json()
        if self.textures:
            out["textures"] = [t.to_json() for t in self.textures]
        return out

    @staticmethod
    def from_json(d: Any, images: Mapping[str, np.ndarray] | None = None) -> Scene:
        """The scene of scene JSON; ``images``: the texels of the environment images a reference
        may name (an uploaded image's, beside the scene in the session store)."""
        d = json_object(
            d,
            "scene",
            {"camera", "lights", "materials", "spheres", "planes", "meshes", "environment", "textures", *SHAPE_KINDS},
        )
        env = json_object(d.get("environment", {}), "environment", {"color", "image", "scale", "rotation_deg"})
        environment = finite_vec3(env.get("color", [0.0, 0.0, 0.0]), "environment.color")
        environment_map = environment_map_from_json(env, images)
        camera = Camera.from_json(d.get("camera", {}), "camera")
        lights = [Light.from_json(x, f"lights[{i}]") for i, x in enumerate(_list(d.get("lights", []), "lights"))]
        materials = [
            material_from_json(x, f"materials[{i}]") for i, x in enumerate(_list(d.get("materials", []), "materials"))
        ]
        raw_textures = _list(d.get("textures", []), "textures")
        if len(raw_textures) > limits.MAX_TEXTURES:
            raise SceneError("textures", f"at most {limits.MAX_TEXTURES} textures allowed, got {len(raw_textures)}")
        textures = tuple(Texture.from_json(x, f"textures[{i}]") for i, x in enumerate(raw_textures))
        spheres = _list(d.get("spheres", []), "spheres")
        if len(spheres) > Scene.MAX_SPHERES:
            raise SceneError("spheres", f"at most {Scene.MAX_SPHERES} spheres allowed, got {len(spheres)}")
        centers = np.empty((len(spheres), 3))
        radii = np.empty(len(spheres))
        mats = np.empty(len(spheres), dtype=np.int32)
        for i, s in enumerate(spheres):
            s = json_object(s, f"spheres[{i}]", {"center", "radius", "material"})
            for k in ("center", "radius"):
                if k not in s:
                    raise SceneError(f"spheres[{i}].{k}", "field required")
            centers[i] = finite_vec3(s["center"], f"spheres[{i}].center")
            radii[i] = finite_number(s["radius"], f"spheres[{i}].radius", lo=0.0, lo_open=True, hi=MAX_COORDINATE)
            mats[i] = _material_index(s.get("material", 0), f"spheres[{i}].material", max(len(materials), 1))
        planes = []
        for i, p in enumerate(_list(d.get("planes", []), "planes")):
            p = json_object(p, f"planes[{i}]", {"point", "normal", "material"})
            mi = _material_index(p.get("material", 0), f"planes[{i}].material", max(len(materials), 1))
            kw = {k: p[k] for k in ("point", "normal") if k in p}
            planes.append(construct(Plane, {**kw, "material": mi}, f"planes[{i}]"))
        raw = _list(d.get("meshes", []), "meshes")
        if len(raw) > Scene.MAX_MESHES:
            raise SceneError("meshes", f"at most {Scene.MAX_MESHES} meshes allowed, got {len(raw)}")
        meshes = []
        for i, x in enumerate(raw):
            mesh = Mesh.from_json(x, f"meshes[{i}]")
            _material_index(mesh.material, f"meshes[{i}].material", max(len(materials), 1))
            meshes.append(mesh)
        shapes = Shapes.from_json(d)
        return Scene(
            camera,
            tuple(lights),
            tuple(materials),
            centers,
            radii,
            mats,
            tuple(planes),
            tuple(meshes),
            environment,
            environment_map,
            shapes,
            textures,
        )


def environment_map_from_json(env: dict, images: Mapping[str, np.ndarray] | None = None) -> EnvironmentMap | None:
    """The image of an ``environment`` object (None without ``image``): ``"sky"`` is the procedural
    sky (renderer/materials/sky.py), any other reference one of ``images``."""
    from ..materials.envmap import SKY_REF, EnvironmentMap

    if "image" not in env:
        for k in ("scale", "rotation_deg"):
            if k in env:
                raise SceneError(f"environment.{k}", "only with an image")
        return None
    ref = env["image"]
    if not isinstance(ref, str):
        raise SceneError("environment.image", f"expected a string, got {type(ref).__name__}")
    if ref == SKY_REF:
        from ..materials.sky import sky_texels

        texels = sky_texels()
    elif images is not None and ref in images:
        texels = images[ref]
    else:
        raise SceneError(
            "environment.image",
            f"unknown image {ref[:64]!r}: 'sky', or the reference of an image uploaded to the session "
            "(PUT /api/sessions/{id}/environment)",
        )
    return EnvironmentMap(ref, texels, env.get("scale", 1.0), env.get("rotation_deg", 0.0))


def _list(v: Any, where: str) -> Sequence:
    if not isinstance(v, (list, tuple)):
        raise SceneError(where, "expected a list")
    return v
