// The leaf interface: how a method's traversal tests primitives (one whole chunk, included by
// raytrace.frag before the method's traversal).
//
// - A tree (bih, bvh, kdtree, twolevel) keeps its leaves as runs of sphere records
//   (SPHERE_AT); a record whose key carries TRI_SLOT or SHAPE_SLOT names a triangle or an
//   analytic shape instead (renderer/gpu/gpu_layout.py, leaf_records). Every tree tests each record
//   of a leaf with leaf_hit(q, record, h), whatever the kinds the variant traces.
// - An id-order method (bruteforce) tests its spheres with test_sphere, then
//   intersect_triangle_range (shaders/triangles.glsl) and intersect_shape_range
//   (shaders/shapes_tracer.glsl) over every triangle and shape.
//
// TREE_MAY_LACK_SPHERES is 1 where a tree can hold other primitives than spheres: its root may
// then be there with u_num_spheres 0, so a traversal may not skip the tree on that count.
#define TREE_MAY_LACK_SPHERES (FEATURE_TRIANGLES || FEATURE_SHAPES)

void leaf_hit(Query q, Sphere s, inout Hit h) {
#if FEATURE_SHAPES
    // A shape's slot: its index; its record is in u_shapes.
    if ((s.key & SHAPE_SLOT) != 0u) { test_shape(q, int(s.key & SHAPE_INDEX_MASK), h); return; }
#endif
#if FEATURE_TRIANGLES
    // A triangle's slot: its index; its corners are in u_triangles.
    if ((s.key & TRI_SLOT) != 0u) { test_triangle(q, int(s.key & TRI_INDEX_MASK), h); return; }
#endif
    test_sphere(q, s, h);
}
