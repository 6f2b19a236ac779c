"""The analytic shapes' stability cases and their float64 oracle (tests and bench/shapes_solvers.py).

A case is one shape (its three vec4 records) and rays (origins and unit directions), built
in float64 and stored in float32, chosen where quadric and quartic solvers fail: grazing
rays, rays along the axis and through the hole, shapes 1e4 from the origin, thin tori, caps
seen edge-on, cylinders of height 1e-6, cones with an apex. The oracle intersects the shape
*as float32 stores it* (the records and rays converted exactly to extended precision), so a
disagreement is the float32 arithmetic's, not the inputs' rounding; ``reference(name,
exact=True)`` is the same oracle on the float64 inputs (what the rounding of the inputs adds):

- quadrics: the textbook quadratic B² − AC in ``numpy.longdouble`` (64-bit mantissa on
  x86-64) in an orthonormal frame of the axis (no shift, no product forms: another route
  than the shader's);
- the torus: the quartic's roots by the eigenvalues of its companion matrix (float64,
  after the shift to the ray's point closest to the centre and a scale by R), every real
  candidate polished by Newton in longdouble on E = (rho − R)² + z² − r² and kept only if
  E vanishes there.

mpmath is not installed here (checked), hence longdouble.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from renderer.accel.shapes_f32 import BIG, CONE, CYLINDER, DISK, TORUS

L = np.longdouble
AGREEMENT = 0.9999  # share of rays whose hit/miss agrees and whose depth is within DEPTH_REL
DEPTH_REL = 1e-4
SIDE = 128  # rays per case: SIDE × SIDE (one disagreement in 16,384 is 99.994 %)
T_MAX = 1.0e30


def pack(kind: int, origin, axis, r0: float, r1: float, height: float = 0.0, caps: bool = False) -> np.ndarray:
    """The three vec4 records of a shape in float64 (the axis normalised); a case stores them in float32."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return np.array(
        [[*origin, r0], [*a, r1], [height, 1.0 if caps else 0.0, float(kind), 0.0]],
        dtype=np.float64,
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def camera_rays(pos, target, fov_deg: float, side: int = SIDE) -> tuple[np.ndarray, np.ndarray]:
    """A pinhole camera's side × side rays (float64, unit directions)."""
    pos = np.asarray(pos, dtype=np.float64)
    fwd = _unit(np.asarray(target, dtype=np.float64) - pos)
    up0 = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    right = _unit(np.cross(fwd, up0))
    up = np.cross(right, fwd)
    s = np.tan(np.radians(fov_deg) / 2)
    u = (np.arange(side) + 0.5) / side * 2 - 1
    uu, vv = np.meshgrid(u * s, u * s)
    d = _unit(fwd + uu[..., None] * right + vv[..., None] * up).reshape(-1, 3)
    o = np.broadcast_to(pos, d.shape).copy()
    return o, d


def _frame(axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = _unit(np.asarray(axis, dtype=np.float64))
    e1 = _unit(np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0]))
    return e1, np.cross(a, e1), a


# --------------------------------------------------------------------------- the oracle


def _to_l(x) -> np.ndarray:
    return np.asarray(x).astype(L)


def _local(o, d, v) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rays in an orthonormal frame of the shape (longdouble): origin xyz, direction xyz (unit), axis, basis."""
    v = _to_l(v)
    o, d = _to_l(o), _to_l(d)
    d = d / np.sqrt((d * d).sum(-1, keepdims=True))
    a = v[1, :3] / np.sqrt((v[1, :3] * v[1, :3]).sum())
    e1 = np.cross(a, np.array([1, 0, 0], dtype=L) if abs(a[0]) < 0.9 else np.array([0, 1, 0], dtype=L))
    e1 = e1 / np.sqrt((e1 * e1).sum())
    e2 = np.cross(a, e1)
    basis = np.stack([e1, e2, a])  # rows
    p = (o - v[0, :3]) @ basis.T
    dl = d @ basis.T
    return p, dl, a, basis


def _nearest(ts: list[np.ndarray], ns: list[np.ndarray], t_max: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.full(ts[0].shape, np.inf)
    n = np.zeros((*ts[0].shape, 3))
    for tc, nc in zip(ts, ns, strict=True):
        ok = np.isfinite(tc) & (tc > 0) & (tc < t_max) & (tc < t)
        t = np.where(ok, tc, t)
        n = np.where(ok[:, None], nc, n)
    return t.astype(np.float64), n.astype(np.float64)


def oracle_quadric(o, d, v, t_max: float = T_MAX) -> tuple[np.ndarray, np.ndarray]:
    """Cylinder, cone or disk: nearest t (inf: miss) and outward normal, float64 from longdouble."""
    v = np.asarray(v)
    kind = int(round(float(v[2, 2])))
    p, dl, a, basis = _local(o, d, v)
    r0, r1 = L(v[0, 3]), L(v[1, 3])
    h = L(v[2, 0])
    n_shape = len(p)
    ts, ns = [], []

    def cap(zc, r_out, r_in, normal):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = (zc - p[:, 2]) / dl[:, 2]
            x = p[:, 0] + t * dl[:, 0]
            y = p[:, 1] + t * dl[:, 1]
            rr = x * x + y * y
            ok = (dl[:, 2] != 0) & (rr <= r_out * r_out) & (rr >= r_in * r_in)
        ts.append(np.where(ok, t, np.inf))
        ns.append(np.broadcast_to(normal, (n_shape, 3)))

    if kind == DISK:
        cap(L(0), r0, r1, a.astype(np.float64))
        return _nearest(ts, ns, t_max)
    m = (r1 - r0) / h if h > 0 else L(0)
    w0 = r0 + m * p[:, 2]
    A = dl[:, 0] ** 2 + dl[:, 1] ** 2 - (m * dl[:, 2]) ** 2
    B = p[:, 0] * dl[:, 0] + p[:, 1] * dl[:, 1] - m * dl[:, 2] * w0
    C = p[:, 0] ** 2 + p[:, 1] ** 2 - w0 * w0
    disc = B * B - A * C
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(disc >= 0, disc, L(0)))
        for sgn in (-1, 1):
            t = np.where(A != 0, (-B + sgn * sq) / A, -C / (2 * B))
            z = p[:, 2] + t * dl[:, 2]
            ok = (disc >= 0) & (z >= 0) & (z <= h) & (r0 + m * z >= 0) & ~((A == 0) & (B == 0))
            x = p[:, 0] + t * dl[:, 0]
            y = p[:, 1] + t * dl[:, 1]
            rho = np.sqrt(x * x + y * y)
            g = np.stack([x / rho, y / rho, -m * np.ones_like(x)], axis=-1)
            g = g / np.sqrt((g * g).sum(-1, keepdims=True))
            ts.append(np.where(ok, t, np.inf))
            ns.append((g @ basis).astype(np.float64))
    if v[2, 1] > 0.5:
        cap(L(0), r0, L(0), -a.astype(np.float64))
        cap(h, r1, L(0), a.astype(np.float64))
    return _nearest(ts, ns, t_max)


def _torus_E(p, dl, s, R, r):
    x = p[:, 0] + s * dl[:, 0]
    y = p[:, 1] + s * dl[:, 1]
    z = p[:, 2] + s * dl[:, 2]
    rho = np.sqrt(x * x + y * y)
    e = z * z + (rho - R - r) * (rho - R + r)
    de = 2 * (z * dl[:, 2] + (x * dl[:, 0] + y * dl[:, 1]) * (rho - R) / rho)
    return e, de, x, y, z, rho


def oracle_torus(o, d, v, t_max: float = T_MAX) -> tuple[np.ndarray, np.ndarray]:
    """The torus: nearest t (inf: miss) and outward normal, float64."""
    v = np.asarray(v)
    p, dl, a, basis = _local(o, d, v)
    R, r = L(v[0, 3]), L(v[1, 3])
    b = (p * dl).sum(-1)
    f = p - b[:, None] * dl  # the closest point to the centre: s = t + b
    e = (f * dl).sum(-1)
    c = (f * f).sum(-1)
    k = dl[:, 0] ** 2 + dl[:, 1] ** 2
    w = f[:, 0] * dl[:, 0] + f[:, 1] * dl[:, 1]
    rho2 = f[:, 0] ** 2 + f[:, 1] ** 2
    rho = np.sqrt(rho2)
    zs2 = f[:, 2] ** 2
    A = c + R * R - r * r
    e0 = zs2 + (rho - R - r) * (rho - R + r)
    h0 = zs2 + (rho + R - r) * (rho + R + r)
    c3 = 4 * e
    c2 = 4 * e * e + 2 * A - 4 * R * R * k
    c1 = 4 * e * A - 8 * R * R * w
    c0 = e0 * h0
    coef = np.stack([c3 / R, c2 / R**2, c1 / R**3, c0 / R**4], axis=-1).astype(np.float64)
    comp = np.zeros((len(p), 4, 4))
    comp[:, 0, :] = -coef
    comp[:, 1, 0] = comp[:, 2, 1] = comp[:, 3, 2] = 1.0
    roots = np.linalg.eigvals(comp)
    cands = []
    for j in range(4):
        u = roots[:, j]
        s = (u.real * float(R)).astype(L)
        real = np.abs(u.imag) < 1e-5
        for _ in range(8):
            ev, de, *_ = _torus_E(f, dl, s, R, r)
            with np.errstate(divide="ignore", invalid="ignore"):
                s = np.where(de != 0, s - ev / de, s)
        ev, *_ = _torus_E(f, dl, s, R, r)
        ok = real & (np.abs(ev) <= L(1e-12) * (R + r) ** 2)
        cands.append(np.where(ok, s - b, np.inf))
    t, _ = _nearest(cands, [np.zeros((len(p), 3))] * 4, t_max)
    s = np.where(np.isfinite(t), t, 0).astype(L) + b
    _, _, x, y, z, rh = _torus_E(f, dl, s, R, r)
    g = np.stack([x * (rh - R) / rh, y * (rh - R) / rh, z], axis=-1)
    g = g / np.sqrt((g * g).sum(-1, keepdims=True))
    return t, (g @ basis).astype(np.float64)


def oracle(o, d, v, t_max: float = T_MAX) -> tuple[np.ndarray, np.ndarray]:
    """Nearest t (inf: miss) and outward normal of any kind."""
    kind = int(round(float(np.asarray(v)[2, 2])))
    return (oracle_torus if kind == TORUS else oracle_quadric)(o, d, v, t_max)


# --------------------------------------------------------------------------- the cases


@dataclass(frozen=True)
class Case:
    """A shape and rays as built in float64; ``shape``, ``o`` and ``d`` are what the GPU gets (float32)."""

    name: str
    what: str
    shape64: np.ndarray  # (3, 4)
    o64: np.ndarray  # (N, 3)
    d64: np.ndarray  # (N, 3), unit
    min_agreement: float = AGREEMENT
    why: str = ""
    # Against the oracle of the float64 inputs (the rounding of the inputs included).
    f64_min_agreement: float = AGREEMENT
    f64_why: str = ""

    def __post_init__(self) -> None:
        if self.min_agreement < AGREEMENT and not self.why:
            raise ValueError(f"{self.name}: a threshold below {AGREEMENT} needs a reason")
        if self.f64_min_agreement < AGREEMENT and not (self.f64_why or self.why):
            raise ValueError(f"{self.name}: a float64-input threshold below {AGREEMENT} needs a reason")

    @property
    def shape(self) -> np.ndarray:
        return self.shape64.astype(np.float32)

    @property
    def o(self) -> np.ndarray:
        return self.o64.astype(np.float32)

    @property
    def d(self) -> np.ndarray:
        return self.d64.astype(np.float32)


@dataclass(frozen=True)
class Score:
    agreement: float  # share of rays: same hit/miss, depth within DEPTH_REL
    mask_diff: int  # rays whose hit/miss differs
    depth_bad: int  # rays hit by both whose depth differs by more than DEPTH_REL
    max_rel_dt: float  # over the rays both hit
    max_normal_deg: float  # over the rays both hit
    hits: int  # rays the oracle hits


def score(t: np.ndarray, n: np.ndarray, t_ref: np.ndarray, n_ref: np.ndarray) -> Score:
    hit = t < BIG
    ref = np.isfinite(t_ref)
    both = hit & ref
    rel = np.abs(t[both].astype(np.float64) - t_ref[both]) / t_ref[both]
    bad = int((rel > DEPTH_REL).sum())
    mask = int((hit != ref).sum())
    cos = np.clip((n[both].astype(np.float64) * n_ref[both]).sum(-1), -1, 1)
    return Score(
        agreement=1.0 - (mask + bad) / len(t),
        mask_diff=mask,
        depth_bad=bad,
        max_rel_dt=float(rel.max()) if rel.size else 0.0,
        max_normal_deg=float(np.degrees(np.arccos(cos)).max()) if cos.size else 0.0,
        hits=int(ref.sum()),
    )


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def _torus_points(rng, n, R, r, center, axis):
    """Random points on a torus, their outward normals (float64)."""
    e1, e2, a = _frame(axis)
    th = rng.uniform(0, 2 * np.pi, n)
    ph = rng.uniform(0, 2 * np.pi, n)
    radial = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
    nrm = np.cos(ph)[:, None] * radial + np.sin(ph)[:, None] * a
    pts = np.asarray(center, dtype=np.float64) + R * radial + r * nrm
    return pts, nrm


def grazing_rays(rng, pts, nrm, offset: float, back: float = 5.0) -> tuple[np.ndarray, np.ndarray]:
    """Rays tangent to the surface at pts, moved off it along the normal by ±offset (half each)."""
    n = len(pts)
    rand = _unit(rng.normal(size=(n, 3)))
    tang = _unit(rand - (rand * nrm).sum(-1, keepdims=True) * nrm)
    sgn = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]
    o = pts + sgn * offset * nrm - back * tang
    return o, tang


def _torus_grazing(name, R, r, offset, center=(0.0, 0.0, 0.0), axis=(0.2, 1.0, 0.3), seed=1, what="", **kw) -> Case:
    rng = _rng(seed)
    pts, nrm = _torus_points(rng, SIDE * SIDE, R, r, center, axis)
    o, d = grazing_rays(rng, pts, nrm, offset, back=5.0 * R)
    return Case(name, what, pack(TORUS, center, axis, R, r), o, d, **kw)


def _axis_rays(center, axis, extent: float, tilt: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays parallel to the axis (every other one tilted by ~tilt) from a grid across the shape."""
    rng = _rng(seed)
    e1, e2, a = _frame(axis)
    u = (np.arange(SIDE) + 0.5) / SIDE * 2 - 1
    uu, vv = np.meshgrid(u * extent, u * extent)
    uu[SIDE // 2, SIDE // 2] = vv[SIDE // 2, SIDE // 2] = 0.0  # one ray exactly along the axis
    o = np.asarray(center) + uu.reshape(-1, 1) * e1 + vv.reshape(-1, 1) * e2 - 4.0 * extent * a
    d = np.broadcast_to(a, o.shape).copy()
    j = np.arange(len(d)) % 2 == 1
    d[j] = _unit(d[j] + tilt * rng.normal(size=(j.sum(), 3)))
    return o, d


def _hole_rays(center, axis, R, r, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays through random points of the hole (rho < R − r in the torus's plane), from all sides."""
    rng = _rng(seed)
    e1, e2, a = _frame(axis)
    n = SIDE * SIDE
    rad = (R - r) * np.sqrt(rng.uniform(0, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    p = np.asarray(center) + rad[:, None] * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
    d = _unit(rng.normal(size=(n, 3)))
    return p - 4.0 * (R + r) * d, d


def _cylinder_grazing(rng, n, radius, height, center, axis, offset):
    e1, e2, a = _frame(axis)
    th = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(0, height, n)
    radial = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
    pts = np.asarray(center) + radius * radial + z[:, None] * a
    tang0 = np.cross(a, radial)  # tangent, perpendicular to the axis
    mix = rng.uniform(-0.6, 0.6, n)[:, None]
    tang = _unit(tang0 + mix * a)
    sgn = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)[:, None]
    o = pts + sgn * offset * radial - 5.0 * tang
    return o, tang


def _cases() -> list[Case]:
    cases: list[Case] = []
    ax = (0.2, 1.0, 0.3)
    cases.append(
        Case(
            "torus_view",
            "a torus seen obliquely: silhouettes, the hole, four-root rays",
            pack(TORUS, (0.0, 0.0, 0.0), ax, 1.0, 0.25),
            *camera_rays((0.5, 3.0, 4.0), (0.0, 0.0, 0.0), 40.0),
        )
    )
    cases.append(
        _torus_grazing(
            "torus_grazing",
            1.0,
            0.25,
            1e-4 * 0.25,
            what="rays tangent to the tube, 1e-4·r off it, half inside (a pair of roots 0.03·r apart), half outside",
        )
    )
    o, d = _axis_rays((0.0, 0.0, 0.0), ax, 1.4, 1e-3, 3)
    cases.append(
        Case(
            "torus_axis",
            "rays parallel to the axis (half tilted by ~1e-3), one exactly along it: k = |dq|² = 0",
            pack(TORUS, (0.0, 0.0, 0.0), ax, 1.0, 0.25),
            o,
            d,
        )
    )
    o, d = _hole_rays((0.0, 0.0, 0.0), ax, 1.0, 0.25, 4)
    cases.append(
        Case(
            "torus_hole",
            "rays through the hole from every direction: the concave piece of D, four roots or none",
            pack(TORUS, (0.0, 0.0, 0.0), ax, 1.0, 0.25),
            o,
            d,
        )
    )
    far = (1.0e4, -1.0e4, 1.0e4)
    cases.append(
        Case(
            "torus_at_1e4",
            "torus and camera 1e4 from the origin (float32 spacing 1e-3), camera 6 units away",
            pack(TORUS, far, ax, 1.0, 0.25),
            *camera_rays((far[0] + 2.0, far[1] + 3.0, far[2] + 5.0), far, 40.0),
        )
    )
    far_cam = (1.0e4 / np.sqrt(3.0)) * np.array([1.0, -1.0, 1.0]) + np.array([1.0e2, 2.0e2, -1.0e2])
    cases.append(
        Case(
            "torus_1e4_from_camera",
            "a torus (R = 100, r = 25) 1e4 from the camera at the origin: f = p0 − b·d has ~1e-3 rounding",
            pack(TORUS, far_cam, ax, 100.0, 25.0),
            *camera_rays((0.0, 0.0, 0.0), far_cam, 1.6),
        )
    )
    cases.append(
        _torus_grazing(
            "torus_grazing_at_1e4",
            1.0,
            0.25,
            1e-3 * 0.25,
            center=far,
            what="grazing rays 1e-3·r off the tube of a torus at 1e4 (the ray origins 5 units away)",
            f64_min_agreement=0.35,
            f64_why=(
                "float32 spacing at 1e4 is 1e-3: storing the ray origins and the centre moves each ray by up"
                " to ~5e-4, twice its 2.5e-4 offset from the tube, so which rays graze inside is decided by the"
                " rounding of the inputs (measured 39 %); against the float32-stored inputs every ray agrees"
            ),
        )
    )
    cases.append(
        Case(
            "torus_thin_view",
            "thin torus r/R = 1e-3 seen obliquely: the quartic's coefficients cancel to 1e-6",
            pack(TORUS, (0.0, 0.0, 0.0), ax, 1.0, 1e-3),
            *camera_rays((0.5, 3.0, 4.0), (0.0, 0.0, 0.0), 40.0),
        )
    )
    cases.append(
        _torus_grazing(
            "torus_thin_grazing",
            1.0,
            1e-3,
            1e-4,
            what="rays tangent to a thin torus's tube (r/R = 1e-3), 1e-4·R = 0.1·r off it",
        )
    )
    rng = _rng(7)
    pts, nrm = _torus_points(rng, SIDE * SIDE, 1.0, 1e-3, (0, 0, 0), ax)
    pts = pts - rng.uniform(0.1e-3, 1e-3, (len(pts), 1)) * nrm  # inside the tube
    dd = _unit(rng.normal(size=pts.shape))
    cases.append(
        Case(
            "torus_thin_aimed",
            "rays from 5 units through random points inside a thin torus's tube (r/R = 1e-3)",
            pack(TORUS, (0.0, 0.0, 0.0), ax, 1.0, 1e-3),
            pts - 5.0 * dd,
            dd,
        )
    )
    cyl_axis = (0.1, 1.0, -0.2)
    cases.append(
        Case(
            "cylinder_view",
            "a capped cylinder seen obliquely",
            pack(CYLINDER, (0.0, -0.5, 0.0), cyl_axis, 0.5, 0.5, 1.0, True),
            *camera_rays((0.3, 2.0, 4.0), (0.0, 0.0, 0.0), 30.0),
        )
    )
    rng = _rng(8)
    cases.append(
        Case(
            "cylinder_grazing",
            "rays tangent to the lateral surface, 1e-4·radius off it",
            pack(CYLINDER, (0.0, -0.5, 0.0), cyl_axis, 0.5, 0.5, 1.0, False),
            *_cylinder_grazing(rng, SIDE * SIDE, 0.5, 1.0, (0.0, -0.5, 0.0), cyl_axis, 1e-4 * 0.5),
        )
    )
    o, d = _axis_rays((0.0, -0.5, 0.0), cyl_axis, 0.7, 1e-3, 9)
    cases.append(
        Case(
            "cylinder_axis",
            "rays along the axis of a capped cylinder: the lateral quadratic degenerates (A = B = 0)",
            pack(CYLINDER, (0.0, -0.5, 0.0), cyl_axis, 0.5, 0.5, 1.0, True),
            o,
            d,
        )
    )
    cases.append(
        Case(
            "cylinder_height_1e-6",
            "a capped cylinder of height 1e-6 (a coin): two caps 1e-6 apart, a lateral band 1e-6 wide",
            pack(CYLINDER, (0.0, 0.0, 0.0), cyl_axis, 0.5, 0.5, 1e-6, True),
            *camera_rays((0.3, 2.0, 4.0), (0.0, 0.0, 0.0), 20.0),
        )
    )
    e1, e2, a = _frame(cyl_axis)
    top = 1.0 * a + np.array([0.0, -0.5, 0.0])
    cam = top + 3.0 * e1 + 1e-5 * a  # in the top cap's plane, 1e-5 above it
    cases.append(
        Case(
            "cap_edge_on",
            "a capped cylinder's top cap seen edge-on from 1e-5 above its plane",
            pack(CYLINDER, (0.0, -0.5, 0.0), cyl_axis, 0.5, 0.5, 1.0, True),
            *camera_rays(cam, top, 20.0),
        )
    )
    cases.append(
        Case(
            "disk_edge_on",
            "an annulus (inner radius 0.3) seen nearly edge-on: camera 0.01 above its plane, 3 away",
            pack(DISK, (0.0, 0.0, 0.0), cyl_axis, 1.0, 0.3),
            *camera_rays(3.0 * e1 + 1e-2 * a, (0.0, 0.0, 0.0), 0.6),
        )
    )
    cases.append(
        Case(
            "disk_edge_on_1e-6",
            "an annulus seen edge-on from 1e-6 above its plane, 3 away (rays 1e-8 rad apart)",
            pack(DISK, (0.0, 0.0, 0.0), cyl_axis, 1.0, 0.3),
            *camera_rays(3.0 * e1 + 1e-6 * a, (0.0, 0.0, 0.0), 1.2e-4),
            min_agreement=0.85,
            f64_min_agreement=0.85,
            why=(
                "the camera's height above the plane, z0 = dot(o − c, axis) = 1e-6, is a sum of products"
                " of size 3 rounded to float32 (spacing 2.4e-7): the GPU's z0, and t = −z0/dz with it, is off"
                " by up to ~20 %, beyond any formula's reach without extended precision (measured 90.7 %)"
            ),
        )
    )
    cases.append(
        Case(
            "disk_view",
            "an annulus seen obliquely",
            pack(DISK, (0.0, 0.0, 0.0), cyl_axis, 1.0, 0.3),
            *camera_rays((0.5, 3.0, 2.0), (0.0, 0.0, 0.0), 50.0),
        )
    )
    cases.append(
        Case(
            "cone_apex_view",
            "a capped cone with top radius 0 (an apex) seen obliquely",
            pack(CONE, (0.0, -0.5, 0.0), cyl_axis, 0.6, 0.0, 1.2, True),
            *camera_rays((0.5, 2.5, 4.0), (0.0, 0.0, 0.0), 35.0),
        )
    )
    apex = np.array([0.0, -0.5, 0.0]) + 1.2 * a
    cases.append(
        Case(
            "cone_apex_aimed",
            "rays aimed within 1e-3 of a cone's apex from 4 units",
            pack(CONE, (0.0, -0.5, 0.0), cyl_axis, 0.6, 0.0, 1.2, True),
            *camera_rays(apex + 4.0 * _unit(np.array([1.0, 0.8, 0.3])), apex, 0.03),
        )
    )
    cases.append(
        Case(
            "frustum_at_1e4",
            "a capped frustum and camera 1e4 from the origin",
            pack(CONE, far, cyl_axis, 0.6, 0.3, 1.0, True),
            *camera_rays((far[0] + 2.0, far[1] + 3.0, far[2] + 4.0), far, 35.0),
        )
    )
    return cases


CASES: list[Case] = _cases()
BY_NAME: dict[str, Case] = {c.name: c for c in CASES}


@cache
def reference(name: str, exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """A case's oracle (t, n) for the shape and rays as float32 stores them, or with ``exact`` as
    built in float64 (what input rounding adds), computed once per process."""
    c = BY_NAME[name]
    if exact:
        return oracle(c.o64, c.d64, c.shape64)
    return oracle(c.o, c.d, c.shape)
