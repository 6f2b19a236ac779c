#version 300 es
// pocketray's Whitted ray tracer (thesis listing 3.1) with BIH traversal
// (listing 3.5, corrected as SPEC.md describes) or brute force.
// The conventions (rays, self-intersection, shading, modes) are those of
// docs/SHADING.md; the texture layout is renderer/gpu_layout.py, whose
// constants and the variant's METHOD_* / MODE_* defines are inserted by the
// host after the #version line. Valid GLSL ES 3.00, for WebGL2 too.
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp usampler2D;

//@HEADER@

uniform highp sampler2D u_spheres;      // (centre.xyz, radius) per sphere id
uniform highp usampler2D u_sphere_mat;  // material index per sphere id
uniform highp sampler2D u_materials;    // MATERIAL_TEXELS texels per material
uniform highp usampler2D u_nodes;       // BIH nodes (bih_layout)
uniform highp usampler2D u_indices;     // BIH sorted primitive indices

uniform int u_num_spheres;
uniform int u_num_planes;
uniform vec3 u_plane_point[MAX_PLANES];
uniform vec3 u_plane_normal[MAX_PLANES];
uniform int u_plane_mat[MAX_PLANES];
uniform int u_num_lights;
uniform vec3 u_light_pos[MAX_LIGHTS];
uniform vec3 u_light_color[MAX_LIGHTS];
uniform vec3 u_box_min;                 // BIH global AABB
uniform vec3 u_box_max;

uniform vec3 u_cam_pos;
uniform vec3 u_cam_right;
uniform vec3 u_cam_up;
uniform vec3 u_cam_forward;
uniform vec2 u_half_extent;             // (tan(fov_y/2)·W/H, tan(fov_y/2))
uniform vec2 u_resolution;              // (W, H)
uniform float u_target_distance;        // |target − position|, for the depth image
uniform int u_max_recursion_depth;      // 1 = primary rays only

layout(location = 0) out vec4 o_image;  // rgb = mode image, a = primary id (−1 miss)
layout(location = 1) out vec4 o_hit;    // xyz = outward normal, w = primary t (−1 miss)

const float BIG = 3.0e38;               // "no hit yet"; finite on purpose (no inf literals in ES)
const int NO_PRIM = -1;

ivec2 texel(int i, int width) { return ivec2(i % width, i / width); }

vec4 fetch_sphere(int id) {
    return texelFetch(u_spheres, texel(id, textureSize(u_spheres, 0).x), 0);
}

// Ray–sphere intersection (docs/SHADING.md). |d| = 1. The discriminant is
// formed as r² − |f|² with f the centre's offset from the ray's closest
// point, which avoids cancellation when the sphere is far away or tiny.
// far_only: count only the far root (a ray entering the sphere it starts on).
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

// Nearest hit; exactly equal t goes to the lower primitive id.
bool closer(float t, int id, float best_t, int best_id) {
    return t < best_t || (t == best_t && t < BIG && id < best_id);
}

struct Query {
    vec3 o;
    vec3 d;
    int skip;     // primitive the ray must ignore (−1: none)
    int far_id;   // sphere for which only the far root counts (−1: none)
    float t_max;  // hits at t >= t_max do not count (shadow rays: the light)
    bool any_hit; // stop at the first hit (shadow rays)
};

struct Hit {
    float t;
    int id;
};

// Counters for the heat mode (Fig. 4.3): nodes visited, gaps, sphere tests.
ivec3 g_counters = ivec3(0);

void test_sphere(Query q, int id, inout Hit h) {
    g_counters.z += 1;
    if (id == q.skip) return;
    float t = intersect_sphere(q.o, q.d, fetch_sphere(id), id == q.far_id);
    if (closer(t, id, h.t, h.id)) { h.t = t; h.id = id; }
}

#ifdef METHOD_BIH
// Slab test against the global AABB, clipped to [0, ∞). A zero direction
// component is handled explicitly: (bound − o) / 0 would give ±inf or NaN.
bool clip_box(vec3 o, vec3 d, out float t0, out float t1) {
    t0 = 0.0;
    t1 = BIG;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < u_box_min[a] || o[a] > u_box_max[a]) return false;
        } else {
            float ta = (u_box_min[a] - o[a]) / d[a];
            float tb = (u_box_max[a] - o[a]) / d[a];
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
    }
    return t0 <= t1;
}

// Listing 3.5 with the corrections of SPEC.md: the near child depends on the
// sign of d[axis]; each child gets its own interval; the far child is pushed
// with its interval and dropped on pop when it starts beyond the best hit.
// The stack has one entry per tree level, and the build never makes a tree
// deeper than BIH_STACK_SIZE, so it cannot overflow.
void traverse_bih(Query q, inout Hit h) {
    float t0, t1;
    if (u_num_spheres == 0 || !clip_box(q.o, q.d, t0, t1)) return;
    int node_width = textureSize(u_nodes, 0).x;
    int index_width = textureSize(u_indices, 0).x;
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
            g_counters.x += 1;
            uvec3 w = texelFetch(u_nodes, texel(node, node_width), 0).xyz;
            if ((w.x & BIH_LEAF_TAG) == BIH_LEAF_TAG) {
                int offset = int(w.y);
                int end = offset + int(w.z);
                for (int i = offset; i < end; i++) {
                    int id = int(texelFetch(u_indices, texel(i, index_width), 0).x);
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
            if (!near_ok && !far_ok) { g_counters.y += 1; break; }  // the empty gap
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
#endif

Hit intersect_scene(Query q) {
    Hit h = Hit(q.t_max, NO_PRIM);
    for (int i = 0; i < MAX_PLANES; i++) {
        if (i >= u_num_planes) break;
        int id = u_num_spheres + i;
        if (id == q.skip) continue;
        vec3 n = u_plane_normal[i];
        float denom = dot(q.d, n);
        if (denom == 0.0) continue;
        float t = dot(u_plane_point[i] - q.o, n) / denom;
        if (t > 0.0 && closer(t, id, h.t, h.id)) { h.t = t; h.id = id; }
    }
    if (q.any_hit && h.id != NO_PRIM) return h;
#ifdef METHOD_BIH
    traverse_bih(q, h);
#else
    for (int i = 0; i < u_num_spheres; i++) {
        test_sphere(q, i, h);
        if (q.any_hit && h.id != NO_PRIM) return h;
    }
#endif
    return h;
}

struct Material {
    vec3 color;
    float ambient, diffuse, specular, shininess, reflective, transmissive, ior;
};

Material fetch_material(int m) {
    int width = textureSize(u_materials, 0).x;
    vec4 a = texelFetch(u_materials, texel(m * MATERIAL_TEXELS, width), 0);
    vec4 b = texelFetch(u_materials, texel(m * MATERIAL_TEXELS + 1, width), 0);
    vec4 c = texelFetch(u_materials, texel(m * MATERIAL_TEXELS + 2, width), 0);
    return Material(a.rgb, a.a, b.x, b.y, b.z, b.w, c.x, c.y);
}

// The ray leaving a hit on primitive `id` with outward normal n: which
// primitive it ignores and for which sphere only the far root counts.
void exclusion(int id, vec3 n, vec3 d, out int skip, out int far_id) {
    if (id >= u_num_spheres || dot(d, n) >= 0.0) { skip = id; far_id = NO_PRIM; }
    else { skip = NO_PRIM; far_id = id; }
}

vec3 recursion_colour(int level) {
    if (level == 1) return vec3(1.0, 0.0, 0.0);
    if (level == 2) return vec3(0.0, 1.0, 0.0);
    if (level == 3) return vec3(0.0, 0.0, 1.0);
    if (level == 4) return vec3(1.0, 1.0, 0.0);
    if (level == 5) return vec3(1.0, 0.0, 1.0);
    if (level == 6) return vec3(0.0, 1.0, 1.0);
    if (level == 7) return vec3(1.0, 1.0, 1.0);
    if (level == 8) return vec3(1.0, 0.5, 0.0);
    return vec3(0.0);
}

struct Task {
    vec3 o;
    vec3 d;
    float weight;
    int level;
    int skip;
    int far_id;
};

#define MAX_TASKS 9

void main() {
    // gl_FragCoord.y grows upwards; image row 0 is the top row.
    float px = gl_FragCoord.x;
    float row = u_resolution.y - gl_FragCoord.y;
    float u = (2.0 * px / u_resolution.x - 1.0) * u_half_extent.x;
    float v = (1.0 - 2.0 * row / u_resolution.y) * u_half_extent.y;
    vec3 dir = normalize(u_cam_forward + u * u_cam_right + v * u_cam_up);

#if defined(MODE_COLOR) || defined(MODE_RECURSION)
    int max_level = u_max_recursion_depth;
#else
    int max_level = 1;
#endif

    Task tasks[MAX_TASKS];
    tasks[0] = Task(u_cam_pos, dir, 1.0, 1, NO_PRIM, NO_PRIM);
    int n_tasks = 1;
    vec3 colour = vec3(0.0);
    int deepest = 0;
    float primary_t = -1.0;
    int primary_id = NO_PRIM;
    vec3 primary_n = vec3(0.0);

    while (n_tasks > 0) {
        n_tasks--;
        Task k = tasks[n_tasks];
        Hit h = intersect_scene(Query(k.o, k.d, k.skip, k.far_id, BIG, false));
        if (h.id == NO_PRIM) continue;
        vec3 p = k.o + h.t * k.d;
        vec3 n;
        int mat;
        if (h.id < u_num_spheres) {
            vec4 s = fetch_sphere(h.id);
            n = (p - s.xyz) / s.w;
            mat = int(texelFetch(u_sphere_mat, texel(h.id, textureSize(u_sphere_mat, 0).x), 0).x);
        } else {
            n = u_plane_normal[h.id - u_num_spheres];
            mat = u_plane_mat[h.id - u_num_spheres];
        }
        n = normalize(n);
        if (k.level == 1) { primary_t = h.t; primary_id = h.id; primary_n = n; }
        deepest = max(deepest, k.level);
        if (max_level == 1 && k.level == 1) {
#if !defined(MODE_COLOR)
            break;
#endif
        }
        Material m = fetch_material(mat);
        vec3 nf = dot(k.d, n) < 0.0 ? n : -n;

        vec3 local = m.ambient * m.color;
        for (int li = 0; li < MAX_LIGHTS; li++) {
            if (li >= u_num_lights) break;
            vec3 to_light = u_light_pos[li] - p;
            float dist = length(to_light);
            vec3 l = to_light / dist;
            float cos_l = dot(nf, l);
            if (!(cos_l > 0.0)) continue;
            int skip, far_id;
            exclusion(h.id, n, l, skip, far_id);
            Hit sh = intersect_scene(Query(p, l, skip, far_id, dist, true));
            if (sh.id != NO_PRIM) continue;
            vec3 r = 2.0 * cos_l * nf - l;
            float x = dot(r, -k.d);
            float spec = x > 0.0 ? pow(x, m.shininess) : 0.0;
            local += u_light_color[li] * (m.diffuse * cos_l * m.color + m.specular * spec);
        }
        colour += k.weight * local;

        if (k.level < max_level) {
            if (m.reflective > 0.0) {
                vec3 r = k.d - 2.0 * dot(k.d, n) * n;
                int skip, far_id;
                exclusion(h.id, n, r, skip, far_id);
                tasks[n_tasks] = Task(p, r, k.weight * m.reflective, k.level + 1, skip, far_id);
                n_tasks++;
            }
            if (m.transmissive > 0.0) {
                bool entering = dot(k.d, n) < 0.0;
                float eta = entering ? 1.0 / m.ior : m.ior;
                vec3 nn = entering ? n : -n;
                float cos_i = -dot(k.d, nn);
                float kk = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                vec3 t_dir = kk < 0.0 ? k.d - 2.0 * dot(k.d, nn) * nn      // total internal reflection
                                      : normalize(eta * k.d + (eta * cos_i - sqrt(kk)) * nn);
                int skip, far_id;
                exclusion(h.id, n, t_dir, skip, far_id);
                tasks[n_tasks] = Task(p, t_dir, k.weight * m.transmissive, k.level + 1, skip, far_id);
                n_tasks++;
            }
        }
    }

    vec3 image;
#if defined(MODE_COLOR)
    image = colour;
#elif defined(MODE_RECURSION)
    image = recursion_colour(deepest);
#elif defined(MODE_DEPTH)
    image = primary_id == NO_PRIM ? vec3(0.0) : vec3(u_target_distance / (u_target_distance + primary_t));
#elif defined(MODE_PRIMID)
    image = primary_id == NO_PRIM ? vec3(0.0)
          : fract(float(primary_id) * vec3(0.6180340, 0.7548777, 0.5698403)) * 0.8 + 0.2;
#elif defined(MODE_NORMAL)
    image = primary_id == NO_PRIM ? vec3(0.0) : 0.5 * (primary_n + 1.0);
#elif defined(MODE_HEAT)
    image = min(vec3(0.05 * float(g_counters.z), 0.2 * float(g_counters.y), 0.2 * float(g_counters.x)), vec3(1.0));
#endif
    o_image = vec4(image, float(primary_id));
    o_hit = vec4(primary_n, primary_t);
}
