// Triangles in the tracer: the ray/triangle test and a triangle's surface. One whole chunk,
// included by raytrace.frag into every variant and compiled where FEATURE_TRIANGLES is 1 (the
// TRIANGLES data format, in a variant that traces: renderer/frame/shader_source.py); a tree's leaf
// reaches test_triangle through leaf_hit (shaders/leaf.glsl), brute force through
// intersect_triangle_range.
#if FEATURE_TRIANGLES
// Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013), in float32
// (docs/SHADING.md, "Triangles"). The ray's shear is computed once per ray
// (intersect_scene), not per triangle: kz = the axis of the largest |d| (the first on
// ties), kx and ky the next two, swapped when d[kz] < 0 so the winding (and the sign of
// det) is kept; S = (d[kx] / d[kz], d[ky] / d[kz], 1 / d[kz]).
struct Shear {
    int kx, ky, kz;
    vec3 s;
};
Shear g_shear;

Shear shear_of(vec3 d) {
    vec3 a = abs(d);
    int kz = (a.x >= a.y && a.x >= a.z) ? 0 : (a.y >= a.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (d[kz] < 0.0) { int t = kx; kx = ky; ky = t; }
    return Shear(kx, ky, kz, vec3(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]));
}

// The edge function E(P, Q) = Q.x·P.y − Q.y·P.x of two sheared corners. Watertightness
// rests on E(Q, P) = −E(P, Q) bit for bit, which plain IEEE arithmetic gives
// (fl(a·b − c·d) = −fl(c·d − a·b)) but a compiler that fuses one product into an FMA
// does not. So the products are always formed in one canonical order of the two corners
// (lexicographic on the sheared coordinates, which two triangles sharing the edge compute
// bitwise alike) and the sign is applied after: the two triangles evaluate the identical
// expression on identical operands, whatever the compiler fuses, and get exactly opposite
// values. The paper recomputes an edge function that is exactly 0 in double precision;
// GLSL ES has no double, so 0 stands: the ray is taken to touch the edge, and both
// triangles that share it accept it — a rare extra hit on the edge, never a leak.
float edge_fn(vec2 p, vec2 q) {
    bool swap = p.x > q.x || (p.x == q.x && p.y > q.y);
    vec2 a = swap ? q : p;
    vec2 b = swap ? p : q;
    float e = b.x * a.y - b.y * a.x;
    return swap ? -e : e;
}

// Record k of triangle j (renderer/gpu/gpu_layout.py, triangle_records): corner k in xyz, the
// material and the TRI_DEGENERATE flag in w of corner 0.
#define TRI_RECORD(j, k) u_triangles_at(TRIANGLE_TEXELS * (j) + (k))

// Triangle j (scene id u_tri_base + j) against the query's ray: both sides hit, the
// triangle the ray leaves ignored (a triangle is flat: the ray cannot meet it again, the
// no-epsilon exclusion of docs/SHADING.md). A zero-area triangle (float64 cross product 0)
// is flagged and never hit, as in the reference: its float32 det need not be 0. The hit keeps
// (U, V, W, det) in h.sphere — the barycentric weights U/det, V/det, W/det that smooth
// shading blends the vertex normals with — and j in h.key.
void test_triangle(Query q, int j, inout Hit h) {
    COUNT(z);
    int id = u_tri_base + j;
    if (id == q.skip) return;
    uvec4 r0 = TRI_RECORD(j, 0);
    if ((r0.w & TRI_DEGENERATE) != 0u) return;
    Shear sh = g_shear;
    // Corners relative to the origin, then sheared: each corner's values depend only on
    // the corner and the ray, so triangles sharing a corner see it bitwise alike.
    vec3 A = uintBitsToFloat(r0.xyz) - q.o;
    vec3 B = uintBitsToFloat(TRI_RECORD(j, 1).xyz) - q.o;
    vec3 C = uintBitsToFloat(TRI_RECORD(j, 2).xyz) - q.o;
    vec2 a = vec2(A[sh.kx] - sh.s.x * A[sh.kz], A[sh.ky] - sh.s.y * A[sh.kz]);
    vec2 b = vec2(B[sh.kx] - sh.s.x * B[sh.kz], B[sh.ky] - sh.s.y * B[sh.kz]);
    vec2 c = vec2(C[sh.kx] - sh.s.x * C[sh.kz], C[sh.ky] - sh.s.y * C[sh.kz]);
    float U = edge_fn(b, c);    // E(B, C)
    float V = edge_fn(c, a);    // E(C, A)
    float W = edge_fn(a, b);    // E(A, B)
    // Mixed signs: outside. Zeros are allowed (an edge or a vertex belongs to every
    // triangle it bounds), which is what closes the mesh.
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0)) return;
    float det = U + V + W;
    if (det == 0.0) return;
    float T = U * (sh.s.z * A[sh.kz]) + V * (sh.s.z * B[sh.kz]) + W * (sh.s.z * C[sh.kz]);
    float t = T / det;
    if (!(t > 0.0)) return;
    if (closer(t, id, h.t, h.id)) { h.t = t; h.id = id; h.sphere = vec4(U, V, W, det); h.key = uint(j); }
}

// Triangles first … first + count − 1 in id order; a shadow ray (any_hit) stops at its first hit.
void intersect_triangle_range(Query q, int first, int count, inout Hit h) {
    for (int j = first; j < first + count; j++) {
        test_triangle(q, j, h);
        if (q.any_hit && h.id != NO_PRIM) return;
    }
}

// A triangle's surface (docs/SHADING.md, "Triangles"): the geometric normal of its winding
// (outward on a closed mesh), the shading normal the normalised barycentric blend of its
// unit vertex normals for a smooth mesh (the weights the hit's test found, in h.sphere),
// the geometric one where the blend cancels or the mesh is flat.
void triangle_surface(vec3 d, Hit h, inout Surface s) {
    int j = int(h.key);
    uvec4 r0 = TRI_RECORD(j, 0);
    vec3 v0 = uintBitsToFloat(r0.xyz);
    vec3 g = cross(uintBitsToFloat(TRI_RECORD(j, 1).xyz) - v0, uintBitsToFloat(TRI_RECORD(j, 2).xyz) - v0);
    float len = length(g);
    s.ng = len > 0.0 ? g / len : -d;   // 0 only where float32 cannot resolve the triangle
    s.n = s.ng;
#if SMOOTH_TRIANGLES && READS_SHADING_NORMALS
    uvec4 n0 = u_tri_normals_at(TRIANGLE_TEXELS * j);
    if (n0.w != 0u) {
        float inv = 1.0 / h.sphere.w;
        vec3 blend = (h.sphere.x * inv) * uintBitsToFloat(n0.xyz)
                   + (h.sphere.y * inv) * uintBitsToFloat(u_tri_normals_at(TRIANGLE_TEXELS * j + 1).xyz)
                   + (h.sphere.z * inv) * uintBitsToFloat(u_tri_normals_at(TRIANGLE_TEXELS * j + 2).xyz);
        float bl = length(blend);
        if (bl > 0.0) s.n = blend / bl;
    }
#endif
#if READS_MATERIALS
    s.mat = int(r0.w & SPHERE_MAT_MASK);   // (bits 7..0; bit 31 is TRI_DEGENERATE)
#endif
}
#endif
