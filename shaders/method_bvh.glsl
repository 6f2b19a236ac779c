// Method "bvh": binned-SAH bounding volume hierarchy with Reiter's ordered
// traversal (near mask per direction octant, listing 4.13), stack-based.
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Layout: renderer/accel/bvh_layout.py (an inner record holds both children's boxes and
// refs, read through its accessors bvh_node_<field>(i); leaves are runs of sphere records).
// Its constants (BVH_*), accessors and bindings (u_bvh_nodes, u_bvh_spheres, u_bvh_root,
// u_bvh_root_min/max) come via the host header.

void bvh_init() {}

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
float bvh_box(vec3 lo, vec3 hi, vec3 o, vec3 inv, float t_best) {
    vec3 ta = (lo - o) * inv;
    vec3 tb = (hi - o) * inv;
    vec3 tn = min(ta, tb);
    vec3 tf = max(ta, tb);
    float t0 = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float t1 = min(min(tf.x, tf.y), tf.z) * BVH_T_SLACK;
    return (t0 <= t1 && t0 <= t_best * BVH_T_SLACK) ? t0 : BIG;
}

// Ordered stack traversal (Reiter §4.4.1): at an inner node both children's
// boxes are tested; the one the near mask names for the ray's octant is
// visited first and the other pushed with its entry distance; a popped entry
// that starts beyond the best hit is dropped. The stack holds one entry per
// level and the build never makes a tree deeper than BVH_STACK_SIZE.
// Three loops, each doing one thing: descend through inner records to a leaf
// child, test the leaf's sphere records up to the one flagged last, pop.
void bvh_intersect(Query q, inout Hit h) {
    vec3 inv = bvh_safe_inv(q.d);
    uint octant = (q.d.x < 0.0 ? 1u : 0u) | (q.d.y < 0.0 ? 2u : 0u) | (q.d.z < 0.0 ? 4u : 0u);
    if (bvh_box(u_bvh_root_min, u_bvh_root_max, q.o, inv, h.t) >= BIG) return;
    uint st_ref[BVH_STACK_SIZE];
    float st_t[BVH_STACK_SIZE];
    int sp = 0;
    uint ref = u_bvh_root;
    while (true) {
        while ((ref & BVH_REF_LEAF) == 0u) {
            COUNT(x);
            int i = int(ref);
            float t_l = bvh_box(bvh_node_left_min(i), bvh_node_left_max(i), q.o, inv, h.t);
            float t_r = bvh_box(bvh_node_right_min(i), bvh_node_right_max(i), q.o, inv, h.t);
            bool right_first = ((bvh_node_near_mask(i) >> octant) & 1u) == 1u;
            uint left = bvh_node_left_ref(i);
            uint right = bvh_node_right_ref(i);
            uint near_ref = right_first ? right : left;
            uint far_ref = right_first ? left : right;
            float t_near = right_first ? t_r : t_l;
            float t_far = right_first ? t_l : t_r;
            if (t_near < BIG) {
                if (t_far < BIG) {
                    st_ref[sp] = far_ref; st_t[sp] = t_far; sp++;
                }
                ref = near_ref;
            } else if (t_far < BIG) {
                ref = far_ref;
            } else {
                COUNT(y);   // both children missed: the ray passes through empty space
                ref = BVH_REF_NONE;
            }
        }
        if (ref != BVH_REF_NONE) {
            COUNT(x);   // a leaf: its records, up to the one flagged last
            int p = int(ref & BVH_REF_INDEX);
            while (true) {
                Sphere s = SPHERE_AT(u_bvh_spheres_at, p);
                leaf_hit(q, s, h);   // shaders/leaf.glsl: a sphere, or a slot of another kind
                if (q.any_hit && h.t < q.t_max) return;
                if (SPHERE_IS_LAST(s.key)) break;
                p++;
            }
        }
        // pop the next entry that can still hold a closer hit
        ref = BVH_REF_NONE;
        while (sp > 0) {
            sp--;
            if (st_t[sp] <= h.t * BVH_T_SLACK) { ref = st_ref[sp]; break; }
        }
        if (ref == BVH_REF_NONE) return;
    }
}

// The method's entry points, where the BVH is the variant's method (twolevel has its own).
#if METHOD_BVH
void method_init() { bvh_init(); }

void intersect_spheres(Query q, inout Hit h) {
#if !TREE_MAY_LACK_SPHERES
    if (u_num_spheres == 0) return;
#endif
    bvh_intersect(q, h);
}
#endif
