"""The scene model: camera, point lights, materials, spheres and planes.

One contract for renderer, server, client and tests: the scene JSON of
``docs/FORMATS.md``. Everything is validated on construction, so a ``Scene``
that exists is renderable; a bad value raises :class:`SceneError` whose
``field`` names the offending JSON path (the server turns it into a 422).

Conventions (docs/FORMATS.md):
- right-handed world, the camera is a pinhole at ``position`` looking at
  ``target``; ``fov_y`` is the vertical field of view in degrees;
- primitive ids: spheres ``0 … n-1`` in scene order, planes follow; -1 = no hit.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from . import limits
# Largest coordinate magnitude accepted (float32 resolves a unit sphere up to it; limits.py).
from .limits import MAX_COORDINATE  # noqa: F401  (re-exported)

Vec3 = tuple[float, float, float]


class SceneError(ValueError):
    """Invalid scene or render input. ``field`` is the JSON path of the culprit."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def finite_number(value: Any, where: str, *, lo: float | None = None, hi: float | None = None,
            lo_open: bool = False, hi_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SceneError(where, f"expected a number, got {type(value).__name__}")
    x = float(value)
    if not math.isfinite(x):
        raise SceneError(where, f"must be a finite number, got {x}")
    if lo is not None and (x < lo or (lo_open and x == lo)):
        raise SceneError(where, f"must be {'>' if lo_open else '>='} {lo}, got {x}")
    if hi is not None and (x > hi or (hi_open and x == hi)):
        raise SceneError(where, f"must be {'<' if hi_open else '<='} {hi}, got {x}")
    return x


def finite_vec3(value: Any, where: str, *, bound: float = MAX_COORDINATE) -> Vec3:
    if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 3:
        raise SceneError(where, "expected a list of 3 numbers")
    return tuple(finite_number(v, f"{where}[{i}]", lo=-bound, hi=bound) for i, v in enumerate(value))  # type: ignore[return-value]


def _norm(v: Vec3) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def _unit(v: Vec3, where: str) -> Vec3:
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
        object.__setattr__(self, "fov_y", finite_number(self.fov_y, "camera.fov_y", lo=0.0, hi=180.0,
                                                  lo_open=True, hi_open=True))
        _unit(self.up, "camera.up")
        fwd = tuple(t - p for t, p in zip(self.target, self.position))
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
        return {"position": list(self.position), "target": list(self.target),
                "up": list(self.up), "fov_y": self.fov_y}

    @staticmethod
    def from_json(d: Any, where: str = "camera") -> "Camera":
        d = _object(d, where, {"position", "target", "up", "fov_y"})
        kw = {k: d[k] for k in ("position", "target", "up", "fov_y") if k in d}
        return _construct(Camera, kw, where)


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
    def from_json(d: Any, where: str) -> "Light":
        d = _object(d, where, {"position", "color"})
        return _construct(Light, {k: d[k] for k in ("position", "color") if k in d}, where)


@dataclass(frozen=True)
class Material:
    """Whitted/Phong material (Table 4.1). Coefficients are plain weights.

    ``reflective`` (kr) and ``transmissive`` (kt) weight the secondary rays;
    ``ior`` is the refraction index of the inside relative to the outside.
    """
    color: Vec3 = (0.9, 0.3, 0.3)
    ambient: float = 0.3
    diffuse: float = 0.3
    specular: float = 0.1
    shininess: float = 40.0
    reflective: float = 0.3
    transmissive: float = 0.0
    ior: float = 1.0

    def __post_init__(self) -> None:
        col = finite_vec3(self.color, "color")
        for i, c in enumerate(col):
            finite_number(c, f"color[{i}]", lo=0.0, hi=1.0)
        object.__setattr__(self, "color", col)
        for name in ("ambient", "diffuse", "specular", "reflective", "transmissive"):
            object.__setattr__(self, name, finite_number(getattr(self, name), name, lo=0.0, hi=1.0))
        object.__setattr__(self, "shininess", finite_number(self.shininess, "shininess", lo=0.0, hi=limits.MAX_SHININESS))
        object.__setattr__(self, "ior", finite_number(self.ior, "ior", lo=0.0, hi=limits.MAX_IOR, lo_open=True))

    def to_json(self) -> dict:
        return {"color": list(self.color), "ambient": self.ambient, "diffuse": self.diffuse,
                "specular": self.specular, "shininess": self.shininess,
                "reflective": self.reflective, "transmissive": self.transmissive, "ior": self.ior}

    @staticmethod
    def from_json(d: Any, where: str) -> "Material":
        keys = ("color", "ambient", "diffuse", "specular", "shininess", "reflective", "transmissive", "ior")
        d = _object(d, where, set(keys))
        return _construct(Material, {k: d[k] for k in keys if k in d}, where)


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


def _object(d: Any, where: str, allowed: set[str]) -> dict:
    if not isinstance(d, dict):
        raise SceneError(where, "expected an object")
    unknown = set(d) - allowed
    if unknown:
        raise SceneError(f"{where}.{sorted(unknown)[0]}", f"unknown field (allowed: {', '.join(sorted(allowed))})")
    return d


def _construct(cls, kw: dict, where: str):
    try:
        return cls(**kw)
    except SceneError as e:
        # Prefix the nested path so the message names the full JSON field.
        inner = e.field if e.field.startswith(where) else f"{where}.{e.field}"
        raise SceneError(inner, e.message) from None


def _material_index(v: Any, where: str, count: int) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) and not (isinstance(v, float) and v.is_integer()):
        raise SceneError(where, "expected an integer material index")
    i = int(v)
    if not 0 <= i < count:
        raise SceneError(where, f"material index {i} out of range (scene has {count} materials)")
    return i


@dataclass(frozen=True)
class Scene:
    """A whole scene. Spheres are stored as arrays (they can number a million).

    ``sphere_centers`` float64 (n, 3), ``sphere_radii`` float64 (n,),
    ``sphere_materials`` int32 (n,). Arrays are made read-only.
    """
    camera: Camera
    lights: tuple[Light, ...]
    materials: tuple[Material, ...]
    sphere_centers: np.ndarray
    sphere_radii: np.ndarray
    sphere_materials: np.ndarray
    planes: tuple[Plane, ...] = field(default_factory=tuple)

    # Upper bounds that keep one scene from exhausting the service.
    MAX_SPHERES = limits.MAX_SPHERES
    MAX_PLANES = limits.MAX_PLANES
    MAX_LIGHTS = limits.MAX_LIGHTS
    MAX_MATERIALS = limits.MAX_MATERIALS

    def __post_init__(self) -> None:
        if not self.materials:
            raise SceneError("materials", "at least one material is required")
        for name, items, cap in (("lights", self.lights, self.MAX_LIGHTS), ("planes", self.planes, self.MAX_PLANES),
                                 ("materials", self.materials, self.MAX_MATERIALS)):
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
                raise SceneError(f"spheres[{i}].material",
                                 f"material index {int(m[i])} out of range (scene has {len(self.materials)} materials)")
        for i, p in enumerate(self.planes):
            _material_index(p.material, f"planes[{i}].material", len(self.materials))
        m = m.astype(np.int32)
        for a in (c, r, m):
            a.setflags(write=False)
        object.__setattr__(self, "sphere_centers", c)
        object.__setattr__(self, "sphere_radii", r)
        object.__setattr__(self, "sphere_materials", m)
        object.__setattr__(self, "lights", tuple(self.lights))
        object.__setattr__(self, "materials", tuple(self.materials))
        object.__setattr__(self, "planes", tuple(self.planes))

    @property
    def n_spheres(self) -> int:
        return len(self.sphere_radii)

    @property
    def n_primitives(self) -> int:
        return self.n_spheres + len(self.planes)

    def with_camera(self, camera: Camera) -> "Scene":
        """The same scene seen through ``camera`` (a validated Camera): everything else is shared,
        already validated and read-only, so nothing is checked again (O(1), not O(n))."""
        if not isinstance(camera, Camera):
            raise SceneError("camera", f"expected a Camera, got {type(camera).__name__}")
        seen = copy.copy(self)
        object.__setattr__(seen, "camera", camera)
        return seen

    # ---- JSON (docs/FORMATS.md) -------------------------------------------------
    def to_json(self) -> dict:
        spheres = [{"center": c, "radius": r, "material": m} for c, r, m in
                   zip(self.sphere_centers.tolist(), self.sphere_radii.tolist(), self.sphere_materials.tolist())]
        return {"camera": self.camera.to_json(), "lights": [l.to_json() for l in self.lights],
                "materials": [m.to_json() for m in self.materials], "spheres": spheres,
                "planes": [p.to_json() for p in self.planes]}

    @staticmethod
    def from_json(d: Any) -> "Scene":
        d = _object(d, "scene", {"camera", "lights", "materials", "spheres", "planes"})
        camera = Camera.from_json(d.get("camera", {}), "camera")
        lights = [Light.from_json(x, f"lights[{i}]") for i, x in enumerate(_list(d.get("lights", []), "lights"))]
        materials = [Material.from_json(x, f"materials[{i}]")
                     for i, x in enumerate(_list(d.get("materials", []), "materials"))]
        spheres = _list(d.get("spheres", []), "spheres")
        if len(spheres) > Scene.MAX_SPHERES:
            raise SceneError("spheres", f"at most {Scene.MAX_SPHERES} spheres allowed, got {len(spheres)}")
        centers = np.empty((len(spheres), 3))
        radii = np.empty(len(spheres))
        mats = np.empty(len(spheres), dtype=np.int32)
        for i, s in enumerate(spheres):
            s = _object(s, f"spheres[{i}]", {"center", "radius", "material"})
            for k in ("center", "radius"):
                if k not in s:
                    raise SceneError(f"spheres[{i}].{k}", "field required")
            centers[i] = finite_vec3(s["center"], f"spheres[{i}].center")
            radii[i] = finite_number(s["radius"], f"spheres[{i}].radius", lo=0.0, lo_open=True, hi=MAX_COORDINATE)
            mats[i] = _material_index(s.get("material", 0), f"spheres[{i}].material", max(len(materials), 1))
        planes = []
        for i, p in enumerate(_list(d.get("planes", []), "planes")):
            p = _object(p, f"planes[{i}]", {"point", "normal", "material"})
            mi = _material_index(p.get("material", 0), f"planes[{i}].material", max(len(materials), 1))
            kw = {k: p[k] for k in ("point", "normal") if k in p}
            planes.append(_construct(Plane, {**kw, "material": mi}, f"planes[{i}]"))
        return Scene(camera, tuple(lights), tuple(materials), centers, radii, mats, tuple(planes))


def _list(v: Any, where: str) -> Sequence:
    if not isinstance(v, (list, tuple)):
        raise SceneError(where, "expected a list")
    return v
