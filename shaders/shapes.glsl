// Analytic shapes: cylinders, cones (frustums), disks (annuli) and tori, in float32.
// Valid GLSL ES 3.00 (WebGL2 too), standalone: the includer defines BIG (the tracer's
// "no hit", 3.0e38) before this text. renderer/accel/shapes_f32.py mirrors every
// function here in NumPy float32, step for step.
//
// A shape is three vec4 records:
//   v0 = (origin.xyz, r0), v1 = (unit axis.xyz, r1), v2 = (height, caps 1/0, kind, unused)
//   cylinder: origin = base centre, r0 = r1 = radius, height along the axis, caps = two disks
//   cone:     origin = base centre, r0 = base radius, r1 = top radius, height, caps
//   disk:     origin = centre, axis = normal, r0 = radius, r1 = inner radius (0: full)
//   torus:    origin = centre, axis, r0 = major radius, r1 = minor radius
// Each intersect_<kind>(o, d, v0, v1, v2, t_max, n) takes a unit direction d and returns
// the nearest t in (0, t_max), or BIG, with the outward unit normal in n (a disk's is
// its axis). Every test works in the shape's frame: z = dot(p, axis) from the origin and
// q = p − z·axis, the part perpendicular to the axis, so no basis is built.

const int SHAPE_CYLINDER = 0;
const int SHAPE_CONE = 1;
const int SHAPE_DISK = 2;
const int SHAPE_TORUS = 3;

// The ray p0 + t·d (p0 relative to the shape's origin) in the shape's frame.
struct ShapeRay {
    vec3 q0;   // perpendicular part of p0
    vec3 dq;   // perpendicular part of d
    float z0;  // axial part of p0
    float dz;  // axial part of d
};

ShapeRay shape_ray(vec3 p0, vec3 d, vec3 a) {
    float z0 = dot(p0, a);
    float dz = dot(d, a);
    return ShapeRay(p0 - z0 * a, d - dz * a, z0, dz);
}

// The plane z = zc of the frame between radii r_in and r_out: t in (0, t_max) or BIG. A ray
// in the plane (dz = 0; llvmpipe flushes a denormal dz to 0 too) never meets a
// zero-thickness disk; a nearly parallel one gets a large, accurate t.
float shape_cap(ShapeRay s, float zc, float r_out, float r_in, float t_max) {
    if (s.dz == 0.0) return BIG;
    float t = (zc - s.z0) / s.dz;
    if (!(t > 0.0 && t < t_max)) return BIG;
    vec3 q = s.q0 + t * s.dq;
    float rho2 = dot(q, q);
    return (rho2 <= r_out * r_out && rho2 >= r_in * r_in) ? t : BIG;
}

// The lateral surface rho = r0 + m·z, 0 <= z <= h (a cylinder: m = 0). As the tracer's
// sphere test forms its discriminant from the offset to the ray's closest point to the
// centre, this one shifts the ray to its closest approach to the axis (s0) first: there
// dot(q1, dq) is ~0, and the discriminant k·(w1² − rho1²) + m²dz²·rho1² (+ the small
// beta terms) has its difference of squares as a product, exact near the silhouette
// where the textbook B² − AC cancels. The roots by the stable quadratic (no subtraction
// of nearly equal terms either).
// The side's roots as offsets u from s0, the ray's closest approach to the axis (t = s0 + u; the
// shifted point q1 and height z1 there): u1 only where A ≠ 0 (`two`; else BIG). False where the ray
// misses the side's surface, or runs along one of its axis-parallel lines (B = disc = 0).
struct SideRoots {
    float s0;
    vec3 q1;
    float z1;
    bool two;
    float u1;
    float u2;
};

bool side_roots(ShapeRay s, float r0, float m, out SideRoots sr) {
    float k = dot(s.dq, s.dq);
    sr.s0 = k > 1e-30 ? -dot(s.q0, s.dq) / k : 0.0;
    sr.q1 = s.q0 + sr.s0 * s.dq;
    sr.z1 = s.z0 + sr.s0 * s.dz;
    float beta = dot(sr.q1, s.dq);
    float w1 = r0 + m * sr.z1;
    float rho1 = sqrt(dot(sr.q1, sr.q1));
    float mdz = m * s.dz;
    float A = k - mdz * mdz;
    float B = beta - mdz * w1;
    float C = (rho1 - w1) * (rho1 + w1);
    float disc = k * ((w1 - rho1) * (w1 + rho1)) + beta * (beta - 2.0 * mdz * w1) + mdz * mdz * rho1 * rho1;
    sr.two = A != 0.0;
    sr.u1 = BIG;
    sr.u2 = BIG;
    if (disc < 0.0) return false;
    float sq = sqrt(disc);
    float qq = -(B + (B >= 0.0 ? sq : -sq));
    if (qq == 0.0) return false;
    if (sr.two) sr.u1 = qq / A;
    sr.u2 = C / qq;
    return true;
}

float shape_lateral(ShapeRay s, vec3 a, float r0, float m, float h, float t_max, out vec3 n) {
    n = vec3(0.0);
    SideRoots sr;
    if (!side_roots(s, r0, m, sr)) return BIG;
    float best = BIG;
    float bu = 0.0;
    for (int i = 0; i < 2; i++) {
        float u = i == 0 ? sr.u1 : sr.u2;
        float t = sr.s0 + u;
        float z = sr.z1 + u * s.dz;
        if (t > 0.0 && t < t_max && t < best && z >= 0.0 && z <= h && r0 + m * z >= 0.0) {
            best = t;
            bu = u;
        }
    }
    if (best < BIG) {
        vec3 q = sr.q1 + bu * s.dq;
        float rho = sqrt(dot(q, q));
        // The apex (rho = 0) has no normal: the axis stands in.
        vec3 er = rho > 0.0 ? q / rho : vec3(0.0);
        vec3 g = er - m * a;
        float gl = sqrt(dot(g, g));
        n = gl > 0.0 ? g / gl : a;
    }
    return best;
}

// A frustum rho = r0 + (r1 − r0)·z/h, 0 <= z <= h, with optional caps (a cylinder: r0 = r1).
float shape_frustum(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    vec3 a = v1.xyz;
    float h = v2.x;
    ShapeRay s = shape_ray(o - v0.xyz, d, a);
    float m = h > 0.0 ? (v1.w - v0.w) / h : 0.0;
    float t = shape_lateral(s, a, v0.w, m, h, t_max, n);
    if (v2.y > 0.5) {
        float tb = shape_cap(s, 0.0, v0.w, 0.0, min(t, t_max));
        if (tb < t) {
            t = tb;
            n = -a;
        }
        float tt = shape_cap(s, h, v1.w, 0.0, min(t, t_max));
        if (tt < t) {
            t = tt;
            n = a;
        }
    }
    return t;
}

float intersect_cylinder(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    return shape_frustum(o, d, v0, v1, v2, t_max, n);
}

float intersect_cone(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    return shape_frustum(o, d, v0, v1, v2, t_max, n);
}

float intersect_disk(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    n = v1.xyz;
    return shape_cap(shape_ray(o - v0.xyz, d, v1.xyz), 0.0, v0.w, v1.w, t_max);
}

// ---- torus ---------------------------------------------------------------------------
// Both methods shift the ray to its closest point to the centre, f (the bounding sphere
// test's offset), and parametrise it by s = t − t_f there, so every coordinate is at most
// R + r: a torus 1e4 from the camera costs only the rounding of o − centre.
//
// The function whose sign changes are the hits is E(s) = D(s) − r², D the squared distance
// from the ray's point to the core circle (radius R in the plane z = 0):
//   D = (rho − R)² + z²,   D'/2 = z·dz + w·(rho − R)/rho,   D''/2 = dz² + k·(rho − R)/rho + R·w²/rho³
// with w = dot(q, dq) and k = |dq|². The quartic is E·((rho + R)² + z² − r²), whose second
// factor is > 0, but E itself has no cancelling terms near the tube (the quartic's
// coefficients lose everything for a thin torus: its constant term is 4R⁴ minus 4R⁴).
struct TorusRay {
    vec3 qs;  // perpendicular part of f
    vec3 dq;
    float zs;  // axial part of f
    float dz;
    float R;
    float r;
};

float torus_E(TorusRay tr, float s) {
    vec3 q = tr.qs + s * tr.dq;
    float z = tr.zs + s * tr.dz;
    float rho = sqrt(dot(q, q));
    return z * z + (rho - tr.R - tr.r) * (rho - tr.R + tr.r);
}

// D'/2 and D''/2 at s (rho = 0, on the axis, far from any hit: the kink's terms left out).
vec2 torus_dD(TorusRay tr, float s) {
    vec3 q = tr.qs + s * tr.dq;
    float z = tr.zs + s * tr.dz;
    float rho = sqrt(dot(q, q));
    float w = dot(q, tr.dq);
    float k = dot(tr.dq, tr.dq);
    if (rho <= 0.0) return vec2(z * tr.dz, tr.dz * tr.dz);
    float g1 = z * tr.dz + w * (rho - tr.R) / rho;
    float g2 = tr.dz * tr.dz + k * (rho - tr.R) / rho + tr.R * (w / rho) * (w / rho) / rho;
    return vec2(g1, g2);
}

const int TORUS_EXTREMUM_STEPS = 24;
const int TORUS_ROOT_STEPS = 24;

// The extremum of D on [lo, hi] where sg·D' increases (sg = +1: a convex piece, its
// minimum; −1: a concave one, its maximum): an end when sg·D' has one sign, else the root
// of D' by Newton safeguarded with bisection.
float torus_extremum(TorusRay tr, float lo, float hi, float sg) {
    float tol = 1e-6 * (tr.R + tr.r);
    // An end on the axis (rho = 0) is the kink of a ray through it: D' jumps there from
    // +2R·sqrt(k) to −2R·sqrt(k), so it is the end of a convex piece with the one-sided sign.
    vec3 qlo = tr.qs + lo * tr.dq;
    vec3 qhi = tr.qs + hi * tr.dq;
    float glo = dot(qlo, qlo) > 0.0 ? sg * torus_dD(tr, lo).x : -1.0;
    if (glo >= 0.0) return lo;
    float ghi = dot(qhi, qhi) > 0.0 ? sg * torus_dD(tr, hi).x : 1.0;
    if (ghi <= 0.0) return hi;
    float x = lo + (hi - lo) * (-glo / (ghi - glo));  // the secant's zero
    for (int i = 0; i < TORUS_EXTREMUM_STEPS; i++) {
        vec2 g = sg * torus_dD(tr, x);
        if (g.x == 0.0) break;
        if (g.x < 0.0) lo = x; else hi = x;
        float xn = g.y > 0.0 ? x - g.x / g.y : 0.5 * (lo + hi);
        // Converged far below what decides a grazing pair: a dip of E deeper than E's own
        // rounding (~1e-7·R·r) is at least 3e-4·sqrt(R·r) wide. Tested before the bracket:
        // a converged step lands on the bracket's end, which must not trigger a bisection.
        if (abs(xn - x) <= tol) {
            x = clamp(xn, lo, hi);
            break;
        }
        x = (xn > lo && xn < hi) ? xn : 0.5 * (lo + hi);
    }
    return x;
}

// The one root of E in [lo, hi], where E is monotone and changes sign, one end the piece's
// extremum m (side = +1: m = lo, −1: m = hi), by Newton kept in the bracket. The start: the
// root of E's quadratic model at m, E(m) + D''(m)/2·(s − m)², which lands next to the near
// root of a grazing pair (Newton from the far end would halve the distance for many steps);
// else the end where sg·E > 0 (Fourier's condition: from there Newton does not overshoot).
float torus_root(TorusRay tr, float lo, float hi, float elo, float sg, float m, float em, float side) {
    float tol = 1e-7 * (tr.R + tr.r);
    float x = sg * elo > 0.0 ? lo : hi;
    float q = -em / torus_dD(tr, m).y;
    if (q > 0.0) {
        float xq = m + side * sqrt(q);
        if (xq > lo && xq < hi) x = xq;
    }
    bool neg_lo = elo < 0.0;
    float last = 3.0e38;
    for (int i = 0; i < TORUS_ROOT_STEPS; i++) {
        float e = torus_E(tr, x);
        if (e == 0.0) break;
        if ((e < 0.0) == neg_lo) lo = x; else hi = x;
        float g = 2.0 * torus_dD(tr, x).x;
        float xn = g != 0.0 ? x - e / g : 0.5 * (lo + hi);
        float step = abs(xn - x);
        // Converged, or at E's rounding floor (a near-double root: the step stops shrinking).
        if (step <= tol || (i > 1 && step >= last)) {
            x = clamp(xn, lo, hi);
            break;
        }
        last = step;
        x = (xn >= lo && xn <= hi) ? xn : 0.5 * (lo + hi);
    }
    return x;
}

// The ray set up against a torus (v0, v1: its records' first two texels), once for every test:
// the bounding sphere (radius R + r, padded) as intersect_sphere in raytrace.frag forms it, cut
// to the slab |z| <= r (padded), and the ray shifted to f (tr, t = tf + s). srange: the chord's
// range of s, cut to t in (0, t_max) — or, with `whole`, all of it, t <= 0 included (a ray
// leaving the torus needs every root to tell its own). False: no hit.
bool torus_setup(vec3 o, vec3 d, vec4 v0, vec4 v1, bool whole, float t_max, out TorusRay tr, out float tf,
                 out vec2 srange) {
    vec3 a = v1.xyz;
    float R = v0.w;
    float r = v1.w;
    vec3 p0 = o - v0.xyz;
    float b = dot(p0, d);
    vec3 f = p0 - b * d;
    // Both bounds padded (by more than the rounding of f and z), so E > 0 on them unless the
    // origin is inside: the torus touches its bounding sphere along the outer equator and the
    // slab's planes along two circles, where an unpadded bound could cut a root off.
    float rb = (R + r) * 1.0001;
    float zb = r + 1e-4 * (R + r);
    float h2 = rb * rb - dot(f, f);
    tf = -b;
    tr = TorusRay(vec3(0.0), vec3(0.0), 0.0, 0.0, R, r);
    srange = vec2(0.0);
    if (h2 < 0.0) return false;
    float h = sqrt(h2);
    float zs = dot(f, a);
    float dz = dot(d, a);
    tr = TorusRay(f - zs * a, d - dz * a, zs, dz, R, r);
    float lo = whole ? -h : max(-h, -tf);
    float hi = whole ? h : min(h, t_max - tf);
    if (dz != 0.0) {
        float s1 = (-zb - zs) / dz;
        float s2 = (zb - zs) / dz;
        lo = max(lo, min(s1, s2));
        hi = min(hi, max(s1, s2));
    } else if (abs(zs) > zb) {
        return false;
    }
    srange = vec2(lo, hi);
    return lo < hi;
}

// Method B's pieces of [lo, hi]: D is convex where rho³ >= R·L², L = |q × dq| (constant along
// the ray), and concave on the one interval (b1, b2) around the ray's closest approach to the
// axis where rho is smaller (b1 = b2 = hi: no such interval).
vec2 torus_pieces(TorusRay tr, float lo, float hi) {
    float k = dot(tr.dq, tr.dq);
    float b1 = hi;
    float b2 = hi;
    if (k > 1e-12) {
        vec3 c = cross(tr.qs, tr.dq);
        float L2 = dot(c, c);
        float sm = -dot(tr.qs, tr.dq) / k;
        float rm2 = L2 / k;
        float x = tr.R * L2;
        float rc = x > 0.0 ? exp2(log2(x) / 3.0) : 0.0;
        float sc2 = (rc * rc - rm2) / k;
        if (sc2 >= 0.0) {  // = 0: the ray meets the axis, D's kink there is the concave piece
            float sc = sqrt(sc2);
            b1 = clamp(sm - sc, lo, hi);
            b2 = clamp(sm + sc, lo, hi);
        }
    }
    return vec2(b1, b2);
}

// The outward unit normal at s: from the core circle's nearest point to the ray's point
// (the axis for a point on the core circle itself).
vec3 torus_normal(TorusRay tr, float s, vec3 axis) {
    vec3 q = tr.qs + s * tr.dq;
    float z = tr.zs + s * tr.dz;
    float rho = sqrt(dot(q, q));
    vec3 g = (rho > 0.0 ? (rho - tr.R) / rho : 0.0) * q + z * axis;
    float gl = sqrt(dot(g, g));
    return gl > 0.0 ? g / gl : axis;
}

// Method B (kept): the range has at most three pieces of known curvature (torus_pieces),
// each at most two monotone halves about its extremum, each at most one root. Every sign
// change of E is found, grazing pairs included, with E evaluated without cancellation.
float intersect_torus_bracket(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    n = vec3(0.0);
    TorusRay tr;
    float tf;
    vec2 sr;
    if (!torus_setup(o, d, v0, v1, false, t_max, tr, tf, sr)) return BIG;
    float lo = sr.x;
    float hi = sr.y;
    vec2 bc = torus_pieces(tr, lo, hi);
    float b1 = bc.x;
    float b2 = bc.y;
    float s_hit = BIG;
    float a_ = lo;
    for (int p = 0; p < 3; p++) {
        float b_ = p == 0 ? b1 : (p == 1 ? b2 : hi);
        float sg = p == 1 ? -1.0 : 1.0;
        if (b_ > a_) {
            float m = torus_extremum(tr, a_, b_, sg);
            float ea = torus_E(tr, a_);
            float em = torus_E(tr, m);
            float eb = torus_E(tr, b_);
            if ((ea < 0.0) != (em < 0.0) && m > a_) {
                s_hit = torus_root(tr, a_, m, ea, sg, m, em, -1.0);
                break;
            }
            if ((em < 0.0) != (eb < 0.0) && b_ > m) {
                s_hit = torus_root(tr, m, b_, em, sg, m, em, 1.0);
                break;
            }
        }
        a_ = max(a_, b_);
    }
    if (s_hit >= BIG) return BIG;
    float t = tf + s_hit;
    if (!(t > 0.0 && t < t_max)) return BIG;
    n = torus_normal(tr, s_hit, v1.xyz);
    return t;
}

// The real roots of x² + b·x + c (stable), as (x1, x2, count).
vec3 torus_quadratic(float b, float c) {
    float disc = b * b - 4.0 * c;
    if (disc < 0.0) return vec3(0.0, 0.0, 0.0);
    float sq = sqrt(disc);
    float qq = -0.5 * (b + (b >= 0.0 ? sq : -sq));
    if (qq == 0.0) return vec3(0.0, 0.0, 2.0);
    return vec3(qq, c / qq, 2.0);
}

// The largest real root of y³ + a·y² + b·y + c (trigonometric or Cardano's form, then Newton).
float torus_cubic_max(float a, float b, float c) {
    float a3 = a / 3.0;
    float p = b - a * a3;
    float qc = c - a3 * b + 2.0 * a3 * a3 * a3;
    float y;
    float disc = 0.25 * qc * qc + p * p * p / 27.0;
    if (disc <= 0.0 && p < 0.0) {
        float mm = 2.0 * sqrt(-p / 3.0);
        float th = acos(clamp(3.0 * qc / (p * mm), -1.0, 1.0)) / 3.0;
        y = mm * cos(th) - a3;
    } else {
        float sq = sqrt(max(disc, 0.0));
        float u = -0.5 * qc + (qc <= 0.0 ? sq : -sq);
        float cu = sign(u) * exp2(log2(abs(u)) / 3.0);
        if (u == 0.0) cu = 0.0;
        y = (cu != 0.0 ? cu - p / (3.0 * cu) : 0.0) - a3;
    }
    for (int i = 0; i < 2; i++) {
        float fy = ((y + a) * y + b) * y + c;
        float dy = (3.0 * y + 2.0 * a) * y + b;
        if (dy != 0.0) y -= fy / dy;
    }
    return y;
}

// Method A (measured, not kept): the quartic in u = s/R, depressed by the shift (no cubic
// term: s = 0 is the closest point to the centre), solved by Descartes' factorisation into
// two quadratics through the resolvent cubic; its constant term as the product E·H at s = 0
// (no cancellation); then two Newton steps on E polish the nearest root.
float intersect_torus_closed(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    n = vec3(0.0);
    TorusRay tr;
    float tf;
    vec2 sr;
    if (!torus_setup(o, d, v0, v1, false, t_max, tr, tf, sr)) return BIG;
    float R = tr.R;
    float r = tr.r;
    float k = dot(tr.dq, tr.dq);
    float rs = sqrt(dot(tr.qs, tr.qs)) / R;
    float zs = tr.zs / R;
    float rr = r / R;
    float e0 = zs * zs + (rs - 1.0 - rr) * (rs - 1.0 + rr);
    float h0 = zs * zs + (rs + 1.0 - rr) * (rs + 1.0 + rr);
    float c = rs * rs + zs * zs;
    float p = 2.0 * (c + (1.0 - rr) * (1.0 + rr)) - 4.0 * k;
    float q = -8.0 * dot(tr.qs, tr.dq) / R;
    float s0 = e0 * h0;
    // (u² + α·u + β)(u² − α·u + γ), α² = y the resolvent y³ + 2p·y² + (p² − 4s0)·y − q² = 0.
    float y = max(torus_cubic_max(2.0 * p, p * p - 4.0 * s0, -q * q), 0.0);
    float al = sqrt(y);
    float beta, gam;
    if (al > 1e-4) {
        beta = 0.5 * (p + y - q / al);
        gam = 0.5 * (p + y + q / al);
    } else {
        // q ~ 0: β and γ are the roots of x² − (p + y)·x + s0 (βγ = s0, β + γ = p + y).
        vec3 bg = torus_quadratic(-(p + y), s0);
        beta = bg.z > 0.0 ? bg.x : 0.5 * (p + y);
        gam = bg.z > 0.0 ? bg.y : 0.5 * (p + y);
    }
    vec3 r1 = torus_quadratic(al, beta);
    vec3 r2 = torus_quadratic(-al, gam);
    float best = BIG;
    for (int i = 0; i < 4; i++) {
        vec3 rq = i < 2 ? r1 : r2;
        float u = (i == 0 || i == 2) ? rq.x : rq.y;
        float s = u * R;
        if (rq.z > 0.0 && s > sr.x - 1e-3 * R && s < sr.y + 1e-3 * R && s < best) best = s;
    }
    if (best >= BIG) return BIG;
    for (int i = 0; i < 2; i++) {
        float g = 2.0 * torus_dD(tr, best).x;
        if (g != 0.0) best -= torus_E(tr, best) / g;
    }
    float t = tf + best;
    if (!(t > 0.0 && t < t_max)) return BIG;
    n = torus_normal(tr, best, v1.xyz);
    return t;
}

float intersect_torus(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    return intersect_torus_bracket(o, d, v0, v1, v2, t_max, n);
}

float intersect_shape(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    int kind = int(v2.z + 0.5);
    if (kind == SHAPE_TORUS) return intersect_torus(o, d, v0, v1, v2, t_max, n);
    if (kind == SHAPE_DISK) return intersect_disk(o, d, v0, v1, v2, t_max, n);
    return shape_frustum(o, d, v0, v1, v2, t_max, n);
}
