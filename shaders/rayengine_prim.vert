// Ray engine: draws one primitive (instance = primitive id: spheres 0 … n−1,
// then planes) over the ray target. Instances are drawn in id order, so with
// the depth test "less" exactly equal depths keep the lower id.
//
// RAYENGINE (Carr et al. 2002, §2.1): the primitive covers the whole target
// as a full-screen quad (a_position, 6 vertices).
// HRE (Szécsi 2006, §3–§4): one point of the tile's size per (tile, primitive);
// the vertex carries the tile's cone and the vertex shader moves the point out
// of view when the primitive's enclosing sphere cannot meet the cone.
// CULL_MATRIX (tests): the same decision written to pixel (primitive, tile).
flat out int v_id;
uniform int u_instance_base;    // id of instance 0: a pass may draw its primitives in batches, in id order

#if HRE || CULL_MATRIX
in vec2 a_tile;     // tile's lower-left texel
in vec4 a_cone0;    // apex.xyz, half-angle (< 0: draw always)
in vec4 a_cone1;    // axis.xyz, slack
uniform float u_tile_size;
uniform vec2 u_target;          // padded target size in texels
uniform vec2 u_matrix_size;     // CULL_MATRIX: (primitives, tiles)

bool drawn(int id) {
    if (id >= u_num_spheres || a_cone0.w < 0.0) return true;   // planes have no enclosing sphere
    return !cone_misses_sphere(a_cone0.xyz, a_cone1.xyz, a_cone0.w, a_cone1.w, fetch_sphere(id));
}
#else
in vec2 a_position;
#endif

void main() {
    int id = u_instance_base + gl_InstanceID;
    v_id = id;
#if CULL_MATRIX
    vec2 c = (vec2(float(id), float(gl_VertexID)) + 0.5) / u_matrix_size * 2.0 - 1.0;
    gl_Position = drawn(id) ? vec4(c, 0.0, 1.0) : vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = 1.0;
#elif HRE
    vec2 c = (a_tile + 0.5 * u_tile_size) / u_target * 2.0 - 1.0;
    // culled: an outlying position, discarded by clipping (§3)
    gl_Position = drawn(id) ? vec4(c, 0.0, 1.0) : vec4(2.0, 2.0, 2.0, 1.0);
    gl_PointSize = u_tile_size;
#else
    gl_Position = vec4(a_position, 0.0, 1.0);
#endif
}
