// Analytic shapes in the tracer: the leaf test (the rays leaving a shape included) and a shape's
// surface, on top of shapes.glsl's intersection tests. One whole chunk, included by
// raytrace.frag (after shapes.glsl) into every variant and compiled where FEATURE_SHAPES is 1
// (the SHAPES data format, in a variant that traces: renderer/frame/shader_source.py); a tree's leaf
// reaches test_shape through leaf_hit (shaders/leaf.glsl), brute force through
// intersect_shape_range.
#if FEATURE_SHAPES
// Record i of shape k (renderer/gpu/gpu_layout.py, shape_records): (origin, r0), (axis, r1),
// (height, caps, kind, material bits).
#define SHAPE_RECORD(k, i) u_shapes_at(SHAPE_TEXELS * (k) + (i))

// The ray leaving a shape ignores that shape's root nearest 0 — the one at its own origin,
// which float32 puts a little before or after 0 — and no other (renderer/geometry/shapes.py, the
// reference's rule; docs/SHADING.md, "Secondary rays"): a ray inside a cylinder meets its
// far wall, a ray leaving a torus may meet it again. So the tests below find every root
// of the shape, signed, drop the one of least |t| and keep the nearest in (0, t_max).

// A frustum's (cylinder's, cone's) signed roots: the side's two, then the base cap's and the
// top cap's, BIG where none (the side's from side_roots, as shape_lateral's).
vec4 frustum_roots(ShapeRay s, vec4 v0, vec4 v1, vec4 v2) {
    vec4 roots = vec4(BIG);
    float h = v2.x;
    float r0 = v0.w;
    float m = h > 0.0 ? (v1.w - v0.w) / h : 0.0;
    SideRoots sr;
    if (side_roots(s, r0, m, sr)) {
        for (int i = 0; i < 2; i++) {
            if (i == 0 && !sr.two) continue;
            float u = i == 0 ? sr.u1 : sr.u2;
            float z = sr.z1 + u * s.dz;
            if (z >= 0.0 && z <= h && r0 + m * z >= 0.0) roots[i] = sr.s0 + u;
        }
    }
    if (v2.y > 0.5 && s.dz != 0.0) {
        for (int i = 0; i < 2; i++) {
            float zc = i == 0 ? 0.0 : h;
            float rc = i == 0 ? v0.w : v1.w;
            float t = (zc - s.z0) / s.dz;
            vec3 q = s.q0 + t * s.dq;
            if (rc > 0.0 && dot(q, q) <= rc * rc) roots[2 + i] = t;
        }
    }
    return roots;
}

float frustum_leaving(vec3 o, vec3 d, vec4 v0, vec4 v1, vec4 v2, float t_max, out vec3 n) {
    n = vec3(0.0);
    vec3 a = v1.xyz;
    ShapeRay s = shape_ray(o - v0.xyz, d, a);
    vec4 roots = frustum_roots(s, v0, v1, v2);
    int own = 0;
    for (int i = 1; i < 4; i++) {
        if (abs(roots[i]) < abs(roots[own])) own = i;
    }
    float best = BIG;
    int part = -1;
    for (int i = 0; i < 4; i++) {
        float t = roots[i];
        if (i != own && t > 0.0 && t < t_max && t < best) { best = t; part = i; }
    }
    if (part == 2) n = -a;
    else if (part == 3) n = a;
    else if (part >= 0) {
        // The side's normal, as shape_lateral's.
        float m = v2.x > 0.0 ? (v1.w - v0.w) / v2.x : 0.0;
        vec3 q = s.q0 + best * s.dq;
        float rho = sqrt(dot(q, q));
        vec3 er = rho > 0.0 ? q / rho : vec3(0.0);
        vec3 g = er - m * a;
        float gl = sqrt(dot(g, g));
        n = gl > 0.0 ? g / gl : a;
    }
    return best;
}

// A torus's roots, all of them along its bounding sphere (t < 0 too), found as
// intersect_torus_bracket finds the first: at most one per monotone half of each piece.
float torus_leaving(vec3 o, vec3 d, vec4 v0, vec4 v1, float t_max, out vec3 n) {
    n = vec3(0.0);
    TorusRay tr;
    float tf;
    vec2 sr;
    if (!torus_setup(o, d, v0, v1, true, t_max, tr, tf, sr)) return BIG;
    float lo = sr.x;
    float hi = sr.y;
    vec2 bc = torus_pieces(tr, lo, hi);
    float b1 = bc.x;
    float b2 = bc.y;
    // The roots come in increasing s; the one of least |t| is the ray's origin.
    float rs[6];
    int nr = 0;
    float a_ = lo;
    for (int p = 0; p < 3; p++) {
        float b_ = p == 0 ? b1 : (p == 1 ? b2 : hi);
        float sg = p == 1 ? -1.0 : 1.0;
        if (b_ > a_) {
            float m = torus_extremum(tr, a_, b_, sg);
            float ea = torus_E(tr, a_);
            float em = torus_E(tr, m);
            float eb = torus_E(tr, b_);
            if ((ea < 0.0) != (em < 0.0) && m > a_) { rs[nr] = torus_root(tr, a_, m, ea, sg, m, em, -1.0); nr++; }
            if ((em < 0.0) != (eb < 0.0) && b_ > m) { rs[nr] = torus_root(tr, m, b_, em, sg, m, em, 1.0); nr++; }
        }
        a_ = max(a_, b_);
    }
    int own = -1;
    float own_abs = BIG;
    for (int i = 0; i < nr; i++) {
        if (abs(tf + rs[i]) < own_abs) { own_abs = abs(tf + rs[i]); own = i; }
    }
    float s_hit = BIG;
    for (int i = 0; i < nr; i++) {
        float t = tf + rs[i];
        if (i != own && t > 0.0 && t < t_max) { s_hit = rs[i]; break; }
    }
    if (s_hit >= BIG) return BIG;
    n = torus_normal(tr, s_hit, v1.xyz);
    return tf + s_hit;
}

// Shape k (scene id u_shape_base + k) against the query's ray; a ray leaving it (q.skip)
// ignores only its root at the origin (above): a disk, flat, has no other. The hit keeps
// the outward normal in h.sphere.xyz (the shading needs no second test) and k in h.key.
void test_shape(Query q, int k, inout Hit h) {
    COUNT(z);
    int id = u_shape_base + k;
    vec4 v0 = uintBitsToFloat(SHAPE_RECORD(k, 0));
    vec4 v1 = uintBitsToFloat(SHAPE_RECORD(k, 1));
    vec4 v2 = vec4(uintBitsToFloat(SHAPE_RECORD(k, 2).xyz), 0.0);
    vec3 n;
    float t;
    if (id != q.skip) {
        t = intersect_shape(q.o, q.d, v0, v1, v2, h.t, n);
    } else {
        int kind = int(v2.z + 0.5);
        n = vec3(0.0);
        t = kind == SHAPE_TORUS ? torus_leaving(q.o, q.d, v0, v1, h.t, n)
          : kind == SHAPE_DISK ? BIG
          : frustum_leaving(q.o, q.d, v0, v1, v2, h.t, n);
    }
    if (closer(t, id, h.t, h.id)) { h.t = t; h.id = id; h.sphere = vec4(n, 0.0); h.key = uint(k); }
}

// Shapes first … first + count − 1 in id order; a shadow ray (any_hit) stops at its first hit.
void intersect_shape_range(Query q, int first, int count, inout Hit h) {
    for (int k = first; k < first + count; k++) {
        test_shape(q, k, h);
        if (q.any_hit && h.id != NO_PRIM) return;
    }
}

// A shape's surface: the normal its test found (one normal: the geometric one too).
void shape_surface(Hit h, inout Surface s) {
    s.n = h.sphere.xyz;
#if FEATURE_TRIANGLES
    s.ng = s.n;
#endif
#if READS_MATERIALS
    s.mat = int(SHAPE_RECORD(int(h.key), 2).w & SHAPE_MAT_MASK);
#endif
}
#endif
