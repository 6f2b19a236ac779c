// Method "bruteforce": every ray tests every sphere (the thesis's "BF").
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Binding (u_bf_spheres: sphere records in id order): renderer/accel/bruteforce.py.

void method_init() {}

void intersect_spheres(Query q, inout Hit h) {
    for (int i = 0; i < u_num_spheres; i++) {
        test_sphere(q, SPHERE_AT(u_bf_spheres_at, i), h);
        if (q.any_hit && h.id != NO_PRIM) return;
    }
#if FEATURE_TRIANGLES
    intersect_triangle_range(q, 0, u_num_triangles, h);   // then every triangle, in id order
    if (q.any_hit && h.id != NO_PRIM) return;
#endif
#if FEATURE_SHAPES
    intersect_shape_range(q, 0, u_num_shapes, h);         // then every analytic shape, in id order
#endif
}
