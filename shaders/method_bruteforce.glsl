// Method "bruteforce": every ray tests every sphere (the thesis's "BF").
// Spliced into raytrace.frag at its METHOD mark; defines intersect_spheres().

void method_init() {}

void intersect_spheres(Query q, inout Hit h) {
    for (int i = 0; i < u_num_spheres; i++) {
        test_sphere(q, i, h);
        if (q.any_hit && h.id != NO_PRIM) return;
    }
}
