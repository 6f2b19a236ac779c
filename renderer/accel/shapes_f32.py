"""The analytic shapes' intersection tests in float32: the CPU copy of ``shaders/shapes.glsl``.

Every function here is the GLSL function of the same name, step for step, over many rays
at once (NumPy, float32 throughout; a GLSL ``break`` is a lane leaving the loop, here a
mask). The shape is three float32 vec4 records (``v0``, ``v1``, ``v2``, see the shader's
header), one per ray or one for all; a direction is a unit vector; ``t`` is BIG (3e38) for
no hit, ``n`` the outward unit normal (a disk's axis), zero on a miss.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

F = np.float32
BIG = F(3.0e38)
CYLINDER, CONE, DISK, TORUS = 0, 1, 2, 3
TORUS_EXTREMUM_STEPS = 24
TORUS_ROOT_STEPS = 24

Arr = np.ndarray


def _f(x) -> Arr:
    return np.asarray(x, dtype=F)


def _dot(a: Arr, b: Arr) -> Arr:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _cross(a: Arr, b: Arr) -> Arr:
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def _col(x: Arr) -> Arr:
    return x[..., None]


def _div(a: Arr, b: Arr) -> Arr:
    """a / b where b != 0 (the GLSL divides only there; elsewhere the value is never used)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return np.divide(a, np.where(b != 0, b, F(1)))


class ShapeRay(NamedTuple):
    q0: Arr  # (N, 3) perpendicular part of p0
    dq: Arr  # (N, 3) perpendicular part of d
    z0: Arr  # (N,) axial part of p0
    dz: Arr  # (N,) axial part of d


def shape_ray(p0: Arr, d: Arr, a: Arr) -> ShapeRay:
    z0 = _dot(p0, a)
    dz = _dot(d, a)
    return ShapeRay(p0 - _col(z0) * a, d - _col(dz) * a, z0, dz)


def shape_cap(s: ShapeRay, zc, r_out, r_in, t_max) -> Arr:
    """The plane z = zc between radii r_in and r_out: t in (0, t_max) or BIG."""
    zc, r_out, r_in, t_max = _f(zc), _f(r_out), _f(r_in), _f(t_max)
    t = _div(zc - s.z0, s.dz)
    q = s.q0 + _col(t) * s.dq
    with np.errstate(over="ignore", invalid="ignore"):
        rho2 = _dot(q, q)
        ok = (s.dz != 0) & (t > 0) & (t < t_max) & (rho2 <= r_out * r_out) & (rho2 >= r_in * r_in)
    return np.where(ok, t, BIG).astype(F)


def shape_lateral(s: ShapeRay, a: Arr, r0, m, h, t_max) -> tuple[Arr, Arr]:
    """The lateral surface rho = r0 + m·z, 0 <= z <= h, shifted to the closest approach to the axis."""
    r0, m, h, t_max = _f(r0), _f(m), _f(h), _f(t_max)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        k = _dot(s.dq, s.dq)
        s0 = np.where(k > F(1e-30), -_div(_dot(s.q0, s.dq), k), F(0)).astype(F)
        q1 = s.q0 + _col(s0) * s.dq
        z1 = s.z0 + s0 * s.dz
        beta = _dot(q1, s.dq)
        w1 = r0 + m * z1
        rho1 = np.sqrt(_dot(q1, q1))
        mdz = m * s.dz
        A = k - mdz * mdz
        B = beta - mdz * w1
        C = (rho1 - w1) * (rho1 + w1)
        disc = k * ((w1 - rho1) * (w1 + rho1)) + beta * (beta - F(2) * mdz * w1) + mdz * mdz * rho1 * rho1
        sq = np.sqrt(np.maximum(disc, F(0)))
        qq = -(B + np.where(B >= 0, sq, -sq))
        live = (disc >= 0) & (qq != 0)
        u1 = np.where(A != 0, _div(qq, A), BIG)
        u2 = _div(C, qq)
        best = np.full(k.shape, BIG, dtype=F)
        bu = np.zeros(k.shape, dtype=F)
        for u in (u1, u2):
            t = s0 + u
            z = z1 + u * s.dz
            ok = live & (t > 0) & (t < t_max) & (t < best) & (z >= 0) & (z <= h) & (r0 + m * z >= 0)
            best = np.where(ok, t, best)
            bu = np.where(ok, u, bu)
        q = q1 + _col(bu) * s.dq
        rho = np.sqrt(_dot(q, q))
        er = np.where(_col(rho > 0), q / _col(np.where(rho > 0, rho, F(1))), F(0))
        g = er - _col(np.broadcast_to(m, k.shape)) * a
        gl = np.sqrt(_dot(g, g))
        n = np.where(_col(gl > 0), g / _col(np.where(gl > 0, gl, F(1))), np.broadcast_to(a, g.shape))
        n = np.where(_col(best < BIG), n, F(0))
    return best.astype(F), n.astype(F)


def _records(o, d, v0, v1, v2) -> tuple[Arr, Arr, Arr, Arr, Arr]:
    o, d = _f(o), _f(d)
    n = len(o)
    return o, d, *(np.broadcast_to(_f(v), (n, 4)) for v in (v0, v1, v2))


def shape_frustum(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    o, d, v0, v1, v2 = _records(o, d, v0, v1, v2)
    t_max = _f(t_max)
    a = v1[:, :3]
    h = v2[:, 0]
    s = shape_ray(o - v0[:, :3], d, a)
    m = np.where(h > 0, _div(v1[:, 3] - v0[:, 3], h), F(0)).astype(F)
    t, n = shape_lateral(s, a, v0[:, 3], m, h, t_max)
    caps = v2[:, 1] > F(0.5)
    tb = shape_cap(s, F(0), v0[:, 3], F(0), np.minimum(t, t_max))
    take = caps & (tb < t)
    t = np.where(take, tb, t)
    n = np.where(_col(take), -a, n)
    tt = shape_cap(s, h, v1[:, 3], F(0), np.minimum(t, t_max))
    take = caps & (tt < t)
    t = np.where(take, tt, t)
    n = np.where(_col(take), a, n)
    return t.astype(F), n.astype(F)


def intersect_cylinder(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    return shape_frustum(o, d, v0, v1, v2, t_max)


def intersect_cone(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    return shape_frustum(o, d, v0, v1, v2, t_max)


def intersect_disk(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    o, d, v0, v1, v2 = _records(o, d, v0, v1, v2)
    t = shape_cap(shape_ray(o - v0[:, :3], d, v1[:, :3]), F(0), v0[:, 3], v1[:, 3], t_max)
    return t, np.where(_col(t < BIG), v1[:, :3], F(0)).astype(F)


# ---- torus ----------------------------------------------------------------------------


class TorusRay(NamedTuple):
    qs: Arr
    dq: Arr
    zs: Arr
    dz: Arr
    R: Arr
    r: Arr


def torus_E(tr: TorusRay, s: Arr) -> Arr:
    """E(s) = (rho − R)² + z² − r², without cancellation near the tube."""
    q = tr.qs + _col(s) * tr.dq
    z = tr.zs + s * tr.dz
    rho = np.sqrt(_dot(q, q))
    return z * z + (rho - tr.R - tr.r) * (rho - tr.R + tr.r)


def torus_dD(tr: TorusRay, s: Arr) -> tuple[Arr, Arr]:
    """D'/2 and D''/2 at s."""
    q = tr.qs + _col(s) * tr.dq
    z = tr.zs + s * tr.dz
    rho = np.sqrt(_dot(q, q))
    w = _dot(q, tr.dq)
    k = _dot(tr.dq, tr.dq)
    pos = rho > 0
    rr = np.where(pos, rho, F(1))
    g1 = z * tr.dz + w * (rho - tr.R) / rr
    g2 = tr.dz * tr.dz + k * (rho - tr.R) / rr + tr.R * (w / rr) * (w / rr) / rr
    return np.where(pos, g1, z * tr.dz), np.where(pos, g2, tr.dz * tr.dz)


def _take(tr: TorusRay, idx: Arr) -> TorusRay:
    return TorusRay(*(x[idx] for x in tr))


def torus_extremum(tr: TorusRay, lo: Arr, hi: Arr, sg: Arr) -> Arr:
    """The extremum of D on [lo, hi] where sg·D' increases: Newton safeguarded by bisection."""
    lo, hi = lo.copy(), hi.copy()
    qlo = tr.qs + _col(lo) * tr.dq
    qhi = tr.qs + _col(hi) * tr.dq
    glo = np.where(_dot(qlo, qlo) > 0, sg * torus_dD(tr, lo)[0], F(-1))  # the axis: D's kink
    ghi = np.where(_dot(qhi, qhi) > 0, sg * torus_dD(tr, hi)[0], F(1))
    res = np.where(glo >= 0, lo, hi).astype(F)
    act = np.flatnonzero((glo < 0) & (ghi > 0))
    x = (lo + (hi - lo) * _div(-glo, ghi - glo)).astype(F)  # the secant's zero (glo < 0 < ghi)
    for _ in range(TORUS_EXTREMUM_STEPS):
        if act.size == 0:
            break
        sub = _take(tr, act)
        g1, g2 = torus_dD(sub, x[act])
        g1, g2 = sg[act] * g1, sg[act] * g2
        xa, la, ha = x[act], lo[act], hi[act]
        stop = g1 == 0
        la = np.where(g1 < 0, xa, la)
        ha = np.where(g1 < 0, ha, xa)
        xn = np.where(g2 > 0, xa - _div(g1, g2), F(0.5) * (la + ha)).astype(F)
        done = ~stop & (np.abs(xn - xa) <= F(1e-6) * (sub.R + sub.r))  # before the bracket (see the GLSL)
        xb = np.where((xn > la) & (xn < ha), xn, F(0.5) * (la + ha))
        lo[act], hi[act] = la, ha
        x[act] = np.where(stop, xa, np.where(done, np.clip(xn, la, ha), xb)).astype(F)
        act = act[~(stop | done)]
    return np.where((glo < 0) & (ghi > 0), x, res).astype(F)


def torus_root(tr: TorusRay, lo: Arr, hi: Arr, elo: Arr, sg: Arr, m: Arr, em: Arr, side: Arr) -> Arr:
    """The one root of E in [lo, hi] (monotone there, the extremum m at the end ``side``): Newton
    in the bracket from the root of E's quadratic model at m, else from Fourier's end."""
    lo, hi = lo.copy(), hi.copy()
    x = np.where(sg * elo > 0, lo, hi).astype(F)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -em / torus_dD(tr, m)[1]
        xq = (m + side * np.sqrt(np.where(q > 0, q, F(0)))).astype(F)
    x = np.where((q > 0) & (xq > lo) & (xq < hi), xq, x).astype(F)
    neg_lo = elo < 0
    act = np.arange(len(x))
    last = np.full(len(x), BIG, dtype=F)
    for i in range(TORUS_ROOT_STEPS):
        if act.size == 0:
            break
        sub = _take(tr, act)
        xa, la, ha = x[act], lo[act], hi[act]
        e = torus_E(sub, xa)
        stop = e == 0
        left = (e < 0) == neg_lo[act]
        la = np.where(left, xa, la)
        ha = np.where(left, ha, xa)
        g = F(2) * torus_dD(sub, xa)[0]
        xn = np.where(g != 0, xa - _div(e, g), F(0.5) * (la + ha)).astype(F)
        step = np.abs(xn - xa)
        done = ~stop & ((step <= F(1e-7) * (sub.R + sub.r)) | ((i > 1) & (step >= last[act])))
        last[act] = step
        xb = np.where((xn >= la) & (xn <= ha), xn, F(0.5) * (la + ha))
        lo[act], hi[act] = la, ha
        x[act] = np.where(stop, xa, np.where(done, np.clip(xn, la, ha), xb)).astype(F)
        act = act[~(stop | done)]
    return x


def torus_setup(o, d, v0, v1, t_max) -> tuple[Arr, TorusRay, Arr, Arr, Arr]:
    """(possible, ray shifted to f, t_f, s range lo, hi): padded bounding sphere, (0, t_max), padded slab."""
    a = v1[:, :3]
    R, r = v0[:, 3], v1[:, 3]
    t_max = np.broadcast_to(_f(t_max), R.shape)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        p0 = o - v0[:, :3]
        b = _dot(p0, d)
        f = p0 - _col(b) * d
        rb = (R + r) * F(1.0001)
        zb = r + F(1e-4) * (R + r)
        h2 = rb * rb - _dot(f, f)
        tf = -b
        h = np.sqrt(np.maximum(h2, F(0)))
        zs = _dot(f, a)
        dz = _dot(d, a)
        tr = TorusRay(f - _col(zs) * a, d - _col(dz) * a, zs, dz, R, r)
        lo = np.maximum(-h, -tf)
        hi = np.minimum(h, t_max - tf)
        s1 = _div(-zb - zs, dz)
        s2 = _div(zb - zs, dz)
        slab = dz != 0
        lo = np.where(slab, np.maximum(lo, np.minimum(s1, s2)), lo)
        hi = np.where(slab, np.minimum(hi, np.maximum(s1, s2)), hi)
        ok = (h2 >= 0) & (slab | (np.abs(zs) <= zb)) & (lo < hi)
    return ok, tr, tf, lo.astype(F), hi.astype(F)


def _torus_normal(tr: TorusRay, s: Arr, a: Arr) -> Arr:
    q = tr.qs + _col(s) * tr.dq
    z = tr.zs + s * tr.dz
    rho = np.sqrt(_dot(q, q))
    g = _col(np.where(rho > 0, (rho - tr.R) / np.where(rho > 0, rho, F(1)), F(0))) * q + _col(z) * a
    gl = np.sqrt(_dot(g, g))
    return np.where(_col(gl > 0), g / _col(np.where(gl > 0, gl, F(1))), a).astype(F)


def _torus_rays(o, d, v0, v1, v2, t_max):
    """What both torus methods start from: the axis records (``v1``, as ``_records`` makes them), the
    outputs (no hit yet), the rays that can meet the torus (``idx``) and, for those, the shifted ray,
    its range and each ray's t_max."""
    o, d, v0, v1, v2 = _records(o, d, v0, v1, v2)
    nr = len(o)
    t_out = np.full(nr, BIG, dtype=F)
    n_out = np.zeros((nr, 3), dtype=F)
    ok, tr, tf, lo, hi = torus_setup(o, d, v0, v1, t_max)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return v1, t_out, n_out, idx, tr, tf, lo, hi, None
    tmx = np.broadcast_to(_f(t_max), (nr,))[idx]
    return v1, t_out, n_out, idx, _take(tr, idx), tf[idx], lo[idx], hi[idx], tmx


def intersect_torus_bracket(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    """Method B: the range cut where D changes curvature, each piece's extremum, one root per monotone half."""
    v1, t_out, n_out, idx, tr, tf, lo, hi, tmx = _torus_rays(o, d, v0, v1, v2, t_max)
    if idx.size == 0:
        return t_out, n_out
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        k = _dot(tr.dq, tr.dq)
        c = _cross(tr.qs, tr.dq)
        L2 = _dot(c, c)
        kk = np.where(k > F(1e-12), k, F(1))
        sm = -_dot(tr.qs, tr.dq) / kk
        rm2 = L2 / kk
        x = tr.R * L2
        rc = np.where(x > 0, np.exp2(np.log2(np.where(x > 0, x, F(1))) / F(3)), F(0)).astype(F)
        sc2 = (rc * rc - rm2) / kk
        conc = (k > F(1e-12)) & (sc2 >= 0)
        sc = np.sqrt(np.maximum(sc2, F(0)))
        b1 = np.where(conc, np.clip(sm - sc, lo, hi), hi).astype(F)
        b2 = np.where(conc, np.clip(sm + sc, lo, hi), hi).astype(F)
    s_hit = np.full(len(idx), BIG, dtype=F)
    todo = np.ones(len(idx), dtype=bool)
    a_ = lo.copy()
    for p, b_ in enumerate((b1, b2, hi)):
        sgv = F(-1) if p == 1 else F(1)
        live = np.flatnonzero(todo & (b_ > a_))
        if live.size:
            sub = _take(tr, live)
            al, bl = a_[live], b_[live]
            sg = np.full(live.size, sgv, dtype=F)
            m = torus_extremum(sub, al, bl, sg)
            ea, em, eb = torus_E(sub, al), torus_E(sub, m), torus_E(sub, bl)
            first = ((ea < 0) != (em < 0)) & (m > al)
            second = ~first & ((em < 0) != (eb < 0)) & (bl > m)
            lo_r = np.where(first, al, m)
            hi_r = np.where(first, m, bl)
            e_r = np.where(first, ea, em)
            hit = first | second
            if hit.any():
                h_idx = np.flatnonzero(hit)
                side = np.where(first, F(-1), F(1))
                roots = torus_root(
                    _take(sub, h_idx), lo_r[h_idx], hi_r[h_idx], e_r[h_idx], sg[h_idx], m[h_idx], em[h_idx], side[h_idx]
                )
                s_hit[live[h_idx]] = roots
                todo[live[h_idx]] = False
        a_ = np.maximum(a_, b_)
    t = (tf + s_hit).astype(F)
    good = (s_hit < BIG) & (t > 0) & (t < tmx)
    t_out[idx] = np.where(good, t, BIG)
    n = _torus_normal(tr, np.where(good, s_hit, F(0)), v1[idx, :3])
    n_out[idx] = np.where(_col(good), n, F(0))
    return t_out, n_out


def torus_quadratic(b: Arr, c: Arr) -> tuple[Arr, Arr, Arr]:
    """The real roots of x² + b·x + c (stable): (x1, x2, real)."""
    disc = b * b - F(4) * c
    sq = np.sqrt(np.maximum(disc, F(0)))
    qq = F(-0.5) * (b + np.where(b >= 0, sq, -sq))
    real = disc >= 0
    x1 = np.where(qq != 0, qq, F(0))
    x2 = np.where(qq != 0, _div(c, qq), F(0))
    return x1.astype(F), x2.astype(F), real


def torus_cubic_max(a: Arr, b: Arr, c: Arr) -> Arr:
    """The largest real root of y³ + a·y² + b·y + c, then two Newton steps."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        a3 = a / F(3)
        p = b - a * a3
        qc = c - a3 * b + F(2) * a3 * a3 * a3
        disc = F(0.25) * qc * qc + p * p * p / F(27)
        trig = (disc <= 0) & (p < 0)
        mm = F(2) * np.sqrt(np.maximum(-p / F(3), F(0)))
        th = np.arccos(np.clip(_div(F(3) * qc, p * mm), F(-1), F(1))) / F(3)
        y_trig = mm * np.cos(th) - a3
        sq = np.sqrt(np.maximum(disc, F(0)))
        u = F(-0.5) * qc + np.where(qc <= 0, sq, -sq)
        cu = np.where(u != 0, np.sign(u) * np.exp2(np.log2(np.where(u != 0, np.abs(u), F(1))) / F(3)), F(0))
        y_card = np.where(cu != 0, cu - _div(p, F(3) * cu), F(0)) - a3
        y = np.where(trig, y_trig, y_card).astype(F)
        for _ in range(2):
            fy = ((y + a) * y + b) * y + c
            dy = (F(3) * y + F(2) * a) * y + b
            y = np.where(dy != 0, y - _div(fy, dy), y).astype(F)
    return y


def intersect_torus_closed(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    """Method A: the depressed quartic by Descartes' factorisation, the nearest root polished by Newton on E."""
    v1, t_out, n_out, idx, tr, tf, lo, hi, tmx = _torus_rays(o, d, v0, v1, v2, t_max)
    if idx.size == 0:
        return t_out, n_out
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        R, r = tr.R, tr.r
        k = _dot(tr.dq, tr.dq)
        rs = np.sqrt(_dot(tr.qs, tr.qs)) / R
        zs = tr.zs / R
        rr = r / R
        e0 = zs * zs + (rs - F(1) - rr) * (rs - F(1) + rr)
        h0 = zs * zs + (rs + F(1) - rr) * (rs + F(1) + rr)
        c = rs * rs + zs * zs
        p = F(2) * (c + (F(1) - rr) * (F(1) + rr)) - F(4) * k
        q = F(-8) * _dot(tr.qs, tr.dq) / R
        s0 = e0 * h0
        y = np.maximum(torus_cubic_max(F(2) * p, p * p - F(4) * s0, -q * q), F(0))
        al = np.sqrt(y)
        big_al = al > F(1e-4)
        bx, by, breal = torus_quadratic(-(p + y), s0)
        beta = np.where(big_al, F(0.5) * (p + y - _div(q, al)), np.where(breal, bx, F(0.5) * (p + y)))
        gam = np.where(big_al, F(0.5) * (p + y + _div(q, al)), np.where(breal, by, F(0.5) * (p + y)))
        best = np.full(len(idx), BIG, dtype=F)
        for bb, cc in ((al, beta), (-al, gam)):
            x1, x2, real = torus_quadratic(bb, cc)
            for u in (x1, x2):
                s = u * R
                okr = real & (s > lo - F(1e-3) * R) & (s < hi + F(1e-3) * R) & (s < best)
                best = np.where(okr, s, best).astype(F)
        found = best < BIG
        for _ in range(2):
            g = F(2) * torus_dD(tr, best)[0]
            best = np.where(found & (g != 0), best - _div(torus_E(tr, best), g), best).astype(F)
    t = (tf + best).astype(F)
    good = found & (t > 0) & (t < tmx)
    t_out[idx] = np.where(good, t, BIG)
    n = _torus_normal(tr, np.where(good, best, F(0)), v1[idx, :3])
    n_out[idx] = np.where(_col(good), n, F(0))
    return t_out, n_out


def intersect_torus(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    return intersect_torus_bracket(o, d, v0, v1, v2, t_max)


Intersect = Callable[..., tuple[Arr, Arr]]
BY_KIND: dict[int, Intersect] = {
    CYLINDER: intersect_cylinder,
    CONE: intersect_cone,
    DISK: intersect_disk,
    TORUS: intersect_torus,
}


def intersect_shape(o, d, v0, v1, v2, t_max) -> tuple[Arr, Arr]:
    """The dispatcher by kind (v2.z): one shape for all rays."""
    kind = int(_f(v2)[..., 2].flat[0] + F(0.5))
    return BY_KIND.get(kind, shape_frustum)(o, d, v0, v1, v2, t_max)
