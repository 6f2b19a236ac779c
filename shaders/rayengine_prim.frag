// Ray engine: the pixel's ray against the one primitive v_id.
// NEAREST (radiance rays): depth = depth_of(t), colour = (t, id); the depth
//   test keeps the nearest hit. ANY_HIT (shadow rays of light u_light): writes
//   1 where the primitive blocks the light (0 < t < distance to the light).
// CULL_MATRIX (tests): 1 where the vertex shader drew (tile, primitive).
// COUNT (heat mode): 1 per sphere drawn over the pixel, blended additively.
flat in int v_id;
uniform highp sampler2D u_ray_o;
uniform highp sampler2D u_ray_d;
uniform highp sampler2D u_surf0;
uniform highp sampler2D u_surf1;
uniform int u_light;
out vec4 o_out;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
#if CULL_MATRIX
    o_out = vec4(1.0);
#elif COUNT
    if (texelFetch(u_ray_d, px, 0).w <= 0.0) discard;
    o_out = vec4(v_id < u_num_spheres ? 1.0 : 0.0);
#elif ANY_HIT
    vec3 o, l;
    float dist;
    int skip, far_id;
    if (!shadow_ray_at(u_surf0, u_surf1, px, u_light, o, l, dist, skip, far_id)) discard;
    float t = intersect_prim(v_id, o, l, skip, far_id);
    if (!(t > 0.0 && t < dist)) discard;
    o_out = vec4(1.0);
#else
    vec4 rd = texelFetch(u_ray_d, px, 0);
    if (rd.w <= 0.0) discard;            // no live ray (the stencil test excludes it too)
    vec4 ro = texelFetch(u_ray_o, px, 0);
    int skip, far_id;
    decode_code(ro.w, skip, far_id);
    float t = intersect_prim(v_id, ro.xyz, rd.xyz, skip, far_id);
    if (!(t > 0.0 && t < BIG)) discard;
    gl_FragDepth = depth_of(t);
    o_out = vec4(t, float(v_id), 0.0, 0.0);
#endif
}
