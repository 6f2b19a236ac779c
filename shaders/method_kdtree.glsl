// Method "kdtree": SAH kd-tree (Reiter §4.3), front-to-back stack traversal
// with early exit. Spliced into raytrace.frag at its METHOD mark; defines
// intersect_spheres(). Layout: renderer/accel/kdtree_layout.py (one uvec4 per inner
// node with both children's refs, read through its accessors kd_node_<field>(i); each leaf
// a run of sphere records). Its constants (KD_*), accessors and bindings (u_kd_nodes,
// u_kd_spheres, u_kd_root, u_kd_box_min/max) come via the host header.

void kd_init() {}

// The root voxel's interval (slab_interval), with the layout's slack.
bool kd_clip(vec3 o, vec3 d, out float t0, out float t1) {
    return slab_interval(o, d, u_kd_box_min, u_kd_box_max, t0, t1) && t0 <= t1 * KD_T_SLACK;
}

// Front-to-back traversal: at an inner node the child on the origin's side of
// the plane is near; it is valid on [a, min(b, t_split)], the far child on
// [max(a, t_split), b]. A leaf's spheres are tested, and once the best hit
// lies inside the leaf's interval (t < b) no later node can hold a closer
// one (every stacked interval starts at or beyond b): the traversal ends. A
// sphere straddling a plane is in both children, so a hit found in a leaf may
// lie beyond the leaf; then the traversal goes on (and such a hit only prunes).
// Three parts, each doing one thing: descend through inner records to a leaf child,
// the leaf (its sphere records, then the early exit), pop.
void kd_intersect(Query q, inout Hit h) {
    float t0, t1;
    if (!kd_clip(q.o, q.d, t0, t1)) return;
    if (t0 > h.t * KD_T_SLACK) return;
    uint st_ref[KD_STACK_SIZE];
    float st_a[KD_STACK_SIZE];
    float st_b[KD_STACK_SIZE];
    int sp = 0;
    uint ref = u_kd_root;
    float a = t0;
    float b = t1;
    while (true) {
        while ((ref & KD_REF_LEAF) == 0u) {
            COUNT(x);
            int i = int(ref);
            int axis = int(kd_node_axis(i));
            uint left = kd_node_left(i);
            uint right = kd_node_right(i);
            float split = kd_node_split(i);
            float o = q.o[axis];
            float dd = q.d[axis];
            if (dd == 0.0) {
                // parallel to the plane: the origin's side only (both when on it)
                if (o < split) { ref = left; }
                else if (o > split) { ref = right; }
                else {
                    st_ref[sp] = right; st_a[sp] = a; st_b[sp] = b; sp++;
                    ref = left;
                }
                continue;
            }
            bool below = o < split || (o == split && dd < 0.0);
            uint near_ref = below ? left : right;
            uint far_ref = below ? right : left;
            float t_split = (split - o) / dd;
            if (t_split <= 0.0 || t_split > b * KD_T_SLACK) {
                ref = near_ref;                        // the ray stays on the near side
            } else if (t_split * KD_T_SLACK < a) {
                ref = far_ref;                         // it is past the plane already
            } else {
                st_ref[sp] = far_ref; st_a[sp] = t_split; st_b[sp] = b; sp++;
                ref = near_ref; b = t_split;
            }
        }
        // A leaf: its records, up to the one flagged last (none in an empty voxel).
        COUNT(x);
        if ((ref & KD_REF_EMPTY) != 0u) {
            COUNT(y);   // an empty voxel
        } else {
            int p = int(ref & KD_REF_INDEX);
            while (true) {
                Sphere s = SPHERE_AT(u_kd_spheres_at, p);
                leaf_hit(q, s, h);   // shaders/leaf.glsl: a sphere, or a slot of another kind
                if (q.any_hit && h.t < q.t_max) return;
                if (SPHERE_IS_LAST(s.key)) break;
                p++;
            }
        }
        // early exit: the best hit lies within this leaf's interval
        if (h.id != NO_PRIM && h.t * KD_T_SLACK < b) return;
        // The next entry that can still hold a closer hit.
        ref = KD_REF_NONE;
        while (sp > 0) {
            sp--;
            if (!(st_a[sp] > h.t * KD_T_SLACK)) { ref = st_ref[sp]; a = st_a[sp]; b = st_b[sp]; break; }
        }
        if (ref == KD_REF_NONE) return;
    }
}

// The method's entry points, where the kd-tree is the variant's method (twolevel has its own).
#if METHOD_KDTREE
void method_init() { kd_init(); }

void intersect_spheres(Query q, inout Hit h) {
#if !TREE_MAY_LACK_SPHERES
    if (u_num_spheres == 0) return;
#endif
    kd_intersect(q, h);
}
#endif
