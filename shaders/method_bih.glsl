// Method "bih": the thesis's Bounding Interval Hierarchy (listing 3.5).
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Node layout and bindings (u_nodes, u_indices, u_box_min/max): renderer/accel/bih_layout.py
// (BIH_* constants and the declarations in the header).

int g_node_shift, g_index_shift;

void method_init() {
    g_node_shift = row_shift(textureSize(u_nodes, 0));
    g_index_shift = row_shift(textureSize(u_indices, 0));
}

// Listing 3.5 with the corrections of docs/THESIS.md: the near child depends on the
// sign of d[axis]; each child gets its own interval; the far child is pushed
// with its interval and dropped on pop when it starts beyond the best hit.
// The stack has one entry per tree level, and the build never makes a tree
// deeper than BIH_STACK_SIZE, so it cannot overflow.
void intersect_spheres(Query q, inout Hit h) {
    float t0, t1;
    if (u_num_spheres == 0 || !slab_interval(q.o, q.d, u_box_min, u_box_max, t0, t1) || !(t0 <= t1)) return;
    int st_node[BIH_STACK_SIZE];
    float st_a[BIH_STACK_SIZE];
    float st_b[BIH_STACK_SIZE];
    int sp = 0;
    st_node[0] = 0; st_a[0] = t0; st_b[0] = t1; sp = 1;
    while (sp > 0) {
        sp--;
        int node = st_node[sp];
        float a = st_a[sp];
        float b = st_b[sp];
        if (a > h.t) continue;
        while (true) {
            COUNT(x);
            uvec3 w = texelFetch(u_nodes, texel(node, g_node_shift), 0).xyz;
            if ((w.x & BIH_LEAF_TAG) == BIH_LEAF_TAG) {
                int offset = int(w.y);
                int end = offset + int(w.z);
                for (int i = offset; i < end; i++) {
                    int id = int(texelFetch(u_indices, texel(i, g_index_shift), 0).x);
                    test_sphere(q, id, h);
                    if (q.any_hit && h.t < q.t_max) return;
                }
                break;
            }
            int axis = int(w.x >> BIH_AXIS_SHIFT);
            int left = int(w.x & BIH_CHILD_MASK);
            float clip_l = uintBitsToFloat(w.y);
            float clip_r = uintBitsToFloat(w.z);
            float o = q.o[axis];
            float dd = q.d[axis];
            int near_node, far_node;
            float near_a, near_b, far_a, far_b;
            if (dd == 0.0) {
                // Parallel to the planes: each child is all or nothing.
                near_node = left; far_node = left + 1;
                near_a = a; near_b = o <= clip_l ? b : -BIG;
                far_a = a;  far_b = o >= clip_r ? b : -BIG;
            } else {
                float t_l = (clip_l - o) / dd;
                float t_r = (clip_r - o) / dd;
                if (dd > 0.0) {
                    near_node = left;     near_a = a;          near_b = min(b, t_l);
                    far_node = left + 1;  far_a = max(a, t_r); far_b = b;
                } else {
                    near_node = left + 1; near_a = a;          near_b = min(b, t_r);
                    far_node = left;      far_a = max(a, t_l); far_b = b;
                }
            }
            bool near_ok = near_a <= near_b;
            bool far_ok = far_a <= far_b;
            if (!near_ok && !far_ok) { COUNT(y); break; }  // the empty gap
            near_ok = near_ok && near_a <= h.t;
            far_ok = far_ok && far_a <= h.t;
            if (near_ok) {
                if (far_ok) {
                    st_node[sp] = far_node; st_a[sp] = far_a; st_b[sp] = far_b; sp++;
                }
                node = near_node; a = near_a; b = near_b;
            } else if (far_ok) {
                node = far_node; a = far_a; b = far_b;
            } else {
                break;
            }
        }
    }
}
