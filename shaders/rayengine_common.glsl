// Shared part of the ray-engine shaders (methods "rayengine" and "hre",
// renderer/gl/ray_engine.py). The host (renderer/frame/shader_source.py) puts
// "#version 300 es", the layout header with the declarations of the scene's
// textures and uniforms (renderer/gpu/gpu_layout.py) and the pass's defines before
// this file, and the pass's own shader after it.
//
// The scene is read exactly as shaders/raytrace.frag reads it (same textures
// and uniforms, packed once by gpu_layout.pack_primitives), and the
// intersection and exclusion code below is raytrace.frag's, so that the ray
// engines compute the same t, ids and shading (docs/SHADING.md).
//
// Ray textures (one texel per pixel of the padded target):
//   ray_o  RGBA32F  origin.xyz, exclusion code (see decode_code)
//   ray_d  RGBA32F  direction.xyz, path weight (0: no live ray in this texel)
//   hit    RGBA32F  t, primitive id (-1: miss), 0, 0
//   surf0  RGBA32F  hit point p.xyz, primitive id (-1: none)
//   surf1  RGBA32F  outward normal N.xyz, +1 if dot(d, N) < 0 else -1
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp usampler2D;

const float BIG = 3.0e38;               // raytrace.frag's "no hit": a hit needs 0 < t < BIG
const int NO_PRIM = -1;
const float EPS32 = 1.1920929e-7;       // float32 machine epsilon

int row_shift(ivec2 size) { return int(log2(float(size.x)) + 0.5); }
ivec2 texel(int i, int shift) { return ivec2(i & ((1 << shift) - 1), i >> shift); }

vec4 fetch_sphere(int id) {
    return texelFetch(u_spheres, texel(id, row_shift(textureSize(u_spheres, 0))), 0);
}

// raytrace.frag's ray–sphere intersection (|d| = 1; far_only: the far root only).
float intersect_sphere(vec3 o, vec3 d, vec4 s, bool far_only) {
    vec3 oc = o - s.xyz;
    float b = dot(oc, d);
    vec3 f = oc - b * d;
    float h2 = s.w * s.w - dot(f, f);
    if (h2 < 0.0) return BIG;
    float h = sqrt(h2);
    float t_far = -b + h;
    if (far_only) return t_far > 0.0 ? t_far : BIG;
    float t_near = -b - h;
    if (t_near > 0.0) return t_near;
    return t_far > 0.0 ? t_far : BIG;
}

// t of primitive `id` (sphere or plane) along the ray with the exclusion rule
// of docs/SHADING.md; the caller accepts it when 0 < t < t_max (NaN fails).
float intersect_prim(int id, vec3 o, vec3 d, int skip, int far_id) {
    if (id == skip) return BIG;
    if (id < u_num_spheres) return intersect_sphere(o, d, fetch_sphere(id), id == far_id);
    int i = id - u_num_spheres;
    vec3 n = u_plane_normal[i];
    float denom = dot(d, n);
    if (denom == 0.0) return BIG;
    float t = dot(u_plane_point[i] - o, n) / denom;
    return t > 0.0 ? t : BIG;
}

// The ray leaving a hit on primitive `id` with outward normal n (raytrace.frag).
void exclusion(int id, vec3 n, vec3 d, out int skip, out int far_id) {
    if (id >= u_num_spheres || dot(d, n) >= 0.0) { skip = id; far_id = NO_PRIM; }
    else { skip = NO_PRIM; far_id = id; }
}

// Exclusion code stored in ray_o.w: -1 none (camera ray), id >= 0 the ray
// ignores primitive id, -(id + 2) only the far root of sphere id counts.
// Ids < 2^24 are exact in float32.
float encode_code(int id, vec3 n, vec3 d) {
    int skip, far_id;
    exclusion(id, n, d, skip, far_id);
    return skip != NO_PRIM ? float(skip) : -float(far_id) - 2.0;
}

void decode_code(float code, out int skip, out int far_id) {
    int c = int(code);
    if (c >= 0) { skip = c; far_id = NO_PRIM; }
    else if (c == -1) { skip = NO_PRIM; far_id = NO_PRIM; }
    else { skip = NO_PRIM; far_id = -c - 2; }
}

//@INCLUDE depth_order.glsl

// The shadow ray of `light` from the surface texel px (SHADING.md):
// false when there is no surface or the light does not face it.
bool shadow_ray_at(sampler2D surf0, sampler2D surf1, ivec2 px, int light,
                   out vec3 o, out vec3 l, out float dist, out int skip, out int far_id) {
    vec4 s0 = texelFetch(surf0, px, 0);
    if (s0.w < 0.0) return false;
    vec4 s1 = texelFetch(surf1, px, 0);
    vec3 to_light = u_light_pos[light] - s0.xyz;
    dist = length(to_light);
    l = to_light / dist;
    float cos_l = dot(s1.w * s1.xyz, l);
    if (!(cos_l > 0.0)) return false;
    exclusion(int(s0.w), s1.xyz, l, skip, far_id);
    o = s0.xyz;
    return true;
}

// Hierarchical ray engine (§4): can the cone (apex a, unit axis x, half-angle
// phi) meet the sphere s? The cone holds every ray of its tile within `slack`
// (world units); the sphere is inflated by the slack and by the rounding of
// s.xyz - a, and a small angular margin covers atan/asin, so the answer
// "cannot meet" is only given when it holds in exact arithmetic too.
const float CONE_ANGLE_MARGIN = 1.0e-4;   // radians (renderer/accel/hre_cones.py)

bool cone_misses_sphere(vec3 a, vec3 x, float phi, float slack, vec4 s) {
    vec3 w = s.xyz - a;
    float dist = length(w);
    float r = s.w + slack + 8.0 * EPS32 * (length(s.xyz) + length(a) + s.w);
    if (!(dist > r)) return false;                       // apex inside the sphere (or NaN): draw
    float ang = atan(length(cross(w, x)), dot(w, x));    // angle between axis and centre
    float rad = asin(r / dist);                          // angular radius seen from the apex
    return ang - rad > phi + CONE_ANGLE_MARGIN;
}
