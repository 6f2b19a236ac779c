// Method "bruteforce": every ray tests every sphere (the thesis's "BF").
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().
// Binding (u_bf_spheres: sphere records in id order): renderer/accel/bruteforce.py.

void method_init() {}

void intersect_spheres(Query q, inout Hit h) {
    for (int i = 0; i < u_num_spheres; i++) {
        test_sphere(q, SPHERE_AT(u_bf_spheres_at, i), h);
        if (q.any_hit && h.id != NO_PRIM) return;
    }
//@TRIANGLES bruteforce_loop
//@SHAPES bruteforce_loop
}
