"""Float64 NumPy reference ray tracer: the ground truth the GPU tracer is tested against.

It implements ``docs/SHADING.md`` literally and independently of the shader:

- primary rays, row 0 = top row, pixel index ``y * W + x`` (row-major);
- brute force over every sphere, plane and triangle, nearest ``t > 0``, ties to the lower id;
- triangles by the watertight test of Woop, Benthin & Wald (2013), written here on its own
  (:func:`triangle_hits`; SHADING.md, "Triangles");
- analytic shapes (cylinders, cones, disks, tori) by :func:`renderer.geometry.shapes.intersect`, their
  closed forms and the torus's bracketed quartic (SHADING.md, "Analytic shapes");
- secondary rays start exactly at the hit point, self-intersection excluded by the
  primitive-exclusion / far-root rule (an analytic shape: its root nearest 0 is dropped;
  no epsilon anywhere);
- Whitted/Phong shading with one shadow ray per light per hit, reflection and
  refraction up to ``settings.max_recursion_depth`` levels (1 = primary only);
- every output mode of SHADING.md.

Units: world units for positions and ``t`` (distance along a unit direction), colours
are linear RGB. All geometry is float64; only the returned arrays are float32/int32.

Structure. The recursive ray tree is evaluated iteratively: a :class:`RayBatch` is
one generation (recursion level) of rays for some pixels, each ray carrying the pixel
it contributes to and its weight (the product of ``kr``/``kt`` along its path), so
``colour(pixel) = Σ weight · local`` over all rays of the tree. Batches are processed
depth first from a stack, and are never larger than ``chunk_rays``, so memory stays
bounded however deep the tree. Intersection works on tiles of rays × spheres; a cheap
conservative cull (BLAS products, with a rigorous rounding margin) picks the few
candidate pairs, and only those go through the robust quadratic. Triangles are culled
the same way by their bounding spheres, and the candidates go through the exact test.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np

from ..accel.bih import build_for_scene
from ..accel.bih_traverse import traverse
from ..config.settings import RenderSettings
from ..geometry.scene import Camera, Scene
from ..geometry.shapes import Shapes, intersect as shape_intersect, normals as shape_normals
from ..image.result import RenderResult
from ..materials import pbr_brdf
from ..materials.envmap import EnvironmentMap
from ..materials.kinds import AnyMaterial
from ..materials.pbr import ALPHA_MODES, WHITTED_AMBIENT, PbrMaterial
from ..materials.phong import Material
from ..modes import AVERAGED_MODES, RECURSION_COLORS, depth_grey, heat_image, primid_colors

_EPS = float(np.finfo(np.float64).eps)
# Rays intersected together (one reduction); bounds the candidate lists.
_RAY_TILE = 1024
# Surfaces one ray may pass (alpha, culled back faces) before its hit is taken as it stands: the
# GPU's loop has no such bound, but a scene needing more than this is no test scene.
MAX_PASSES = 64
# Ray × sphere pairs per cull tile: ~6 float64 temporaries of this size (≈ 2 MiB each).
_PAIR_BUDGET = 1 << 18


# --------------------------------------------------------------------------- rays


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of two (k, 3) arrays."""
    return np.einsum("ij,ij->i", a, b)


def _pixel_rays(camera: Camera, width: int, height: int, pix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Primary rays of the pixels with row-major indices ``pix`` (SHADING.md § Primary rays)."""
    right, up, forward = camera.basis()
    x = (pix % width).astype(np.float64)
    y = (pix // width).astype(np.float64)
    s = np.tan(np.radians(camera.fov_y) / 2.0)
    u = (2.0 * (x + 0.5) / width - 1.0) * s * width / height
    v = (1.0 - 2.0 * (y + 0.5) / height) * s  # row 0 is the top row: v > 0
    d = forward[None, :] + u[:, None] * right[None, :] + v[:, None] * up[None, :]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.array(camera.position, dtype=np.float64), d.shape).copy()
    return o, d


def primary_rays(camera: Camera, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """float64 origins (H*W, 3) and unit directions (H*W, 3), row-major, row 0 = top (SHADING.md).

    Ray ``y * W + x`` goes through the centre of pixel column ``x``, row ``y``.
    """
    return _pixel_rays(camera, width, height, np.arange(width * height, dtype=np.int64))


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror directions ``d − 2 dot(d, n) n`` row-wise; not renormalised (as SHADING.md)."""
    return d - 2.0 * _dot(d, n)[:, None] * n


def transmitted_directions(
    d: np.ndarray, normal: np.ndarray, ior: np.ndarray, entering: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Transmitted directions (SHADING.md § Secondary rays) and the total-internal-reflection mask.

    ``d`` unit incoming directions (k, 3), ``normal`` the outward normals N (k, 3), ``ior``
    (k,) inside relative to outside. Entering (``dot(d, N) < 0``, or ``entering`` where
    given — a smooth triangle enters by its geometric normal and bends about its shading
    normal): η = 1/ior, n = N; else η = ior, n = −N. Under total internal reflection the ray
    is the mirror of ``d`` about n.
    """
    if entering is None:
        entering = _dot(d, normal) < 0.0
    eta = np.where(entering, 1.0 / ior, ior)
    n = np.where(entering[:, None], normal, -normal)
    cos_i = -_dot(d, n)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    tir = k < 0.0
    t = eta[:, None] * d + (eta * cos_i - np.sqrt(np.maximum(k, 0.0)))[:, None] * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    out = np.where(tir[:, None], reflect(d, n), t)
    return out, tir


# ----------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class _Balls:
    """Spheres for the conservative cull (the scene's spheres, or bounding balls of triangles)."""

    centers_t: np.ndarray  # (3, k) contiguous, for the cull's matrix products
    cc: np.ndarray  # (k,) |c|²
    r2: np.ndarray  # (k,) r²
    extent: float  # max |c| + max r: bounds the cull's rounding error

    @staticmethod
    def of(c: np.ndarray, r: np.ndarray) -> _Balls:
        extent = float(np.sqrt(_dot(c, c).max()) + r.max()) if len(r) else 0.0
        return _Balls(np.ascontiguousarray(c.T), _dot(c, c), r * r, extent)

    def __len__(self) -> int:
        return len(self.r2)


@dataclass(frozen=True)
class _Triangles:
    """The triangles flattened in id order (``base + j``), world space, float64."""

    base: int  # id of triangle 0 (spheres + planes)
    v0: np.ndarray  # (T, 3) corners …
    v1: np.ndarray
    v2: np.ndarray
    geo_normal: np.ndarray  # (T, 3) unit (v1 − v0) × (v2 − v0); 0 for a degenerate triangle
    vertex_normals: np.ndarray  # (T, 3, 3) unit shading normals at the corners (smooth ones)
    smooth: np.ndarray  # (T,) bool
    valid: np.ndarray  # (T,) bool: not degenerate (a zero-area triangle is never hit)
    balls: _Balls  # bounding balls for the cull

    @staticmethod
    def of(scene: Scene) -> _Triangles:
        c = np.asarray(scene.triangle_corners, dtype=np.float64).reshape(-1, 3, 3)
        v0, v1, v2 = (np.ascontiguousarray(c[:, k]) for k in range(3))
        cross = np.cross(v1 - v0, v2 - v0)
        length = np.linalg.norm(cross, axis=1)
        valid = ~np.asarray(scene.triangle_degenerate, dtype=bool) & (length > 0)
        geo = cross / np.where(length > 0, length, 1.0)[:, None]
        vn = np.asarray(scene.triangle_normals, dtype=np.float64).reshape(-1, 3, 3)
        vlen = np.linalg.norm(vn, axis=2, keepdims=True)
        vn = vn / np.where(vlen > 0, vlen, 1.0)
        centre = (v0 + v1 + v2) / 3.0
        # The ball must hold the float64 triangle: the largest corner distance, inflated far
        # beyond its rounding error (relative 1e-16), so no vertex lies on the ball's surface.
        radius = (
            np.sqrt(np.max([_dot(v - centre, v - centre) for v in (v0, v1, v2)], axis=0)) if len(c) else np.zeros(0)
        )
        radius = radius * (1.0 + 1e-9) + 1e-300
        return _Triangles(
            scene.triangle_id_base,
            v0,
            v1,
            v2,
            geo,
            vn,
            np.asarray(scene.triangle_smooth, bool),
            valid,
            _Balls.of(centre, radius),
        )

    def __len__(self) -> int:
        return len(self.v0)


@dataclass(frozen=True)
class _Geometry:
    """The scene flattened into float64 arrays, indexed by primitive / material id."""

    n: int  # spheres; ids 0 … n−1, planes n …, triangles after the planes
    centers: np.ndarray  # (n, 3)
    centers_t: np.ndarray  # (3, n) contiguous, for the cull's matrix products
    cc: np.ndarray  # (n,) |c|²
    r2: np.ndarray  # (n,) r²
    radii: np.ndarray  # (n,)
    extent: float  # max |c| + max r: bounds the cull's rounding error
    plane_points: np.ndarray  # (P, 3)
    plane_normals: np.ndarray  # (P, 3) unit
    prim_material: np.ndarray  # (n + P + T,) material index of each primitive
    color: np.ndarray  # (M, 3) material tables …
    ka: np.ndarray
    kd: np.ndarray
    ks: np.ndarray
    shininess: np.ndarray
    kr: np.ndarray
    kt: np.ndarray
    ior: np.ndarray
    light_pos: np.ndarray  # (L, 3)
    light_col: np.ndarray  # (L, 3)
    tris: _Triangles
    emission: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (M, 3) radiance per material
    environment: np.ndarray = field(default_factory=lambda: np.zeros(3))  # what a ray meeting nothing sees
    environment_map: EnvironmentMap | None = None  # … or this image (its float64 bilinear lookup)
    shapes: Shapes = field(default_factory=Shapes.empty)  # analytic shapes, ids shape_base …
    shape_base: int = 0  # id of shape 0 (spheres + planes + triangles)
    # The glTF metallic-roughness materials (pbr True; their Phong entries above are 0 but ior):
    # factors only (textures are not read here).
    pbr: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    base: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    metallic: np.ndarray = field(default_factory=lambda: np.zeros(0))
    roughness: np.ndarray = field(default_factory=lambda: np.zeros(0))
    transmission: np.ndarray = field(default_factory=lambda: np.zeros(0))
    alpha: np.ndarray = field(default_factory=lambda: np.ones(0))
    alpha_mode: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # 0 opaque, 1 mask, 2 blend
    alpha_cutoff: np.ndarray = field(default_factory=lambda: np.zeros(0))
    double_sided: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    att_color: np.ndarray = field(default_factory=lambda: np.ones((0, 3)))
    att_distance: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @staticmethod
    def of(scene: Scene) -> _Geometry:
        c = np.asarray(scene.sphere_centers, dtype=np.float64).reshape(-1, 3)
        r = np.asarray(scene.sphere_radii, dtype=np.float64).reshape(-1)
        mats = scene.materials
        extent = float(np.sqrt(_dot(c, c).max()) + r.max()) if len(r) else 0.0
        return _Geometry(
            n=len(r),
            centers=c,
            centers_t=np.ascontiguousarray(c.T),
            cc=_dot(c, c),
            r2=r * r,
            radii=r,
            extent=extent,
            plane_points=np.array([p.point for p in scene.planes], dtype=np.float64).reshape(-1, 3),
            plane_normals=np.array([p.normal for p in scene.planes], dtype=np.float64).reshape(-1, 3),
            prim_material=np.concatenate(
                [
                    np.asarray(scene.sphere_materials, dtype=np.int64),
                    np.array([p.material for p in scene.planes], dtype=np.int64),
                    np.asarray(scene.triangle_materials, dtype=np.int64),
                    np.asarray(scene.shapes.material, dtype=np.int64),
                ]
            ),
            color=np.array([_phong(m, "color", (0.0, 0.0, 0.0)) for m in mats], dtype=np.float64).reshape(-1, 3),
            ka=np.array([_phong(m, "ambient", 0.0) for m in mats]),
            kd=np.array([_phong(m, "diffuse", 0.0) for m in mats]),
            ks=np.array([_phong(m, "specular", 0.0) for m in mats]),
            shininess=np.array([_phong(m, "shininess", 1.0) for m in mats]),
            kr=np.array([_phong(m, "reflective", 0.0) for m in mats]),
            kt=np.array([_phong(m, "transmissive", 0.0) for m in mats]),
            ior=np.array([m.ior for m in mats]),
            light_pos=np.array([light.position for light in scene.lights], dtype=np.float64).reshape(-1, 3),
            light_col=np.array([light.color for light in scene.lights], dtype=np.float64).reshape(-1, 3),
            tris=_Triangles.of(scene),
            emission=np.array([m.emission for m in mats], dtype=np.float64).reshape(-1, 3),
            environment=np.array(scene.environment, dtype=np.float64),
            environment_map=scene.environment_map,
            shapes=scene.shapes,
            shape_base=scene.shape_id_base,
            pbr=np.array([isinstance(m, PbrMaterial) for m in mats], dtype=bool),
            base=np.array([_pbr(m, "base_color", (0.0, 0.0, 0.0)) for m in mats], dtype=np.float64).reshape(-1, 3),
            metallic=np.array([_pbr(m, "metallic", 0.0) for m in mats], dtype=np.float64),
            roughness=np.array([_pbr(m, "roughness", 1.0) for m in mats], dtype=np.float64),
            transmission=np.array([_pbr(m, "transmission", 0.0) for m in mats], dtype=np.float64),
            alpha=np.array([_pbr(m, "alpha", 1.0) for m in mats], dtype=np.float64),
            alpha_mode=np.array([ALPHA_MODES.index(_pbr(m, "alpha_mode", "opaque")) for m in mats], dtype=np.int64),
            alpha_cutoff=np.array([_pbr(m, "alpha_cutoff", 0.5) for m in mats], dtype=np.float64),
            double_sided=np.array([_pbr(m, "double_sided", True) for m in mats], dtype=bool),
            att_color=np.array([_pbr(m, "attenuation_color", (1.0, 1.0, 1.0)) for m in mats]).reshape(-1, 3),
            att_distance=np.array([_pbr(m, "attenuation_distance", 0.0) for m in mats], dtype=np.float64),
        )

    def passes(self, prim: np.ndarray, front: np.ndarray) -> np.ndarray:
        """Whether rays that meet primitives ``prim`` (on the side their geometric normal faces where
        ``front``) go on through them unchanged: Whitted's PBR rule (shaders/bsdf_pbr.glsl's
        pbr_passes with u = ½): a single-sided back face that does not transmit, alpha below the mask's
        cutoff, a blend's coverage ≤ ½."""
        mat = self.prim_material[prim]
        if not len(self.pbr) or not self.pbr.any():
            return np.zeros(len(prim), bool)
        pbr = self.pbr[mat]
        culled = ~front & ~self.double_sided[mat] & (self.transmission[mat] <= 0.0)
        mode, a = self.alpha_mode[mat], self.alpha[mat]
        cut = ((mode == 1) & (a < self.alpha_cutoff[mat])) | ((mode == 2) & (a <= 0.5))
        return pbr & (culled | cut)

    def attenuation(self, prim: np.ndarray, t: np.ndarray) -> np.ndarray:
        """(k, 3) KHR_materials_volume's Beer–Lambert share after a distance t inside the materials of
        ``prim`` (1 where they have none)."""
        mat = self.prim_material[prim]
        dist = self.att_distance[mat] if len(self.att_distance) else np.zeros(len(prim))
        out = np.ones((len(prim), 3))
        has = dist > 0.0
        if has.any():
            c = np.maximum(self.att_color[mat[has]], 1e-30)
            out[has] = np.exp(np.log(c) * (t[has] / dist[has])[:, None])
        return out

    def normals(
        self, prim: np.ndarray, p: np.ndarray, o: np.ndarray | None = None, d: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(geometric, shading) outward unit normals at points ``p`` of primitives ``prim``.

        Sphere: both ``(p − c)/r``; plane: both its normal; triangle: the geometric normal
        of its winding, and — smooth meshes — the normalised barycentric blend of its corner
        normals at the hit of ray (o, d) (the same test that found it gives the weights),
        flat ones the geometric normal. A blend that cancels to zero falls back to the
        geometric normal. An analytic shape: both its outward normal at p
        (:func:`renderer.geometry.shapes.normals`)."""
        sph = prim < self.n
        shp = prim >= self.shape_base if len(self.shapes) else np.zeros(len(prim), bool)
        tri = (prim >= self.tris.base) & ~shp
        geo = np.empty_like(p)
        i = prim[sph]
        geo[sph] = (p[sph] - self.centers[i]) / self.radii[i][:, None]
        pl = ~sph & ~tri & ~shp
        geo[pl] = self.plane_normals[prim[pl] - self.n]
        if shp.any():
            geo[shp] = shape_normals(self.shapes, prim[shp] - self.shape_base, p[shp])
        shade = geo.copy()
        if tri.any():
            j = prim[tri] - self.tris.base
            geo[tri] = self.tris.geo_normal[j]
            shade[tri] = geo[tri]
            smooth = self.tris.smooth[j]
            if smooth.any() and o is not None and d is not None:
                rows = np.flatnonzero(tri)[smooth]
                js = j[smooth]
                _, b0, b1, b2 = triangle_hits(o[rows], d[rows], self.tris.v0[js], self.tris.v1[js], self.tris.v2[js])
                vn = self.tris.vertex_normals[js]
                blend = b0[:, None] * vn[:, 0] + b1[:, None] * vn[:, 1] + b2[:, None] * vn[:, 2]
                length = np.linalg.norm(blend, axis=1)
                ok = length > 0
                shade[rows[ok]] = blend[ok] / length[ok][:, None]
        return geo, shade


def _phong(m: AnyMaterial, name: str, default: Any) -> Any:
    """Phong parameter ``name`` of ``m``; ``default`` for another kind (which the Phong terms skip)."""
    return getattr(m, name) if isinstance(m, Material) else default


def _pbr(m: AnyMaterial, name: str, default: Any) -> Any:
    """PBR parameter ``name`` of ``m``; ``default`` for a Phong material."""
    return getattr(m, name) if isinstance(m, PbrMaterial) else default


# ------------------------------------------------------------------- intersection

_NO_PAIRS = (np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64))


def sphere_t(o: np.ndarray, d: np.ndarray, c: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Nearest root ``t > 0`` of each ray (o, d) with each sphere (c, r²) row-wise; ``inf`` if none.

    Robust quadratic: ``b = dot(o − c, d)``, ``h² = r² − |(o − c) − b d|²`` (no b² − c
    cancellation). Roots are ``−b ± h``; the one of larger magnitude is computed directly
    and the other from the product of the roots ``c = |o − c|² − r²``, so a root close
    to 0 (origin near the surface) keeps its relative precision.
    """
    oc = o - c
    b = _dot(oc, d)
    e = oc - b[:, None] * d
    h2 = r2 - _dot(e, e)
    hit = h2 >= 0.0
    h = np.sqrt(np.where(hit, h2, 0.0))
    cq = _dot(oc, oc) - r2
    ahead = b < 0.0
    big = np.where(ahead, -b + h, -b - h)
    with np.errstate(divide="ignore", invalid="ignore"):
        small = np.where(big != 0.0, cq / np.where(big != 0.0, big, 1.0), 0.0)
    t_near = np.where(ahead, small, big)
    t_far = np.where(ahead, big, small)
    t = np.where(t_near > 0.0, t_near, np.where(t_far > 0.0, t_far, np.inf))
    return np.where(hit, t, np.inf)


def sphere_far_t(o: np.ndarray, d: np.ndarray, c: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """Far root ``−b + √(b² − c)`` only (a ray entering its source sphere); ``inf`` if not > 0.

    The origin lies on the sphere and d points inwards, so the root exists; a slightly
    negative h² from rounding (grazing ray) is clamped to 0 instead of losing the hit.
    """
    oc = o - c
    b = _dot(oc, d)
    e = oc - b[:, None] * d
    t = -b + np.sqrt(np.maximum(r2 - _dot(e, e), 0.0))
    return np.where(t > 0.0, t, np.inf)


def _cull(balls: _Balls, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ray, ball) of every pair whose ray may meet the ball at some t (a superset).

    The cull evaluates ``h² ≈ r² − (|o|² − 2 o·c + |c|²) + (o·d − c·d)²`` with matrix
    products (cheap, cancellation-prone) and keeps pairs with ``h² ≥ −tol``. ``tol``
    bounds the rounding error of that expression and of the robust one, plus the
    difference between the two when |d| ≠ 1 (reflected rays are not renormalised), so
    no pair the robust test would accept is lost.
    """
    k = len(balls)
    od, oo, dd = _dot(o, d), _dot(o, o), _dot(d, d)
    scale = (float(np.sqrt(oo.max())) + balls.extent) ** 2 * float(dd.max())
    tol = (64.0 * _EPS + 4.0 * float(np.abs(1.0 - dd).max())) * scale
    tile = max(1, _PAIR_BUDGET // len(o))
    rays, sph = [], []
    for s0 in range(0, k, tile):
        s1 = min(k, s0 + tile)
        ct = balls.centers_t[:, s0:s1]
        # einsum, not `@`: a K = 3 BLAS product is slow and multi-threaded (contention).
        h2 = np.einsum("ik,kj->ij", d, ct)
        np.subtract(od[:, None], h2, out=h2)  # b = o·d − c·d
        h2 *= h2  # b²
        q = np.einsum("ik,kj->ij", o, ct)  # |o − c|² = |o|² − 2 o·c + |c|²
        q *= -2.0
        q += oo[:, None]
        q += balls.cc[None, s0:s1]
        h2 -= q
        h2 += balls.r2[None, s0:s1]
        ri, si = np.nonzero(h2 >= -tol)
        rays.append(ri)
        sph.append(si + s0)
    return np.concatenate(rays), np.concatenate(sph)


def _sphere_candidates(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ray, t, sphere id) of every sphere hit with t > 0, the source sphere excluded
    (candidates from :func:`_cull`, then the robust quadratic)."""
    if g.n == 0 or len(o) == 0:
        return _NO_PAIRS
    ri, si = _cull(_Balls(g.centers_t, g.cc, g.r2, g.extent), o, d)
    keep = si != src[ri]  # the source sphere is handled by the exclusion rule
    ri, si = ri[keep], si[keep]
    t = sphere_t(o[ri], d[ri], g.centers[si], g.r2[si])
    ok = np.isfinite(t)
    return ri[ok], t[ok], si[ok]


def _far_root_candidates(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray, far_only: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ray, t, id) of the far-side hit of the source sphere for rays entering it."""
    ri = np.nonzero(far_only)[0]
    if len(ri) == 0:
        return _NO_PAIRS
    si = src[ri]
    t = sphere_far_t(o[ri], d[ri], g.centers[si], g.r2[si])
    ok = np.isfinite(t)
    return ri[ok], t[ok], si[ok]


def _plane_candidates(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ray, t, id) of every plane hit with t > 0; a ray leaving a plane ignores it."""
    rays, ts, ids = [], [], []
    for j in range(len(g.plane_normals)):
        nrm = g.plane_normals[j]
        denom = np.einsum("ij,j->i", d, nrm)
        num = np.einsum("ij,j->i", g.plane_points[j][None, :] - o, nrm)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / denom
        ok = (denom != 0.0) & (t > 0.0) & np.isfinite(t) & (src != g.n + j)
        ri = np.nonzero(ok)[0]
        rays.append(ri)
        ts.append(t[ri])
        ids.append(np.full(len(ri), g.n + j, dtype=np.int64))
    if not rays:
        return _NO_PAIRS
    return np.concatenate(rays), np.concatenate(ts), np.concatenate(ids)


# ------------------------------------------------------------------- triangles


def _exact_edge(qx: float, py: float, qy: float, px: float) -> float:
    """``qx·py − qy·px`` exactly (rational arithmetic on the float64 inputs), as a float of
    the exact sign (the smallest subnormal when the exact value is below the float range)."""
    v = Fraction(qx) * Fraction(py) - Fraction(qy) * Fraction(px)
    f = float(v)
    if f == 0.0 and v != 0:
        f = 5e-324 if v > 0 else -5e-324
    return f


def _edge(qx: np.ndarray, py: np.ndarray, qy: np.ndarray, px: np.ndarray) -> np.ndarray:
    """Edge function ``E(P, Q) = Q.x·P.y − Q.y·P.x`` of the sheared 2-D corners P, Q.

    Woop et al. fall back to double precision for an edge function that came out exactly
    0 in single precision. In float64 there is no wider type, so the fallback is the exact
    value: an edge that rounds to 0 is recomputed exactly (only that edge: each edge
    function stays a function of its own two corners, ``E(Q, P) = −E(P, Q)`` bit for bit,
    which is what keeps two triangles sharing the edge consistent). Exactly 0 means the
    ray meets the edge itself, and the edge belongs to both triangles."""
    e = qx * py - qy * px
    zero = np.flatnonzero(e == 0.0)
    for k in zero.tolist():
        e[k] = _exact_edge(float(qx[k]), float(py[k]), float(qy[k]), float(px[k]))
    return e


def triangle_hits(
    o: np.ndarray, d: np.ndarray, v0: np.ndarray, v1: np.ndarray, v2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Woop, Benthin & Wald's watertight ray/triangle test, row-wise over (k, 3) arrays.

    Returns ``(t, b0, b1, b2)``: ``t`` of the hit (``inf`` when none or ``t ≤ 0``) and the
    barycentric weights of corners v0, v1, v2 (meaningful where t is finite). Both sides
    are hit (no backface culling). Per ray: ``kz`` = the axis of the largest |d| (the first
    on ties), ``kx, ky`` the next two, swapped when ``d[kz] < 0`` (keeps the winding);
    shear ``Sx = d[kx]/d[kz]``, ``Sy = d[ky]/d[kz]``, ``Sz = 1/d[kz]``. Corners relative to
    the origin are sheared to ``(A[kx] − Sx A[kz], A[ky] − Sy A[kz])``, and the edge
    functions ``U = E(B, C)``, ``V = E(C, A)``, ``W = E(A, B)`` (:func:`_edge`) must not
    have mixed signs; ``det = U + V + W ≠ 0``; ``t = (U Az + V Bz + W Cz) / det`` with
    ``Az = Sz A[kz]`` … must be > 0.
    """
    k = len(o)
    rows = np.arange(k)
    kz = np.argmax(np.abs(d), axis=1)
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    neg = d[rows, kz] < 0.0
    kx, ky = np.where(neg, ky, kx), np.where(neg, kx, ky)
    dz = d[rows, kz]
    sx, sy, sz = d[rows, kx] / dz, d[rows, ky] / dz, 1.0 / dz
    a, b, c = v0 - o, v1 - o, v2 - o
    az_, bz_, cz_ = a[rows, kz], b[rows, kz], c[rows, kz]
    ax, ay = a[rows, kx] - sx * az_, a[rows, ky] - sy * az_
    bx, by = b[rows, kx] - sx * bz_, b[rows, ky] - sy * bz_
    cx, cy = c[rows, kx] - sx * cz_, c[rows, ky] - sy * cz_
    u = _edge(cx, by, cy, bx)
    v = _edge(ax, cy, ay, cx)
    w = _edge(bx, ay, by, ax)
    mixed = ((u < 0) | (v < 0) | (w < 0)) & ((u > 0) | (v > 0) | (w > 0))
    det = u + v + w
    big_t = u * (sz * az_) + v * (sz * bz_) + w * (sz * cz_)
    ok = ~mixed & (det != 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(ok, big_t / np.where(ok, det, 1.0), np.inf)
        inv = 1.0 / np.where(ok, det, 1.0)
    t = np.where(t > 0.0, t, np.inf)
    return t, u * inv, v * inv, w * inv


def _triangle_candidates(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ray, t, id) of every triangle hit with t > 0; a ray leaving a triangle ignores it
    (flat: it cannot meet its own plane again). Candidates from the bounding balls' cull."""
    tr = g.tris
    if len(tr) == 0 or len(o) == 0:
        return _NO_PAIRS
    ri, ti = _cull(tr.balls, o, d)
    keep = tr.valid[ti] & (tr.base + ti != src[ri])
    ri, ti = ri[keep], ti[keep]
    t, _, _, _ = triangle_hits(o[ri], d[ri], tr.v0[ti], tr.v1[ti], tr.v2[ti])
    ok = np.isfinite(t)
    return ri[ok], t[ok], tr.base + ti[ok]


def _shape_candidates(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ray, t, id) of each ray's nearest analytic shape with t > 0; a ray leaving a shape
    ignores that shape's root nearest 0 (its own origin), not its other roots."""
    if len(g.shapes) == 0 or len(o) == 0:
        return _NO_PAIRS
    own = np.where(src >= g.shape_base, src - g.shape_base, -1)
    t, k, _ = shape_intersect(g.shapes, o, d, src=own)
    ri = np.flatnonzero(k >= 0)
    return ri, t[ri], g.shape_base + k[ri]


def _reduce_nearest(count: int, rays: np.ndarray, ts: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per ray the smallest t; among exactly equal t the lowest id. (inf, −1) without candidates."""
    t = np.full(count, np.inf)
    np.minimum.at(t, rays, ts)
    at_min = ts == t[rays]
    best = np.full(count, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(best, rays[at_min], ids[at_min])
    best[np.isinf(t)] = -1
    return t, best


def nearest_hit(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray, far_only: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hit of each ray: (t float64, primitive id int64), (inf, −1) on a miss.

    ``src`` is the primitive each ray leaves (−1 for primary rays) and ``far_only`` is
    True where that primitive is a sphere the ray enters (``dot(d, N) < 0``): for it only
    the far root counts. Any other source primitive (a plane, a triangle) is ignored, and a
    source analytic shape's root nearest 0 (SHADING.md, no epsilon).
    """
    t_out = np.full(len(o), np.inf)
    id_out = np.full(len(o), -1, dtype=np.int64)
    for a in range(0, len(o), _RAY_TILE):
        sl = slice(a, min(len(o), a + _RAY_TILE))
        parts = [
            _sphere_candidates(g, o[sl], d[sl], src[sl]),
            _far_root_candidates(g, o[sl], d[sl], src[sl], far_only[sl]),
            _plane_candidates(g, o[sl], d[sl], src[sl]),
            _triangle_candidates(g, o[sl], d[sl], src[sl]),
            _shape_candidates(g, o[sl], d[sl], src[sl]),
        ]
        rays, ts, ids = (np.concatenate([p[k] for p in parts]) for k in range(3))
        t_out[sl], id_out[sl] = _reduce_nearest(sl.stop - sl.start, rays, ts, ids)
    return t_out, id_out


def trace_rays(
    scene: Scene,
    origins: np.ndarray,
    dirs: np.ndarray,
    src: np.ndarray | None = None,
    far_only: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Nearest hits (t float64, id int64; inf/−1 on a miss) of arbitrary rays in ``scene``.

    ``dirs`` should be unit vectors (t is then a distance). Without ``src`` the rays are
    camera-like (no source primitive); see :func:`nearest_hit` for ``src``/``far_only``.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    src = np.full(len(o), -1, np.int64) if src is None else np.asarray(src, dtype=np.int64).reshape(-1)
    far_only = np.zeros(len(o), bool) if far_only is None else np.asarray(far_only, dtype=bool).reshape(-1)
    return nearest_hit(_Geometry.of(scene), o, d, src, far_only)


# ------------------------------------------------------------------------ shading


def local_color(
    g: _Geometry,
    p: np.ndarray,
    d: np.ndarray,
    normal: np.ndarray,
    prim: np.ndarray,
    geo_normal: np.ndarray | None = None,
) -> np.ndarray:
    """Phong ``local`` term of SHADING.md at hits (p, prim) of rays with direction d, (k, 3).

    ``normal`` is the shading normal, ``geo_normal`` the geometric one (the same for
    spheres and planes, and when not given): the side the ray sees is decided by the
    geometric normal, ``Nf`` is the shading normal turned to that side. One shadow ray per
    light from exactly ``p``; every primitive blocks light fully.
    """
    geo = normal if geo_normal is None else geo_normal
    mat = g.prim_material[prim]
    c = g.color[mat]
    local = g.ka[mat][:, None] * c
    facing = np.where((_dot(d, geo) < 0.0)[:, None], normal, -normal)  # Nf
    is_sphere = prim < g.n
    for lp, lc in zip(g.light_pos, g.light_col, strict=True):
        to_light = lp[None, :] - p
        dist = np.linalg.norm(to_light, axis=1)
        # A light exactly at p has no direction: it contributes nothing (avoids 0/0).
        with np.errstate(divide="ignore", invalid="ignore"):
            ldir = to_light / dist[:, None]
            cos = _dot(facing, ldir)
        idx = np.nonzero((dist > 0.0) & (cos > 0.0))[0]
        if len(idx) == 0:
            continue
        li = ldir[idx]
        far = is_sphere[idx] & (_dot(li, geo[idx]) < 0.0)
        t_s, _ = nearest_hit(g, p[idx], li, prim[idx], far)
        idx = idx[~(t_s < dist[idx])]
        li, ci, fi, m = ldir[idx], cos[idx], facing[idx], mat[idx]
        r = 2.0 * ci[:, None] * fi - li
        x = -_dot(r, d[idx])
        spec = np.where(x > 0.0, np.power(np.where(x > 0.0, x, 1.0), g.shininess[m]), 0.0)
        local[idx] += lc[None, :] * (g.kd[m][:, None] * ci[:, None] * c[idx] + (g.ks[m] * spec)[:, None])
        if len(g.pbr) and g.pbr[m].any():  # the glTF BRDF · cos under irradiance π · the light's colour
            j = np.flatnonzero(g.pbr[m])
            mj = m[j]
            f = pbr_brdf.brdf(
                g.base[mj],
                g.metallic[mj],
                pbr_brdf.alpha_of(g.roughness[mj]),
                pbr_brdf.f0_of(g.ior[mj]),
                g.transmission[mj],
                fi[j],
                -d[idx][j],
                li[j],
            )
            local[idx[j]] += lc[None, :] * (np.pi * ci[j])[:, None] * f
    if len(g.pbr) and g.pbr[mat].any():  # Whitted's ambient term of a PBR material
        j = np.flatnonzero(g.pbr[mat])
        opaque = 1.0 - (1.0 - g.metallic[mat[j]]) * g.transmission[mat[j]]  # not for the share that refracts
        local[j] += (WHITTED_AMBIENT * opaque)[:, None] * g.base[mat[j]]
    return local


# ---------------------------------------------------------------------- ray tree


@dataclass
class RayBatch:
    """One generation of rays: all at recursion ``level`` (primary = 1).

    ``pix`` row-major pixel index each ray contributes to, ``weight`` (k, 3) the product
    of kr/kt along its path, ``src`` the primitive it leaves (−1: camera), ``far_only``
    whether it enters that source sphere (far-root rule).
    """

    origins: np.ndarray
    dirs: np.ndarray
    pix: np.ndarray
    weight: np.ndarray
    level: int
    src: np.ndarray
    far_only: np.ndarray

    def __len__(self) -> int:
        return len(self.pix)

    def split(self, size: int) -> list[RayBatch]:
        """Pieces of at most ``size`` rays (memory bound)."""
        return [
            RayBatch(
                self.origins[a : a + size],
                self.dirs[a : a + size],
                self.pix[a : a + size],
                self.weight[a : a + size],
                self.level,
                self.src[a : a + size],
                self.far_only[a : a + size],
            )
            for a in range(0, len(self), size)
        ]


@dataclass
class _Frame:
    """Per-pixel accumulators (flat, row-major)."""

    color: np.ndarray  # (P, 3) float64 Whitted sum
    depth: np.ndarray  # (P,) t of the primary hit
    primid: np.ndarray  # (P,)
    normal: np.ndarray  # (P, 3)
    deepest: np.ndarray  # (P,) deepest level whose ray hit something (0: primary miss)

    @staticmethod
    def empty(pixels: int) -> _Frame:
        return _Frame(
            np.zeros((pixels, 3)),
            np.full(pixels, np.inf),
            np.full(pixels, -1, dtype=np.int64),
            np.zeros((pixels, 3)),
            np.zeros(pixels, dtype=np.int64),
        )


def _secondary_rays(
    g: _Geometry, batch: RayBatch, hit: np.ndarray, p: np.ndarray, normal: np.ndarray, prim: np.ndarray, geo: np.ndarray
) -> RayBatch | None:
    """Reflected (kr > 0) and transmitted (kt > 0) children of the hits ``hit`` of ``batch``.

    Directions bend about the shading normal ``normal``; whether a transmitted ray enters
    or leaves is decided by the geometric normal ``geo`` (the same for spheres and planes)."""
    mat = g.prim_material[prim]
    d, w = batch.dirs[hit], batch.weight[hit]
    kr, kt = _ray_weights(g, mat, d, normal, geo)
    r_sel = np.nonzero(kr.max(axis=1) > 0.0)[0]
    t_sel = np.nonzero(kt.max(axis=1) > 0.0)[0]
    if len(r_sel) + len(t_sel) == 0:
        return None
    t_dirs, _ = transmitted_directions(d[t_sel], normal[t_sel], g.ior[mat[t_sel]], _dot(d[t_sel], geo[t_sel]) < 0.0)
    sel = np.concatenate([r_sel, t_sel])
    dirs = np.concatenate([reflect(d[r_sel], normal[r_sel]), t_dirs])
    weight = w[sel] * np.concatenate([kr[r_sel], kt[t_sel]])
    src = prim[sel]
    far_only = (src < g.n) & (_dot(dirs, geo[sel]) < 0.0)
    return RayBatch(p[sel], dirs, batch.pix[hit][sel], weight, batch.level + 1, src, far_only)


def _ray_weights(
    g: _Geometry, mat: np.ndarray, d: np.ndarray, normal: np.ndarray, geo: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(k, 3) each: the weights of the reflected and the transmitted ray of hits on materials ``mat``
    met along ``d``: kr and kt of a Phong material; Whitted's PBR rule for a PBR one (docs/SHADING.md,
    "PBR"): the specular Fresnel at the view × (1 − roughness)², and (1 − metallic) · transmission ·
    (1 − the dielectric's Fresnel) · base colour."""
    kr = np.repeat(g.kr[mat][:, None], 3, axis=1)
    kt = np.repeat(g.kt[mat][:, None], 3, axis=1)
    if len(g.pbr) and g.pbr[mat].any():
        j = np.flatnonzero(g.pbr[mat])
        mj = mat[j]
        nf = np.where((_dot(d[j], geo[j]) < 0.0)[:, None], normal[j], -normal[j])
        c = np.maximum(-_dot(d[j], nf), 0.0)
        f0 = pbr_brdf.f0_of(g.ior[mj])
        smooth = np.square(1.0 - g.roughness[mj])
        kr[j] = pbr_brdf.fresnel(g.base[mj], g.metallic[mj], f0, c) * smooth[:, None]
        share = (1.0 - g.metallic[mj]) * g.transmission[mj] * (1.0 - pbr_brdf.dielectric_fresnel(f0, c))
        kt[j] = share[:, None] * g.base[mj]
    return kr, kt


def _nearest_unpassed(
    g: _Geometry, o: np.ndarray, d: np.ndarray, src: np.ndarray, far_only: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hits that a ray does not pass (:meth:`_Geometry.passes`): (t from the ray's origin
    summed over what it passed, prim, the origin and source of the last leg)."""
    t, prim = nearest_hit(g, o, d, src, far_only)
    if not len(g.pbr) or not g.pbr.any():
        return t, prim, o, src
    total = np.where(prim >= 0, t, np.inf)
    o, src = o.copy(), src.copy()
    passed = np.zeros(len(t))
    for _ in range(MAX_PASSES):
        hit = np.flatnonzero(prim >= 0)
        if not len(hit):
            break
        p = o[hit] + t[hit, None] * d[hit]
        geo, _ = g.normals(prim[hit], p, o[hit], d[hit])
        go = g.passes(prim[hit], _dot(d[hit], geo) < 0.0)
        if not go.any():
            break
        k = hit[go]
        passed[k] += t[k]
        o[k], src[k] = p[go], prim[k]
        far = (prim[k] < g.n) & (_dot(d[k], geo[go]) < 0.0)
        t[k], prim[k] = nearest_hit(g, o[k], d[k], src[k], far)
    total = np.where(prim >= 0, passed + t, np.inf)
    return total, prim, o, src


def _trace_batch(g: _Geometry, batch: RayBatch, frame: _Frame, max_level: int, shade: bool) -> RayBatch | None:
    """Trace one generation: record primary data, add weighted local colour, return children."""
    t, prim, o_last, _ = _nearest_unpassed(g, batch.origins, batch.dirs, batch.src, batch.far_only)
    hit = np.nonzero(prim >= 0)[0]
    if shade and g.environment.any():  # a ray that meets nothing sees the environment
        miss = np.nonzero(prim < 0)[0]
        np.add.at(frame.color, batch.pix[miss], batch.weight[miss] * g.environment)
    if shade and g.environment_map is not None:  # … or the image along the ray
        miss = np.nonzero(prim < 0)[0]
        seen = g.environment_map.radiance(batch.dirs[miss])
        np.add.at(frame.color, batch.pix[miss], batch.weight[miss] * seen)
    if len(hit) == 0:
        return None  # a miss is black: nothing to add
    prim_h, pix_h = prim[hit], batch.pix[hit]
    p = batch.origins[hit] + t[hit, None] * batch.dirs[hit]
    geo, normal = g.normals(prim_h, p, batch.origins[hit], batch.dirs[hit])
    if len(g.pbr) and g.pbr.any():  # a back face met from inside a volume: Beer–Lambert over the leg
        back = _dot(batch.dirs[hit], geo) >= 0.0
        if back.any():
            leg = np.linalg.norm(p - o_last[hit], axis=1)
            batch.weight = batch.weight.copy()
            batch.weight[hit] = np.where(
                back[:, None], batch.weight[hit] * g.attenuation(prim_h, leg), batch.weight[hit]
            )
    frame.deepest[pix_h] = np.maximum(frame.deepest[pix_h], batch.level)
    if batch.level == 1:  # primary rays: one per pixel
        frame.depth[pix_h] = t[hit]
        frame.primid[pix_h] = prim_h
        frame.normal[pix_h] = normal
    if shade:
        local = local_color(g, p, batch.dirs[hit], normal, prim_h, geo)
        if g.emission.any():  # emitted on the side the (geometric) normal faces
            front = _dot(batch.dirs[hit], geo) < 0.0
            local = local + np.where(front[:, None], g.emission[g.prim_material[prim_h]], 0.0)
        np.add.at(frame.color, pix_h, batch.weight[hit] * local)
    if batch.level >= max_level:
        return None  # the deepest level returns `local` only
    return _secondary_rays(g, batch, hit, p, normal, prim_h, geo)


def _trace_pixels(
    g: _Geometry, camera: Camera, w: int, h: int, frame: _Frame, chunk_rays: int, max_level: int, shade: bool
) -> None:
    """Evaluate the ray trees of all w × h pixels, one chunk of primary rays at a time, depth first."""
    for a in range(0, w * h, chunk_rays):
        pix = np.arange(a, min(w * h, a + chunk_rays), dtype=np.int64)
        o, d = _pixel_rays(camera, w, h, pix)
        stack = [
            RayBatch(
                o,
                d,
                pix,
                np.ones((len(pix), 3)),
                1,
                np.full(len(pix), -1, dtype=np.int64),
                np.zeros(len(pix), dtype=bool),
            )
        ]
        while stack:
            child = _trace_batch(g, stack.pop(), frame, max_level, shade)
            if child is not None:
                stack.extend(child.split(chunk_rays))


def ray_tree_counts(scene: Scene, width: int, height: int, levels: int, min_weight: float) -> list[int]:
    """Radiance rays per level (primary = level 1) that the Whitted tracer traces for the pixel
    centres of a ``width`` × ``height`` grid, at most ``levels`` levels: children of the hits whose
    path weight (the product of kr and kt along the path) is at least ``min_weight``, the shader's
    ε rule (``shaders/raytrace.frag``). Shadow rays are not counted. The cost model's ray tree of a
    scene, sampled on a coarse grid (:mod:`renderer.frame.prepare`)."""
    g = _Geometry.of(scene)
    pixels = width * height
    pix = np.arange(pixels, dtype=np.int64)
    o, d = _pixel_rays(scene.camera, width, height, pix)
    frame = _Frame.empty(pixels)
    batch: RayBatch | None = RayBatch(
        o, d, pix, np.ones((pixels, 3)), 1, np.full(pixels, -1, dtype=np.int64), np.zeros(pixels, dtype=bool)
    )
    counts: list[int] = []
    while batch is not None and len(batch) and batch.level <= levels:
        counts.append(len(batch))
        child = _trace_batch(g, batch, frame, levels, shade=False)
        if child is not None:
            keep = np.flatnonzero(child.weight.max(axis=1) >= min_weight)  # the shader's WEIGHT_MAX
            child = RayBatch(
                child.origins[keep],
                child.dirs[keep],
                child.pix[keep],
                child.weight[keep],
                child.level,
                child.src[keep],
                child.far_only[keep],
            )
        batch = child
    return counts


# ------------------------------------------------------------------------- modes


def heat_counts(
    scene: Scene, settings: RenderSettings, o: np.ndarray, d: np.ndarray, chunk_rays: int = 4096
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(nodes visited, gaps, primitive tests) per primary ray for ``settings.method``.

    Brute force tests every sphere, triangle and analytic shape and visits no node. ``bih``
    counts come from the BIH traversal of docs/SHADING.md (:mod:`renderer.accel.bih_traverse`,
    the CPU mirror of the shader's) over the spheres, triangles and analytic shapes; a
    triangle's or a shape's test counts as a sphere test does.
    """
    n_rays = len(o)
    if settings.method == "bruteforce":
        return (
            np.zeros(n_rays, np.int64),
            np.zeros(n_rays, np.int64),
            np.full(n_rays, scene.n_tree_primitives, dtype=np.int64),
        )
    bih = build_for_scene(scene, settings.max_prims, settings.max_tree_depth)
    nodes, gaps, tests = [], [], []
    for a in range(0, n_rays, chunk_rays):
        res = traverse(
            bih,
            scene.sphere_centers,
            scene.sphere_radii,
            o[a : a + chunk_rays],
            d[a : a + chunk_rays],
            triangles=scene.triangle_corners,
            shapes=scene.shapes,
        )
        nodes.append(np.asarray(res.nodes_visited))
        gaps.append(np.asarray(res.gaps))
        tests.append(np.asarray(res.tests))
    return np.concatenate(nodes), np.concatenate(gaps), np.concatenate(tests)


def _mode_image(scene: Scene, settings: RenderSettings, frame: _Frame, chunk_rays: int, w: int, h: int) -> np.ndarray:
    """The flat (P, 3) float64 image the render mode shows (SHADING.md § Output modes)."""
    mode = settings.mode
    hit = (frame.primid >= 0)[:, None]
    if mode == "color":
        return np.clip(frame.color, 0.0, 1.0)
    if mode == "depth":
        dist = float(np.linalg.norm(np.subtract(scene.camera.target, scene.camera.position)))
        return np.repeat(depth_grey(frame.depth, dist)[:, None], 3, axis=1)
    if mode == "primid":
        return primid_colors(frame.primid)
    if mode == "normal":
        return np.where(hit, 0.5 * (frame.normal + 1.0), 0.0)
    if mode == "recursion":
        return RECURSION_COLORS[frame.deepest]
    if mode == "heat":
        o, d = primary_rays(scene.camera, w, h)
        return heat_image(*heat_counts(scene, settings, o, d, chunk_rays))
    raise ValueError(f"unknown mode {mode!r}")


def render_reference(
    scene: Scene, settings: RenderSettings, *, chunk_rays: int = 4096, supersample: int | None = None
) -> RenderResult:
    """Render ``scene`` with the float64 reference tracer (SHADING.md), whatever ``settings.method``.

    ``chunk_rays`` bounds the rays traced together (memory ∝ chunk_rays × recursion depth).
    depth/primid/normal always describe the primary hit through the pixel centre; the
    Whitted tree is only traced in the modes that need it (color, recursion). ``method``
    only changes the heat image. Supersampling (docs/FORMATS.md): the images that are
    averaged (color, recursion, heat) are the mean of ``k × k`` sub-pixels per pixel
    (``k`` = ``supersample``, else √``settings.samples_per_pixel``); depth, primid and
    normal — their arrays, and their images in those modes — come from one ray through
    each pixel centre. ``supersample`` is not bound by the GPU's 4,096-pixel texture side
    (a reference may be larger).
    """
    start = time.perf_counter()
    chunk_rays = max(1, int(chunk_rays))
    k = int(supersample) if supersample is not None else settings.supersampling
    if k < 1:
        raise ValueError(f"supersample must be >= 1, got {k}")
    w, h = settings.width, settings.height
    g = _Geometry.of(scene)
    averaged = settings.mode in AVERAGED_MODES
    whitted = settings.mode in ("color", "recursion")
    max_level = settings.max_recursion_depth if whitted else 1
    # The pixel centres: every mode's arrays, and the whole image of the modes not averaged.
    centre = _Frame.empty(w * h)
    _trace_pixels(
        g,
        scene.camera,
        w,
        h,
        centre,
        chunk_rays,
        1 if averaged and k > 1 else max_level,
        shade=settings.mode == "color" and not (averaged and k > 1),
    )
    depth = centre.depth.reshape(h, w)
    primid = centre.primid.reshape(h, w)
    normal = centre.normal.reshape(h, w, 3)
    if averaged and k > 1:
        W, H = w * k, h * k
        grid = _Frame.empty(W * H)
        _trace_pixels(g, scene.camera, W, H, grid, chunk_rays, max_level, shade=settings.mode == "color")
        image = _mode_image(scene, settings, grid, chunk_rays, W, H).reshape(h, k, w, k, 3).mean(axis=(1, 3))
    else:
        image = _mode_image(scene, settings, centre, chunk_rays, w, h).reshape(h, w, 3)
    trace_ms = (time.perf_counter() - start) * 1e3
    return RenderResult(
        image=np.ascontiguousarray(image, dtype=np.float32),
        depth=np.ascontiguousarray(depth, dtype=np.float32),
        primid=np.ascontiguousarray(primid, dtype=np.int32),
        normal=np.ascontiguousarray(normal, dtype=np.float32),
        mode=settings.mode,
        timings={"trace": trace_ms},
        stats=None,
    )


# ------------------------------------------------------------------------ textures
# The float64 twins of shaders/textures.glsl and shaders/pbr_inputs.glsl's texture coordinates (the
# tests compare the GPU's with these): a hit's barycentrics and UVs, and a texture's value at a UV
# and mip level with its wrap modes and filter. The mip levels are data (renderer/gpu/texture_layout.py's
# mip_chain), not GLSL.


def triangle_barycentrics(scene: Scene, tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """float64 (N, 3): the barycentric weights of points ``p`` (N, 3) on triangles ``tri`` (scene
    order), from their float64 corners: weight k of corner k, p's projection on the plane."""
    c = np.asarray(scene.triangle_corners, dtype=np.float64)[np.asarray(tri, dtype=np.int64)]
    a, e1, e2 = c[:, 0], c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
    g = np.cross(e1, e2)
    gg = _dot(g, g)
    w = np.asarray(p, dtype=np.float64) - a
    b1 = _dot(np.cross(w, e2), g) / gg
    b2 = _dot(np.cross(e1, w), g) / gg
    return np.stack([1.0 - b1 - b2, b1, b2], axis=1)


def hit_texcoords(scene: Scene, tri: np.ndarray, bary: np.ndarray, uv_set: int = 0) -> np.ndarray:
    """float64 (N, 2): UV set ``uv_set`` (0 or 1) at barycentrics ``bary`` of triangles ``tri``
    (0 where the mesh has none)."""
    name = "uvs1" if uv_set else "uvs"
    tri = np.asarray(tri, dtype=np.int64)
    out = np.zeros((len(tri), 2))
    mesh_of = np.asarray(scene.triangle_mesh)[tri]
    for k, m in enumerate(scene.meshes):
        sel = np.flatnonzero(mesh_of == k)
        uv = getattr(m, name)
        if uv is None or not len(sel):
            continue
        local = tri[sel] - scene.mesh_triangle_range(k).start
        corners = np.asarray(uv, dtype=np.float64)[np.asarray(m.triangles, dtype=np.int64)[local]]  # (n, 3, 2)
        out[sel] = np.einsum("nk,nkc->nc", np.asarray(bary, dtype=np.float64)[sel], corners)
    return out


def _wrap(i: np.ndarray, n: int, mode: str) -> np.ndarray:
    if mode == "clamp":
        return np.clip(i, 0, n - 1)
    if mode == "mirror":
        m = np.mod(i, 2 * n)
        return np.where(m < n, m, 2 * n - 1 - m)
    return np.mod(i, n)


def texture_sample(levels: list[np.ndarray], texture, uv: np.ndarray, level: np.ndarray | float = 0.0) -> np.ndarray:
    """float64 (N, 4) linear RGBA of ``texture`` (its ``wrap_s``, ``wrap_t``, ``filter``, ``srgb``)
    whose mip levels are ``levels`` (uint8 (h_l, w_l, 4) each) at ``uv`` (N, 2) and mip ``level``
    (clamped to the levels; a fraction mixes the two around it): each texel decoded to linear
    before it is mixed, bilinear about texel centres or the nearest texel, wrapped per texel."""
    from ..gpu.texture_layout import srgb_to_linear

    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    lv = np.clip(np.broadcast_to(np.asarray(level, dtype=np.float64), (len(uv),)), 0.0, len(levels) - 1)
    l0 = np.floor(lv).astype(np.int64)
    frac = lv - l0

    def at_level(k: int, rows: np.ndarray) -> np.ndarray:
        img = np.asarray(levels[k], dtype=np.float64) / 255.0
        if texture.srgb:
            img = img.copy()
            img[..., :3] = srgb_to_linear(img[..., :3])
        h, w = img.shape[:2]
        s = uv[rows, 0] * w
        t = uv[rows, 1] * h
        if texture.filter == "nearest":
            x = _wrap(np.floor(s).astype(np.int64), w, texture.wrap_s)
            y = _wrap(np.floor(t).astype(np.int64), h, texture.wrap_t)
            return img[y, x]
        s, t = s - 0.5, t - 0.5
        x0, y0 = np.floor(s).astype(np.int64), np.floor(t).astype(np.int64)
        fx, fy = (s - x0)[:, None], (t - y0)[:, None]
        xa, xb = _wrap(x0, w, texture.wrap_s), _wrap(x0 + 1, w, texture.wrap_s)
        ya, yb = _wrap(y0, h, texture.wrap_t), _wrap(y0 + 1, h, texture.wrap_t)
        top = img[ya, xa] * (1 - fx) + img[ya, xb] * fx
        bottom = img[yb, xa] * (1 - fx) + img[yb, xb] * fx
        return top * (1 - fy) + bottom * fy

    out = np.zeros((len(uv), 4))
    for k in np.unique(l0):
        rows = np.flatnonzero(l0 == k)
        c = at_level(int(k), rows)
        f = frac[rows][:, None]
        if k + 1 < len(levels) and (f > 0).any():
            c = c * (1 - f) + at_level(int(k) + 1, rows) * f
        out[rows] = c
    return out
