// Method "bvh": binned-SAH bounding volume hierarchy with Reiter's ordered
// traversal (near mask per direction octant, listing 4.13), stack-based.
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Node layout: renderer/accel/bvh_layout.py (two RGBA32UI texels per node).

// Layout constants (BVH_*) and the bindings (u_bvh_nodes, u_bvh_indices) come from
// renderer/accel/bvh_layout.py via the host header.

int g_bvh_node_shift, g_bvh_index_shift;

void bvh_init() {
    g_bvh_node_shift = row_shift(textureSize(u_bvh_nodes, 0));
    g_bvh_index_shift = row_shift(textureSize(u_bvh_indices, 0));
}

// 1/d with components of magnitude below BVH_DIR_EPS replaced by ±1/BVH_DIR_EPS,
// so that (bound − o) · inv is never 0 · inf = NaN (a parallel ray outside a
// slab gets a huge entry distance instead of a miss: conservative).
vec3 bvh_safe_inv(vec3 d) {
    vec3 s = vec3(d.x < 0.0 ? -1.0 : 1.0, d.y < 0.0 ? -1.0 : 1.0, d.z < 0.0 ? -1.0 : 1.0);
    return s / max(abs(d), vec3(BVH_DIR_EPS));
}

// Entry distance of the ray into the box, clamped to [0, ∞); BIG when the ray
// misses the box or enters it beyond t_best. The slack keeps float32 rounding
// from culling a box that holds the nearest hit (it only adds work).
float bvh_box(uvec4 lo, uvec4 hi, vec3 o, vec3 inv, float t_best) {
    vec3 ta = (uintBitsToFloat(lo.xyz) - o) * inv;
    vec3 tb = (uintBitsToFloat(hi.xyz) - o) * inv;
    vec3 tn = min(ta, tb);
    vec3 tf = max(ta, tb);
    float t0 = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float t1 = min(min(tf.x, tf.y), tf.z) * BVH_T_SLACK;
    return (t0 <= t1 && t0 <= t_best * BVH_T_SLACK) ? t0 : BIG;
}

uvec4 bvh_texel(int i) {
    return texelFetch(u_bvh_nodes, texel(i, g_bvh_node_shift), 0);
}

// Ordered stack traversal (Reiter §4.4.1): at an inner node both children's
// boxes are tested; the one the near mask names for the ray's octant is
// visited first and the other pushed with its entry distance; a popped entry
// that starts beyond the best hit is dropped. The stack holds one entry per
// level and the build never makes a tree deeper than BVH_STACK_SIZE.
void bvh_intersect(Query q, inout Hit h) {
    vec3 inv = bvh_safe_inv(q.d);
    uint octant = (q.d.x < 0.0 ? 1u : 0u) | (q.d.y < 0.0 ? 2u : 0u) | (q.d.z < 0.0 ? 4u : 0u);
    uvec4 n0 = bvh_texel(0);
    uvec4 n1 = bvh_texel(1);
    if (bvh_box(n0, n1, q.o, inv, h.t) >= BIG) return;
    int st_node[BVH_STACK_SIZE];
    float st_t[BVH_STACK_SIZE];
    int sp = 0;
    while (true) {
        COUNT(x);
        if ((n1.w & BVH_INNER_FLAG) == 0u) {
            int offset = int(n0.w);
            int end = offset + int(n1.w & BVH_COUNT_MASK);
            for (int i = offset; i < end; i++) {
                int id = int(texelFetch(u_bvh_indices, texel(i, g_bvh_index_shift), 0).x);
                test_sphere(q, id, h);
                if (q.any_hit && h.t < q.t_max) return;
            }
        } else {
            int l = int(n0.w);
            bool right_first = ((n1.w >> octant) & 1u) == 1u;
            int near_node = right_first ? l + 1 : l;
            int far_node = right_first ? l : l + 1;
            uvec4 a0 = bvh_texel(2 * near_node);
            uvec4 a1 = bvh_texel(2 * near_node + 1);
            uvec4 b0 = bvh_texel(2 * far_node);
            uvec4 b1 = bvh_texel(2 * far_node + 1);
            float t_near = bvh_box(a0, a1, q.o, inv, h.t);
            float t_far = bvh_box(b0, b1, q.o, inv, h.t);
            if (t_near < BIG) {
                if (t_far < BIG) {
                    st_node[sp] = far_node; st_t[sp] = t_far; sp++;
                }
                n0 = a0; n1 = a1;
                continue;
            }
            if (t_far < BIG) {
                n0 = b0; n1 = b1;
                continue;
            }
            COUNT(y);   // both children missed: the ray passes through empty space
        }
        // pop the next entry that can still hold a closer hit
        int node = -1;
        while (sp > 0) {
            sp--;
            if (st_t[sp] <= h.t * BVH_T_SLACK) { node = st_node[sp]; break; }
        }
        if (node < 0) return;
        n0 = bvh_texel(2 * node);
        n1 = bvh_texel(2 * node + 1);
    }
}

#ifndef BVH_NO_METHOD_INIT
void method_init() { bvh_init(); }

void intersect_spheres(Query q, inout Hit h) {
    if (u_num_spheres == 0) return;
    bvh_intersect(q, h);
}
#endif
