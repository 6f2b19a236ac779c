// Method "twolevel" (Reiter §3.2.2): static spheres in a kd-tree, moving ones in a BVH;
// every ray traverses both and keeps the nearer hit. The two traversals are the
// methods' own files, inlined by the host (renderer/frame/shader_source.py, INCLUDE lines).
// Bindings (both trees', u_bvh_count, u_kd_count): renderer/accel/twolevel.py.

//@INCLUDE method_bvh.glsl
//@INCLUDE method_kdtree.glsl

void method_init() { bvh_init(); kd_init(); }

void intersect_spheres(Query q, inout Hit h) {
    if (u_kd_count > 0) kd_intersect(q, h);          // static geometry first: its hit bounds the BVH
    if (q.any_hit && h.t < q.t_max) return;
    if (u_bvh_count > 0) bvh_intersect(q, h);
}
