// Method "kdtree": SAH kd-tree (Reiter §4.3), front-to-back stack traversal
// with early exit. Spliced into raytrace.frag at its METHOD mark; defines
// intersect_spheres(). Node layout: renderer/accel/kdtree_layout.py (RG32UI).

// Layout constants (KD_*) and the bindings (u_kd_nodes, u_kd_indices, u_kd_box_min/max)
// come from renderer/accel/kdtree_layout.py via the host header.

int g_kd_node_shift, g_kd_index_shift;

void kd_init() {
    g_kd_node_shift = row_shift(textureSize(u_kd_nodes, 0));
    g_kd_index_shift = row_shift(textureSize(u_kd_indices, 0));
}

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
void kd_intersect(Query q, inout Hit h) {
    float t0, t1;
    if (!kd_clip(q.o, q.d, t0, t1)) return;
    int st_node[KD_STACK_SIZE];
    float st_a[KD_STACK_SIZE];
    float st_b[KD_STACK_SIZE];
    int sp = 0;
    st_node[0] = 0; st_a[0] = t0; st_b[0] = t1; sp = 1;
    while (sp > 0) {
        sp--;
        int node = st_node[sp];
        float a = st_a[sp];
        float b = st_b[sp];
        if (a > h.t * KD_T_SLACK) continue;
        while (true) {
            COUNT(x);
            uvec2 w = texelFetch(u_kd_nodes, texel(node, g_kd_node_shift), 0).xy;
            if ((w.x & KD_LEAF_TAG) == KD_LEAF_TAG) {
                int offset = int(w.y);
                int count = int(w.x & KD_LOW_MASK);
                if (count == 0) COUNT(y);   // an empty voxel
                for (int i = offset; i < offset + count; i++) {
                    int id = int(texelFetch(u_kd_indices, texel(i, g_kd_index_shift), 0).x);
                    test_sphere(q, id, h);
                    if (q.any_hit && h.t < q.t_max) return;
                }
                // early exit: the best hit lies within this leaf's interval
                if (h.id != NO_PRIM && h.t * KD_T_SLACK < b) return;
                break;
            }
            int axis = int(w.x >> KD_AXIS_SHIFT);
            int left = int(w.x & KD_LOW_MASK);
            float split = uintBitsToFloat(w.y);
            float o = q.o[axis];
            float dd = q.d[axis];
            if (dd == 0.0) {
                // parallel to the plane: the origin's side only (both when on it)
                if (o < split) { node = left; }
                else if (o > split) { node = left + 1; }
                else {
                    st_node[sp] = left + 1; st_a[sp] = a; st_b[sp] = b; sp++;
                    node = left;
                }
                continue;
            }
            bool below = o < split || (o == split && dd < 0.0);
            int near_node = below ? left : left + 1;
            int far_node = below ? left + 1 : left;
            float t_split = (split - o) / dd;
            if (t_split <= 0.0 || t_split > b * KD_T_SLACK) {
                node = near_node;                      // the ray stays on the near side
            } else if (t_split * KD_T_SLACK < a) {
                node = far_node;                       // it is past the plane already
            } else {
                st_node[sp] = far_node; st_a[sp] = t_split; st_b[sp] = b; sp++;
                node = near_node; b = t_split;
            }
        }
    }
}

#ifndef KD_NO_METHOD_INIT
void method_init() { kd_init(); }

void intersect_spheres(Query q, inout Hit h) {
    if (u_num_spheres == 0) return;
    kd_intersect(q, h);
}
#endif
