"""Analytic shapes: cylinders, cones (frusta), disks (annuli) and tori, in float64.

The curved surfaces as they are, not as triangles: one record of 12 numbers each
(:attr:`Shapes.params`, the layout the GPU records are made from), their exact bounding
boxes (:func:`bounds`) and the float64 ray intersection every reference test trusts
(:func:`intersect`). docs/FORMATS.md ("Analytic shapes") is the contract: JSON keys, id
order (cylinders, cones, disks, tori, after the triangles), validation.

Record layout, float64 (N, 12) — keep it: the GPU side packs the same numbers:

====== ============================================================================
[0:3]  origin: cylinder / cone base centre, disk / torus centre
[3]    r0: cylinder radius, cone base_radius, disk radius, torus major_radius
[4:7]  unit axis (a disk's normal); the cylinder and cone rise along it
[7]    r1: cylinder radius (= r0), cone top_radius, disk inner_radius (0: a full
       disk), torus minor_radius
[8]    height (cylinder, cone; 0 for disks and tori)
[9]    caps: 1.0 closed by its end disks, 0.0 open (cylinder, cone; 0 otherwise)
[10]   the kind as a float (CYLINDER 0, CONE 1, DISK 2, TORUS 3)
[11]   0
====== ============================================================================

Intersection (docs/SHADING.md, "Analytic shapes"): every root in closed form, each computed
so that a root near 0 keeps its relative precision (the larger root directly, the other from
the product of the roots, as the sphere's). The torus quartic is solved in the torus's own
frame, scaled by its major radius, from the point of the ray nearest its centre: there the
coefficients are O(1) whatever the distance. Its real roots are bracketed between the
critical points (the cubic's roots, in closed form: a spurious breakpoint is harmless, a
missed one is not, so all three real parts are kept) and bisected to the last bit on the
distance to the core circle, whose sign is the quartic's and whose rounding is ρ times
smaller. A ray that leaves a shape (``src``) ignores that shape's root nearest 0 — the one at
its own origin — and no other: a ray inside a cylinder meets its far wall, a ray leaving a
torus may meet it again; no epsilon anywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import limits
from ..errors import SceneError
from ..limits import MAX_COORDINATE

CYLINDER, CONE, DISK, TORUS = 0, 1, 2, 3
KINDS = ("cylinders", "cones", "disks", "tori")  # the JSON keys, in id order
N_PARAMS = 12
_EPS = float(np.finfo(np.float64).eps)

# Per kind: the JSON field each record number comes from (the names a SceneError gives).
_FIELDS: dict[int, dict[int, str]] = {
    CYLINDER: {0: "base", 1: "base", 2: "base", 3: "radius", 4: "axis", 5: "axis", 6: "axis", 7: "radius"}
    | {8: "height", 9: "caps"},
    CONE: {0: "base", 1: "base", 2: "base", 3: "base_radius", 4: "axis", 5: "axis", 6: "axis", 7: "top_radius"}
    | {8: "height", 9: "caps"},
    DISK: {0: "center", 1: "center", 2: "center", 3: "radius", 4: "normal", 5: "normal", 6: "normal"}
    | {7: "inner_radius", 8: "height", 9: "caps"},
    TORUS: {0: "center", 1: "center", 2: "center", 3: "major_radius", 4: "axis", 5: "axis", 6: "axis"}
    | {7: "minor_radius", 8: "height", 9: "caps"},
}
# Per kind: the JSON object's fields (material aside), required ones first.
_JSON_FIELDS = {
    CYLINDER: (("base", "axis", "radius", "height"), ("caps",)),
    CONE: (("base", "axis", "base_radius", "top_radius", "height"), ("caps",)),
    DISK: (("center", "normal", "radius"), ("inner_radius",)),
    TORUS: (("center", "axis", "major_radius", "minor_radius"), ()),
}


def _where(kind: int, j: int, name: str) -> str:
    return f"{KINDS[kind]}[{j}].{name}"


@dataclass(frozen=True, eq=False)
class Shapes:
    """The scene's analytic shapes in id order (cylinders, cones, disks, tori); read-only arrays.

    ``kind`` int8 (N,), ``params`` float64 (N, 12) (the module's layout), ``material`` int32
    (N,). Validated on construction: a SceneError names the JSON field
    (``cones[2].top_radius``) and the accepted range. A non-unit axis is normalised (a unit
    one is kept bit for bit, so a JSON round trip gives the same records). Material indices
    are checked by the scene, which knows how many materials there are.
    """

    kind: np.ndarray
    params: np.ndarray
    material: np.ndarray

    def __post_init__(self) -> None:
        kind = np.asarray(self.kind).reshape(-1)
        if kind.dtype.kind not in "iu":
            raise SceneError("shapes", f"kind: expected integers, got {kind.dtype}")
        kind = kind.astype(np.int8)
        p = np.array(self.params, dtype=np.float64).reshape(-1, N_PARAMS) if len(kind) else np.zeros((0, N_PARAMS))
        m = np.asarray(self.material).reshape(-1)
        if not (len(kind) == len(p) == len(m)):
            raise SceneError("shapes", "kind, params and material differ in length")
        if len(kind) > limits.MAX_SHAPES:
            raise SceneError("shapes", f"at most {limits.MAX_SHAPES} analytic shapes per scene, got {len(kind)}")
        if ((kind < 0) | (kind > TORUS)).any():
            raise SceneError("shapes", f"unknown kind {int(kind[(kind < 0) | (kind > TORUS)][0])} (0 … 3)")
        if (np.diff(kind.astype(np.int64)) < 0).any():
            raise SceneError("shapes", "not in id order (cylinders, cones, disks, tori)")
        if m.dtype.kind not in "iu":
            raise SceneError("shapes", f"material: expected integer indices, got {m.dtype}")
        # The common case at C speed; only a bad record is walked in Python, to name its field.
        bad = np.flatnonzero(~_rows_ok(p, kind))
        if len(bad):
            i = int(bad[0])
            _check_row(p[i].copy(), int(kind[i]), i - int(np.searchsorted(kind, kind[i])))
            raise AssertionError(f"shape {i} failed the fast check only")  # the two checks disagree
        n = np.sqrt(_dot(p[:, 4:7], p[:, 4:7]))
        off = np.abs(n - 1.0) > 4 * _EPS  # a unit axis stays as it is: JSON round trips are exact
        p[off, 4:7] /= n[off, None]
        m = m.astype(np.int32)
        for a in (kind, p, m):
            a.setflags(write=False)
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "params", p)
        object.__setattr__(self, "material", m)

    @staticmethod
    def empty() -> Shapes:
        return Shapes(np.zeros(0, np.int8), np.zeros((0, N_PARAMS)), np.zeros(0, np.int32))

    def __len__(self) -> int:
        return len(self.kind)

    def counts(self) -> dict[str, int]:
        """Shapes of each kind, by JSON key."""
        return {key: int((self.kind == k).sum()) for k, key in enumerate(KINDS)}

    def where(self, i: int) -> str:
        """The JSON path of shape ``i`` (``disks[3]``)."""
        k = int(self.kind[i])
        return f"{KINDS[k]}[{i - int(np.searchsorted(self.kind, k))}]"

    def with_placement(self, origins: np.ndarray, axes: np.ndarray | None = None) -> Shapes:
        """The same shapes moved: new origins (N, 3) and, when given, axes (N, 3) (validated)."""
        p = self.params.copy()
        p[:, 0:3] = origins
        if axes is not None:
            p[:, 4:7] = axes
        return Shapes(self.kind, p, self.material)

    # ---- JSON (docs/FORMATS.md, "Analytic shapes") ----------------------------------------
    def to_json(self) -> dict[str, list[dict]]:
        """The four JSON keys, each only when it has shapes."""
        out: dict[str, list[dict]] = {}
        for k, row, mat in zip(self.kind.tolist(), self.params.tolist(), self.material.tolist(), strict=True):
            o, r0, ax, r1, h, caps = row[0:3], row[3], row[4:7], row[7], row[8], row[9] != 0.0
            d: dict[str, Any]
            if k == CYLINDER:
                d = {"base": o, "axis": ax, "radius": r0, "height": h, "caps": caps}
            elif k == CONE:
                d = {"base": o, "axis": ax, "base_radius": r0, "top_radius": r1, "height": h, "caps": caps}
            elif k == DISK:
                d = {"center": o, "normal": ax, "radius": r0}
                if r1 > 0.0:
                    d["inner_radius"] = r1
            else:
                d = {"center": o, "axis": ax, "major_radius": r0, "minor_radius": r1}
            d["material"] = mat
            out.setdefault(KINDS[k], []).append(d)
        return out

    @staticmethod
    def from_json(d: dict) -> Shapes:
        """The shapes of a scene JSON object's ``cylinders``, ``cones``, ``disks``, ``tori``."""
        lists = {}
        total = 0
        for k, key in enumerate(KINDS):
            raw = d.get(key, [])
            if not isinstance(raw, (list, tuple)):
                raise SceneError(key, "expected a list")
            total += len(raw)
            if total > limits.MAX_SHAPES:
                raise SceneError(key, f"at most {limits.MAX_SHAPES} analytic shapes per scene, got {total} or more")
            lists[k] = raw
        kinds, rows, mats = [], [], []
        for k, raw in lists.items():
            for j, x in enumerate(raw):
                rows.append(_row_from_json(x, k, j))
                kinds.append(k)
                mats.append(_material(x.get("material", 0), _where(k, j, "material")))
        if not rows:
            return Shapes.empty()
        return Shapes(np.array(kinds, np.int8), np.array(rows), np.array(mats, np.int64))


def _number(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise SceneError(where, f"expected a number, got {type(v).__name__}")
    try:
        return float(v)
    except OverflowError:
        raise SceneError(where, "a number too large for float64") from None


def _vec3(v: Any, where: str) -> list[float]:
    if not isinstance(v, (list, tuple, np.ndarray)) or len(v) != 3:
        raise SceneError(where, "expected a list of 3 numbers")
    return [_number(x, f"{where}[{i}]") for i, x in enumerate(v)]


def _material(v: Any, where: str) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) and not (isinstance(v, float) and v.is_integer()):
        raise SceneError(where, "expected an integer material index")
    return int(v)


def _row_from_json(x: Any, k: int, j: int) -> list[float]:
    """One JSON object as a record (validated by :func:`_check_row` afterwards)."""
    required, optional = _JSON_FIELDS[k]
    where = f"{KINDS[k]}[{j}]"
    if not isinstance(x, dict):
        raise SceneError(where, "expected an object")
    allowed = {*required, *optional, "material"}
    unknown = set(x) - allowed
    if unknown:
        raise SceneError(f"{where}.{sorted(unknown)[0]}", f"unknown field (allowed: {', '.join(sorted(allowed))})")
    for name in required:
        if name not in x:
            raise SceneError(f"{where}.{name}", "field required")
    row = [0.0] * N_PARAMS
    row[0:3] = _vec3(x[required[0]], f"{where}.{required[0]}")
    row[4:7] = _vec3(x[required[1]], f"{where}.{required[1]}")
    row[10] = float(k)
    if k in (CYLINDER, CONE):
        caps = x.get("caps", True)
        if not isinstance(caps, bool):
            raise SceneError(f"{where}.caps", f"expected true or false, got {type(caps).__name__}")
        row[9] = 1.0 if caps else 0.0
    if k == CYLINDER:
        row[3] = row[7] = _number(x["radius"], f"{where}.radius")
        row[8] = _number(x["height"], f"{where}.height")
    elif k == CONE:
        row[3] = _number(x["base_radius"], f"{where}.base_radius")
        row[7] = _number(x["top_radius"], f"{where}.top_radius")
        row[8] = _number(x["height"], f"{where}.height")
    elif k == DISK:
        row[3] = _number(x["radius"], f"{where}.radius")
        row[7] = _number(x.get("inner_radius", 0.0), f"{where}.inner_radius")
    else:
        row[3] = _number(x["major_radius"], f"{where}.major_radius")
        row[7] = _number(x["minor_radius"], f"{where}.minor_radius")
    return row


def _rows_ok(p: np.ndarray, kind: np.ndarray) -> np.ndarray:
    """bool (N,): the records :func:`_check_row` accepts, all at once."""
    with np.errstate(invalid="ignore", over="ignore"):
        ok = np.isfinite(p[:, :10]).all(axis=1) & (np.abs(p[:, 0:3]) <= MAX_COORDINATE).all(axis=1)
        ok &= (p[:, 10] == kind) & (p[:, 11] == 0.0)
        n = np.sqrt(_dot(p[:, 4:7], p[:, 4:7]))
        ok &= (n > 1e-12) & np.isfinite(n)
        r0, r1, h, caps = p[:, 3], p[:, 7], p[:, 8], p[:, 9]
        in_range = (r0 <= MAX_COORDINATE) & (r1 <= MAX_COORDINATE)
        tube = (kind == CYLINDER) | (kind == CONE)
        ok &= np.where(
            tube, (h > 0.0) & (h <= MAX_COORDINATE) & ((caps == 0.0) | (caps == 1.0)), (h == 0) & (caps == 0)
        )
        ok &= np.where(kind == CYLINDER, (r0 > 0.0) & (r1 == r0) & in_range, True)
        ok &= np.where(kind == CONE, (r0 >= 0.0) & (r1 >= 0.0) & ((r0 > 0.0) | (r1 > 0.0)) & in_range, True)
        ok &= np.where(kind == DISK, (r0 > 0.0) & in_range & (r1 >= 0.0) & (r1 < r0), True)
        ok &= np.where(kind == TORUS, (r0 > 0.0) & in_range & (r1 > 0.0) & (r1 < r0), True)
    return ok


def _check_row(p: np.ndarray, k: int, j: int) -> None:
    """Validate record ``p`` of shape ``j`` of kind ``k``: a SceneError names its first bad field."""
    names = _FIELDS[k]
    for c in range(10):
        if not math.isfinite(p[c]):
            raise SceneError(_where(k, j, names[c]), f"must be a finite number, got {p[c]}")
    origin = names[0]
    if (np.abs(p[0:3]) > MAX_COORDINATE).any():
        raise SceneError(_where(k, j, origin), f"must be within ±{MAX_COORDINATE:g}, got {p[0:3].tolist()}")
    if p[10] != k or p[11] != 0.0:
        raise SceneError(_where(k, j, "kind"), f"record numbers 10, 11 must be {k}, 0; got {p[10]}, {p[11]}")
    n = math.sqrt(float(p[4] * p[4] + p[5] * p[5] + p[6] * p[6]))
    if not n > 1e-12 or not math.isfinite(n):
        raise SceneError(_where(k, j, names[4]), "must be a non-zero vector")

    def radius(c: int, *, zero: bool = False, below: float | None = None, what: str = "") -> None:
        x = float(p[c])
        hi = MAX_COORDINATE if below is None else below
        ok = (x >= 0.0 if zero else x > 0.0) and (x <= hi if below is None else x < hi)
        if not ok:
            lo = ">= 0" if zero else "> 0"
            top = f"<= {MAX_COORDINATE:g}" if below is None else f"< {what} ({below:g})"
            raise SceneError(_where(k, j, names[c]), f"must be {lo} and {top}, got {x:g}")

    if k in (CYLINDER, CONE):
        radius(8)
        if p[9] not in (0.0, 1.0):
            raise SceneError(_where(k, j, "caps"), f"must be true or false (1.0 or 0.0), got {p[9]}")
    elif p[8] != 0.0 or p[9] != 0.0:
        raise SceneError(_where(k, j, "height"), f"a {KINDS[k][:-1]} has no height nor caps (record numbers 8, 9: 0)")
    if k == CYLINDER:
        radius(3)
        if p[7] != p[3]:
            raise SceneError(_where(k, j, "radius"), f"record number 7 must equal the radius {p[3]:g}, got {p[7]:g}")
    elif k == CONE:
        radius(3, zero=True)
        radius(7, zero=True)
        if not (p[3] > 0.0 or p[7] > 0.0):
            raise SceneError(_where(k, j, "base_radius"), "base_radius or top_radius must be > 0 (both are 0)")
    elif k == DISK:
        radius(3)
        radius(7, zero=True, below=float(p[3]), what="radius")
    else:
        radius(3)
        radius(7, below=float(p[3]), what="major_radius")


# ----------------------------------------------------------------------------- geometry


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...j,...j->...", a, b)


def bounds(shapes: Shapes) -> np.ndarray:
    """float64 (N, 2, 3): each shape's tight axis-aligned box (min, max), exact for these forms.

    A circle of centre c, unit normal n and radius r spans ``c_i ± r·√(1 − n_i²)`` along axis
    i; a cylinder or cone is the convex hull of its two end circles (the box of both), a
    torus the core circle swept by a ball of the minor radius (``± (R·√(1 − a_i²) + r)``).
    """
    p = shapes.params
    out = np.zeros((len(p), 2, 3))
    if not len(p):
        return out
    c, a = p[:, 0:3], p[:, 4:7]
    r0, r1, h = p[:, 3:4], p[:, 7:8], p[:, 8:9]
    e = np.sqrt(np.maximum(1.0 - a * a, 0.0))
    kind = shapes.kind
    # Cylinders and cones: the boxes of the base circle (r0) and the top circle (r1).
    top = c + h * a
    lo = np.minimum(c - r0 * e, top - r1 * e)
    hi = np.maximum(c + r0 * e, top + r1 * e)
    disk = kind == DISK
    lo[disk], hi[disk] = (c - r0 * e)[disk], (c + r0 * e)[disk]
    torus = kind == TORUS
    lo[torus], hi[torus] = (c - r0 * e - r1)[torus], (c + r0 * e + r1)[torus]
    out[:, 0], out[:, 1] = lo, hi
    return out


def _quadric_roots(q: np.ndarray, d: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed roots (K, 4) of rays (q = origin − base, d) with cylinders / cones ``p``: the
    side's two, then the base cap's and the top cap's (NaN where none)."""
    a, r0, r1, h, caps = p[:, 4:7], p[:, 3], p[:, 7], p[:, 8], p[:, 9] != 0.0
    k = (r1 - r0) / h  # the radius grows k per unit of height
    qz, dz = _dot(q, a), _dot(d, a)
    qp, dp = q - qz[:, None] * a, d - dz[:, None] * a
    w0, w1 = r0 + k * qz, k * dz
    big_a = _dot(dp, dp) - w1 * w1
    big_b = _dot(qp, dp) - w0 * w1
    big_c = _dot(qp, qp) - w0 * w0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # A cylinder's discriminant without the b² − ac cancellation: A·(r² − |qp − (B/A)·dp|²).
        e = qp - (big_b / big_a)[:, None] * dp
        disc = np.where(k == 0.0, big_a * (r0 * r0 - _dot(e, e)), big_b * big_b - big_a * big_c)
        sq = np.sqrt(np.where(disc >= 0.0, disc, np.nan))
        big = -big_b - np.copysign(sq, big_b)
        t1, t2 = big / big_a, big_c / big
        roots = np.full((len(q), 4), np.nan)
        for col, t in ((0, t1), (1, t2)):
            s = qz + t * dz
            ok = np.isfinite(t) & (s >= 0.0) & (s <= h)
            roots[:, col] = np.where(ok, t, np.nan)
        for col, level, rad in ((2, 0.0, r0), (3, h, r1)):
            t = (level - qz) / dz
            x = qp + t[:, None] * dp
            ok = caps & (rad > 0.0) & np.isfinite(t) & (_dot(x, x) <= rad * rad)
            roots[:, col] = np.where(ok, t, np.nan)
    return roots


def _disk_roots(q: np.ndarray, d: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed roots (K, 1) of rays with disks / annuli (the plane's, inside the ring)."""
    n, r, inner = p[:, 4:7], p[:, 3], p[:, 7]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -_dot(q, n) / _dot(d, n)
        x = q + t[:, None] * d
        x = x - _dot(x, n)[:, None] * n  # in the plane (rounding aside)
        rho2 = _dot(x, x)
        ok = np.isfinite(t) & (rho2 <= r * r) & (rho2 >= inner * inner)
    return np.where(ok, t, np.nan)[:, None]


def _cubic_breakpoints(p3: np.ndarray, q3: np.ndarray) -> np.ndarray:
    """(K, 3): the real parts of the roots of y³ + p·y + q = 0 (a complex pair's shared real
    part where there is one real root: as a breakpoint it is harmless)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        disc = (q3 / 2.0) ** 2 + (p3 / 3.0) ** 3
        # One real root (disc > 0): Cardano in the form without cancellation.
        big = -np.copysign(np.cbrt(np.abs(q3) / 2.0 + np.sqrt(np.maximum(disc, 0.0))), q3)
        small = np.where(big != 0.0, -p3 / (3.0 * big), 0.0)
        one = big + small
        # Three real roots (disc ≤ 0): the trigonometric form.
        pn = np.minimum(p3, 0.0)
        m = 2.0 * np.sqrt(-pn / 3.0)
        arg = np.where(pn < 0.0, (3.0 * q3 / (2.0 * pn)) * np.sqrt(-3.0 / np.where(pn < 0.0, pn, -1.0)), 0.0)
        phi = np.arccos(np.clip(arg, -1.0, 1.0)) / 3.0
        three = np.stack([m * np.cos(phi - 2.0 * np.pi * j / 3.0) for j in range(3)], axis=1)
        one3 = np.stack([one, -one / 2.0, -one / 2.0], axis=1)
        y = np.where((disc > 0.0)[:, None], one3, three)
        # Two Newton steps on the cubic (guarded): the breakpoints to the last bits.
        for _ in range(2):
            f = (y * y + p3[:, None]) * y + q3[:, None]
            df = 3.0 * y * y + p3[:, None]
            step = np.where(df != 0.0, f / np.where(df != 0.0, df, 1.0), 0.0)
            y = np.where(np.isfinite(step) & (np.abs(step) < 1.0), y - step, y)
    return np.where(np.isfinite(y), y, 0.0)


_BISECTIONS = 64  # halvings of an interval ≤ 4 (scaled units): past the last bit of float64


def _torus_roots(o: np.ndarray, d: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed roots (K, 4) of rays (o, d) with tori ``p`` (NaN where none); module docstring."""
    c, big_r, a, minor = p[:, 0:3], p[:, 3], p[:, 4:7], p[:, 7]
    rho = minor / big_r
    q = (o - c) / big_r[:, None]
    length = np.sqrt(_dot(d, d))
    u = d / length[:, None]
    s0 = -_dot(q, u)
    x0 = q + s0[:, None] * u  # the ray's point nearest the centre: |x0| ≤ |q|, coefficients O(1)
    x0a, ua = _dot(x0, a), _dot(u, a)
    x0p, up = x0 - x0a[:, None] * a, u - ua[:, None] * a
    g2, g1 = _dot(up, up), 2.0 * _dot(x0p, up)
    e = _dot(x0, x0) + 1.0 - rho * rho
    # P(s) = (s² + e)² − 4 (g2 s² + g1 s + g0) (x0 ⟂ u); P'(s)/4 = s³ + (e − 2 g2) s − g1.
    crit = _cubic_breakpoints(e - 2.0 * g2, -g1)
    # The torus lies within |X| ≤ 1 + ρ, and |X|² = |x0|² + s² on the ray.
    reach = np.sqrt(np.maximum((1.0 + rho) ** 2 * (1.0 + 1e-12) - _dot(x0, x0), 0.0)) * (1.0 + 1e-12)
    ends = np.stack([-reach, reach], axis=1)
    edges = np.sort(np.concatenate([ends, np.clip(crit, -reach[:, None], reach[:, None])], axis=1), axis=1)
    lo, hi = edges[:, :-1].copy(), edges[:, 1:].copy()  # (K, 4) monotone pieces of P

    def inside(s: np.ndarray) -> np.ndarray:
        """h(s) < 0: the point is nearer the core circle than ρ (h has P's sign, ρ-fold less rounding)."""
        x = x0[:, None, :] + s[:, :, None] * u[:, None, :]
        z = _dot(x, a[:, None, :])
        xp = x - z[:, :, None] * a[:, None, :]
        ring = np.sqrt(_dot(xp, xp)) - 1.0
        return ring * ring + z * z - (rho * rho)[:, None] < 0.0

    in_lo, in_hi = inside(lo), inside(hi)
    has = in_lo != in_hi
    for _ in range(_BISECTIONS):
        mid = 0.5 * (lo + hi)
        in_mid = inside(mid)
        left = in_mid != in_lo  # the sign changes in [lo, mid]
        hi = np.where(left, mid, hi)
        lo = np.where(left, lo, mid)
        in_lo = np.where(left, in_lo, in_mid)
    s = 0.5 * (lo + hi)
    t = (s0[:, None] + s) * (big_r / length)[:, None]
    return np.where(has, t, np.nan)


def _roots(shapes: Shapes, idx: np.ndarray, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Signed roots (K, 4) of rays (o, d) (K, 3) with shapes ``idx`` (K,) (NaN where none)."""
    out = np.full((len(idx), 4), np.nan)
    kind = shapes.kind[idx]
    p = shapes.params[idx]
    quad = (kind == CYLINDER) | (kind == CONE)
    if quad.any():
        out[quad] = _quadric_roots(o[quad] - p[quad, 0:3], d[quad], p[quad])
    disk = kind == DISK
    if disk.any():
        out[disk, :1] = _disk_roots(o[disk] - p[disk, 0:3], d[disk], p[disk])
    tor = kind == TORUS
    if tor.any():
        out[tor] = _torus_roots(o[tor], d[tor], p[tor])
    return out


def pair_t(shapes: Shapes, idx: np.ndarray, o: np.ndarray, d: np.ndarray, src: np.ndarray | None = None) -> np.ndarray:
    """t (K,) of the nearest hit with ``t > 0`` of ray k (``o[k]``, ``d[k]``) with shape ``idx[k]``
    (inf: none); ``src`` (K,): the shape each ray leaves (−1: none), whose root nearest 0 is
    ignored as :func:`intersect` ignores it. (The CPU traversals' per-pair test.)"""
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    o = np.asarray(o, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    if not len(idx):
        return np.zeros(0)
    roots = _roots(shapes, idx, o, d)
    if src is not None:
        own = np.flatnonzero(np.asarray(src, dtype=np.int64).reshape(-1) == idx)
        if len(own):
            nearest = np.argmin(np.where(np.isnan(roots[own]), np.inf, np.abs(roots[own])), axis=1)
            roots[own, nearest] = np.nan
    with np.errstate(invalid="ignore"):
        return np.where(roots > 0.0, roots, np.inf).min(axis=1)


def normals(shapes: Shapes, idx: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Outward unit normals (K, 3) at points ``x`` (K, 3) on shapes ``idx`` (K,).

    A cylinder's or cone's point belongs to the part whose surface it is nearest (side, base
    cap: −axis, top cap: +axis); a disk's normal is its ``normal`` (both sides are hit); a
    torus's points away from the nearest point of its core circle."""
    idx = np.asarray(idx, dtype=np.int64).reshape(-1)
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    p = shapes.params[idx]
    kind = shapes.kind[idx]
    c, a, r0, r1, h = p[:, 0:3], p[:, 4:7], p[:, 3], p[:, 7], p[:, 8]
    q = x - c
    z = _dot(q, a)
    qp = q - z[:, None] * a
    rho = np.sqrt(_dot(qp, qp))
    with np.errstate(divide="ignore", invalid="ignore"):
        radial = np.where((rho > 0.0)[:, None], qp / np.where(rho > 0.0, rho, 1.0)[:, None], 0.0)
        k = np.where(h > 0.0, (r1 - r0) / np.where(h > 0.0, h, 1.0), 0.0)
    # Cylinders and cones: the side's normal (radial − k·axis)/√(1 + k²) or a cap's.
    side = (radial - k[:, None] * a) / np.sqrt(1.0 + k * k)[:, None]
    miss_side = np.abs(rho - (r0 + k * z)) / np.sqrt(1.0 + k * k)
    caps = p[:, 9] != 0.0
    miss_base = np.where(caps & (r0 > 0.0), np.abs(z), np.inf)
    miss_top = np.where(caps & (r1 > 0.0), np.abs(z - h), np.inf)
    out = np.where((miss_side <= np.minimum(miss_base, miss_top))[:, None], side, 0.0)
    out = np.where(((miss_base < miss_side) & (miss_base <= miss_top))[:, None], -a, out)
    out = np.where(((miss_top < miss_side) & (miss_top < miss_base))[:, None], a, out)
    out = np.where((kind == DISK)[:, None], a, out)
    tor = kind == TORUS
    if tor.any():
        v = q[tor] - r0[tor, None] * radial[tor]
        out[tor] = v / np.linalg.norm(v, axis=1, keepdims=True)
    # A side at a cone's apex (radial undefined) falls back to the axis.
    bad = ~np.isfinite(out).all(axis=1) | (np.abs(out).sum(axis=1) == 0.0)
    out[bad] = a[bad]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


_PAIR_BUDGET = 1 << 18  # ray × shape pairs culled together


def _box_pairs(box: np.ndarray, o: np.ndarray, d: np.ndarray, t_min: float, t_max: float) -> tuple:
    """(ray, shape) pairs whose ray meets the (inflated) box within [t_min, t_max] (a superset)."""
    lo, hi = box[None, :, 0, :], box[None, :, 1, :]
    oo, dd = o[:, None, :], d[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - oo) / dd, (hi - oo) / dd
    inside = (oo >= lo) & (oo <= hi)
    flat = dd == 0.0
    near = np.where(flat, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    far = np.where(flat, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    enter, leave = near.max(axis=2), far.min(axis=2)
    return np.nonzero((enter <= leave) & (leave >= t_min) & (enter <= t_max))


def intersect(
    shapes: Shapes,
    o: np.ndarray,
    d: np.ndarray,
    t_min: float = 0.0,
    t_max: float = math.inf,
    src: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit of each ray (o, d) (M, 3) with ``t_min < t < t_max``: (t float64 (M,),
    shape index int64 (M,) or −1, outward unit normal float64 (M, 3), 0 on a miss).

    ``t`` is along ``d`` (a distance when ``d`` is a unit vector); exactly equal ``t`` go to
    the lower index. ``src`` (M,): the shape each ray leaves (−1: none): its root nearest 0
    — the ray's own origin — is ignored, the others count (module docstring)."""
    o = np.asarray(o, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    m = len(o)
    src = np.full(m, -1, np.int64) if src is None else np.asarray(src, dtype=np.int64).reshape(-1)
    t_out = np.full(m, np.inf)
    id_out = np.full(m, -1, np.int64)
    n_out = np.zeros((m, 3))
    n = len(shapes)
    if n == 0 or m == 0:
        return t_out, id_out, n_out
    box = bounds(shapes)
    # Inflated far beyond the rounding of the slab test and of the roots (a cull only).
    size = np.abs(box).max(axis=(1, 2)) + (box[:, 1] - box[:, 0]).max(axis=1)
    box = box + np.array([-1.0, 1.0])[None, :, None] * (1e-9 * size + 1e-300)[:, None, None]
    tile = max(1, _PAIR_BUDGET // m)
    for s0 in range(0, n, tile):
        ri, sj = _box_pairs(box[s0 : s0 + tile], o, d, t_min, t_max)
        sj = sj + s0
        if not len(ri):
            continue
        roots = _roots(shapes, sj, o[ri], d[ri])
        own = np.flatnonzero(src[ri] == sj)
        if len(own):  # a ray leaving a shape: its root at the origin is not a hit
            nearest = np.argmin(np.where(np.isnan(roots[own]), np.inf, np.abs(roots[own])), axis=1)
            roots[own, nearest] = np.nan
        with np.errstate(invalid="ignore"):
            roots = np.where((roots > t_min) & (roots < t_max), roots, np.inf)
        t = roots.min(axis=1)
        ok = np.isfinite(t)
        ri, sj, t = ri[ok], sj[ok], t[ok]
        # Per ray the smallest t, ties to the lower index (this tile's, then against earlier tiles').
        order = np.lexsort((sj, t, ri))
        ri, sj, t = ri[order], sj[order], t[order]
        first = np.ones(len(ri), bool)
        first[1:] = ri[1:] != ri[:-1]
        ri, sj, t = ri[first], sj[first], t[first]
        better = t < t_out[ri]
        t_out[ri[better]], id_out[ri[better]] = t[better], sj[better]
    hit = np.flatnonzero(id_out >= 0)
    if len(hit):
        n_out[hit] = normals(shapes, id_out[hit], o[hit] + t_out[hit, None] * d[hit])
    return t_out, id_out, n_out


def reach(shapes: Shapes) -> np.ndarray:
    """(N,): how far each shape extends from its origin (the largest distance of its box's corners)."""
    box = bounds(shapes)
    rel = np.abs(box - shapes.params[:, None, 0:3]).max(axis=1)
    return np.linalg.norm(rel, axis=1)
