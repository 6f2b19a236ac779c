// Method "bih": the thesis's Bounding Interval Hierarchy (listing 3.5).
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Layout and bindings (u_bih_nodes: inner records, read through the accessors
// bih_node_<field>(i); u_bih_spheres: sphere records in leaf order, u_bih_root,
// u_box_min/max): renderer/accel/bih_layout.py (BIH_* constants, the accessors and the
// declarations in the header).

void method_init() {}

// Listing 3.5 with the corrections of docs/THESIS.md: the near child depends on the
// sign of d[axis]; each child gets its own interval; the far child is pushed
// with its interval and dropped on pop when it starts beyond the best hit.
// The stack has one entry per tree level, and the build never makes a tree
// deeper than BIH_STACK_SIZE, so it cannot overflow.
// Three loops, each doing one thing (llvmpipe runs every lane through all the code
// of a loop's body): descend through inner records to a leaf child, test the leaf's
// sphere records up to the one flagged last, pop.
void intersect_spheres(Query q, inout Hit h) {
    float t0, t1;
#if TREE_MAY_LACK_SPHERES
    // The tree holds other primitives too (at least one of them): u_num_spheres may be 0.
    if (!slab_interval(q.o, q.d, u_box_min, u_box_max, t0, t1) || !(t0 <= t1)) return;
#else
    if (u_num_spheres == 0 || !slab_interval(q.o, q.d, u_box_min, u_box_max, t0, t1) || !(t0 <= t1)) return;
#endif
    if (t0 > h.t) return;     // the whole box lies beyond the best hit (a plane's)
    uint st_ref[BIH_STACK_SIZE];
    float st_a[BIH_STACK_SIZE];
    float st_b[BIH_STACK_SIZE];
    int sp = 0;
    uint ref = u_bih_root;
    float a = t0;
    float b = t1;
    while (true) {
        while ((ref & BIH_REF_LEAF) == 0u) {
            COUNT(x);
            int i = int(ref);
            int axis = int(bih_node_axis(i));
            uint left = bih_node_left(i);
            uint right = bih_node_right(i);
            float clip_l = bih_node_clip_left(i);
            float clip_r = bih_node_clip_right(i);
            float o = q.o[axis];
            float dd = q.d[axis];
            uint near_ref, far_ref;
            float near_a, near_b, far_a, far_b;
            if (dd == 0.0) {
                // Parallel to the planes: each child is all or nothing.
                near_ref = left; far_ref = right;
                near_a = a; near_b = o <= clip_l ? b : -BIG;
                far_a = a;  far_b = o >= clip_r ? b : -BIG;
            } else {
                float t_l = (clip_l - o) / dd;
                float t_r = (clip_r - o) / dd;
                if (dd > 0.0) {
                    near_ref = left;  near_a = a;          near_b = min(b, t_l);
                    far_ref = right;  far_a = max(a, t_r); far_b = b;
                } else {
                    near_ref = right; near_a = a;          near_b = min(b, t_r);
                    far_ref = left;   far_a = max(a, t_l); far_b = b;
                }
            }
            bool near_ok = near_a <= near_b;
            bool far_ok = far_a <= far_b;
            if (!near_ok && !far_ok) { COUNT(y); ref = BIH_REF_NONE; break; }  // the empty gap
            near_ok = near_ok && near_a <= h.t;
            far_ok = far_ok && far_a <= h.t;
            if (near_ok) {
                if (far_ok) {
                    st_ref[sp] = far_ref; st_a[sp] = far_a; st_b[sp] = far_b; sp++;
                }
                ref = near_ref; a = near_a; b = near_b;
            } else if (far_ok) {
                ref = far_ref; a = far_a; b = far_b;
            } else {
                ref = BIH_REF_NONE;
            }
        }
        if (ref != BIH_REF_NONE) {
            COUNT(x);   // a leaf: its records, up to the one flagged last
            int p = int(ref & BIH_REF_INDEX);
            while (true) {
                Sphere s = SPHERE_AT(u_bih_spheres_at, p);
                leaf_hit(q, s, h);   // shaders/leaf.glsl: a sphere, or a slot of another kind
                if (q.any_hit && h.t < q.t_max) return;
                if (SPHERE_IS_LAST(s.key)) break;
                p++;
            }
        }
        // The next entry that can still hold a closer hit.
        ref = BIH_REF_NONE;
        while (sp > 0) {
            sp--;
            if (!(st_a[sp] > h.t)) { ref = st_ref[sp]; a = st_a[sp]; b = st_b[sp]; break; }
        }
        if (ref == BIH_REF_NONE) return;
    }
}
