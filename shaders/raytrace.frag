#version 300 es
// pocketray's Whitted ray tracer (thesis listing 3.1) with BIH traversal
// (listing 3.5, corrected as docs/THESIS.md describes) or another method. The conventions
// (rays, self-intersection, shading, modes) are those of docs/SHADING.md. Valid GLSL ES 3.00,
// for WebGL2 too. Every variant is this file with the same whole chunks in the same order
// (renderer/frame/shader_source.py): the host writes the header at the HEADER mark (the layout
// constants, the variant's METHOD_* / MODE_* / READS_* defines, FEATURE_TRIANGLES,
// FEATURE_SHAPES, FEATURE_LIGHTING and its host choices always defined 0 or 1, and the
// declarations of every texture, uniform and record array the variant reads, generated from
// renderer/gpu/gpu_layout.py and the method's layout module, so each name is written once), the
// method's traversal at the METHOD mark (shaders/method_<name>.glsl: method_init(), called
// once per fragment, and intersect_spheres(), testing primitives through shaders/leaf.glsl),
// and includes the other chunks whole at their INCLUDE lines; #if switches them.
//
// Shaped for how llvmpipe runs it: a fragment shader is run for 8 pixels
// at once, and a branch no lane takes, or a loop that runs zero times, costs as much
// as running it; every texelFetch is a call into a generated function. So each loop
// does one thing (the traversal descends, tests a leaf, or pops), the shading loop
// traces one ray per iteration, and what a frame cannot use is not compiled in.
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp usampler2D;

//@HEADER@

#if FIRST_HITS_SPHERES
// First hits by rasterisation (renderer/frame/first_hits.py): this fragment lies in one sphere's screen
// rectangle, drawn as an instance of shaders/first_hits.vert; it tests that sphere alone and the
// depth test (≤, instances in descending id order) keeps the nearest, lower id on a tie.
flat in vec4 v_sphere;
flat in uint v_key;
#endif
#if FIRST_HITS_TILES
// … or in one tile (shaders/first_hit_tiles.vert): its list of spheres, nearest-possible first
// (TILE_ENTRY_TEXELS texels each: centre and radius; key and the near bound, as float bits).
flat in uvec2 v_list;   // first entry, count
uniform highp usampler2D u_tile_entries;
#endif

#if IMAGE_ONLY
layout(location = 0) out vec4 o_image;  // rgb = mode image rounded to 8 bits (an RGBA8 target)
#else
layout(location = 0) out vec4 o_image;  // rgb = mode image, a = primary id (−1 miss)
layout(location = 1) out vec4 o_hit;    // xyz = outward normal, w = primary t (−1 miss)
#endif

const float BIG = 3.0e38;               // "no hit yet"; finite on purpose (no inf literals in ES)
const int NO_PRIM = -1;

// Texture rows are a power of two wide (gpu_layout.wrap_rows), so element i
// is texel (i & mask, i >> shift): integer division per fetch costs llvmpipe
// half of a brute-force frame. The shifts are read once per fragment (LAYOUT_INIT).
int g_mat_shift;

#if FIRST_HITS
//@INCLUDE depth_order.glsl
#endif

int row_shift(ivec2 size) { return int(log2(float(size.x)) + 0.5); }  // exact: a power of two

ivec2 texel(int i, int shift) { return ivec2(i & ((1 << shift) - 1), i >> shift); }

// A sphere record (gpu_layout.sphere_records): centre and radius, and the key
// (id | material << SPHERE_MAT_SHIFT | SPHERE_LAST on the last record of a leaf).
// SPHERE_AT(ARRAY, p) reads record p of a record array (its NAME_at accessor).
struct Sphere {
    vec4 s;
    uint key;
};

#if EQUAL_RADII && !BACKGROUND
Sphere sphere_of(uvec4 w) { return Sphere(vec4(uintBitsToFloat(w.xyz), u_sphere_radius), w.w); }
#define SPHERE_AT(ARRAY, p) sphere_of(ARRAY(p))
#else
Sphere sphere_of(uvec4 a, uvec4 b) { return Sphere(uintBitsToFloat(a), b.x); }
#define SPHERE_AT(ARRAY, p) sphere_of(ARRAY(2 * (p)), ARRAY(2 * (p) + 1))
#endif
#define SPHERE_ID(key) int((key) & SPHERE_ID_MASK)
#define SPHERE_IS_LAST(key) (((key) & SPHERE_LAST) != 0u)

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

// The nearest hit so far, with the sphere's record (its centre and material are what
// shading needs: no second fetch by id).
struct Hit {
    float t;
    int id;
    vec4 sphere;
    uint key;
};

// Counters for the heat mode (Fig. 4.3): nodes visited, gaps, sphere tests.
// Compiled in only for that mode.
#if MODE_HEAT
ivec3 g_counters = ivec3(0);
#define COUNT(c) g_counters.c += 1
#else
#define COUNT(c)
#endif

void test_sphere(Query q, Sphere sp, inout Hit h) {
    COUNT(z);
    int id = SPHERE_ID(sp.key);
    if (id == q.skip) return;
    float t = intersect_sphere(q.o, q.d, sp.s, id == q.far_id);
    if (closer(t, id, h.t, h.id)) { h.t = t; h.id = id; h.sphere = sp.s; h.key = sp.key; }
}

// Slab test of a ray against an axis-aligned box, clipped to [0, ∞): entry
// and exit distances t0, t1. A zero direction component is handled
// explicitly, since (bound − o) / 0 gives ±inf or NaN. False when the ray runs
// parallel to a slab outside it; otherwise the caller compares t0 with t1.
bool slab_interval(vec3 o, vec3 d, vec3 bmin, vec3 bmax, out float t0, out float t1) {
    t0 = 0.0;
    t1 = BIG;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < bmin[a] || o[a] > bmax[a]) return false;
        } else {
            float ta = (bmin[a] - o[a]) / d[a];
            float tb = (bmax[a] - o[a]) / d[a];
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
    }
    return true;
}

// A hit's surface: where, its outward normal, its material (and, with triangles, the geometric
// normal: the side the ray sees, whether it enters; = n but on triangles).
struct Surface {
    vec3 p;
    vec3 n;   // outward unit normal
    int mat;
#if FEATURE_TRIANGLES
    vec3 ng;
#endif
};

// The primitive kinds beyond spheres and planes, each one whole chunk compiled where its
// FEATURE_* is 1, then the leaf interface every traversal calls (shaders/leaf.glsl).
//@INCLUDE triangles.glsl
#if FEATURE_SHAPES
//@INCLUDE shapes.glsl
#endif
//@INCLUDE shapes_tracer.glsl
//@INCLUDE leaf.glsl
//@INCLUDE ray_cones.glsl

#if !BACKGROUND
//@METHOD@
#else
// The background variant (host's choice): drawn only where no primary ray can meet a
// sphere (renderer/gpu/gpu_layout.py, primary_rect), so it has no traversal.
void method_init() {}
void intersect_spheres(Query q, inout Hit h) {}
#endif

// Planes and lights: a specialised variant knows their counts (N_PLANES, N_LIGHTS from
// PLANES_k / LIGHTS_k), so their loops have a known length; the generic one (-1) reads them.
#if N_PLANES >= 0
#define PLANE_LOOP N_PLANES
#define PLANES_END(i) false
#else
#define PLANE_LOOP MAX_PLANES
#define PLANES_END(i) ((i) >= u_num_planes)
#endif
#if N_PLANES == 1
#define PLANE_INDEX(i) 0
#else
#define PLANE_INDEX(i) (i)
#endif
#if N_LIGHTS >= 0
#define LIGHT_LOOP N_LIGHTS
#define LIGHTS_END(i) false
#else
#define LIGHT_LOOP MAX_LIGHTS
#define LIGHTS_END(i) ((i) >= u_num_lights)
#endif

Hit intersect_scene(Query q) {
    Hit h = Hit(q.t_max, NO_PRIM, vec4(0.0), 0u);
#if FEATURE_TRIANGLES
    g_shear = shear_of(q.d);   // once per ray, for every triangle it meets
#endif
    // llvmpipe pays for a loop's machinery even when it runs once: a variant that knows it
    // has one plane (every thesis scenario) tests it in straight code, 30 % of a 640 × 1088
    // depth frame of the plane alone. (With no plane the loop stays: without it, Mesa 22.3's
    // compiler crashes on a colour variant that can hit nothing.)
#if PLANE_LOOP == 1
    {
        int id = u_num_spheres;
        vec3 n = u_plane_normal[0];
        float denom = dot(q.d, n);
        if (id != q.skip && denom != 0.0) {
            float t = dot(u_plane_point[0] - q.o, n) / denom;
            if (t > 0.0 && closer(t, id, h.t, h.id)) { h.t = t; h.id = id; }
        }
    }
#else
    for (int i = 0; i < PLANE_LOOP; i++) {
        if (PLANES_END(i)) break;
        int id = u_num_spheres + i;
        if (id == q.skip) continue;
        vec3 n = u_plane_normal[i];
        float denom = dot(q.d, n);
        if (denom == 0.0) continue;
        float t = dot(u_plane_point[i] - q.o, n) / denom;
        if (t > 0.0 && closer(t, id, h.t, h.id)) { h.t = t; h.id = id; }
    }
#endif
    if (q.any_hit && h.id != NO_PRIM) return h;
    intersect_spheres(q, h);   // the method's traversal (shaders/method_*.glsl)
    return h;
}

// PBR_SHADING: a variant that shades (reads the materials) in a scene with PBR materials.
#if FEATURE_PBR && READS_MATERIALS
#define PBR_SHADING 1
#else
#define PBR_SHADING 0
#endif

struct Material {
    vec3 color;
    float ambient, diffuse, specular, shininess, reflective, transmissive, ior;
};

#if READS_MATERIALS
// Texel k of material m's record, read by the accessors material_<name>(m) of the header
// (renderer/materials: the record is laid out from the material's declaration). With several kinds
// (FEATURE_PBR) every record is MATERIAL_STRIDE texels, its kind's id first (MATERIAL_KIND), then
// the kind's record (the Phong kind's accessors material_<name>, the PBR kind's pbr_<name>).
#if FEATURE_PBR
#define MATERIAL_TEXEL(m, k) texelFetch(u_materials, texel((m) * MATERIAL_STRIDE + 1 + (k), g_mat_shift), 0)
#define MATERIAL_KIND(m) int(texelFetch(u_materials, texel((m) * MATERIAL_STRIDE, g_mat_shift), 0).x + 0.5)
#elif MATERIAL_TEXTURE
#define MATERIAL_TEXEL(m, k) texelFetch(u_materials, texel((m) * MATERIAL_TEXELS + (k), g_mat_shift), 0)
#else
#define MATERIAL_TEXEL(m, k) u_material_vecs[(m) * MATERIAL_TEXELS + (k)]
#endif
Material material_at(int m) {
    return Material(material_color(m), material_ambient(m), material_diffuse(m), material_specular(m),
                    material_shininess(m), material_reflective(m), material_transmissive(m), material_ior(m));
}
#endif

// The ray leaving a hit on primitive `id` with outward normal n: which
// primitive it ignores and for which sphere only the far root counts.
void exclusion(int id, vec3 n, vec3 d, out int skip, out int far_id) {
    if (id >= u_num_spheres || dot(d, n) >= 0.0) { skip = id; far_id = NO_PRIM; }
    else { skip = NO_PRIM; far_id = id; }
}

// The recursion mode's colour of a ray level: vec3 recursion_color(int level), written by the
// host from renderer/modes.py (RECURSION_COLORS), where the legend's come from too.
//@RECURSION_COLORS@

// Compile-time shape of the variant (llvmpipe and mobile GPUs pay for code
// that is only masked off, so what a frame cannot use is not compiled in):
// MAX_RECURSION_DEPTH (1 … 8) bounds the ray tree; modes other than colour
// and recursion trace the primary ray only.
#if !MODE_COLOR && !MODE_RECURSION
#undef MAX_RECURSION_DEPTH
#define MAX_RECURSION_DEPTH 1
#define PRIMARY_ONLY 1
#else
#define PRIMARY_ONLY 0
#endif
// The ray tree is evaluated depth-first (GLSL has no recursion). A hit spawns at most one
// reflected and one transmitted ray; the transmitted one is traced next and the
// reflected one waits on a task stack (one entry per level), so the tree is summed in
// the order of a recursion that follows the transmitted ray first. Only where a
// material both reflects and transmits can a hit spawn two rays: elsewhere
// (NO_SPLIT, NO_REFLECTION, NO_TRANSMISSION) the tree is a path and there is no stack.
// Shadow rays are traced by the same loop, one light per iteration: every iteration
// traces exactly one ray (the frame has a single call of intersect_scene, because
// every call site inlines another copy of the traversal), then shades its hit and
// picks the next ray — the next light's shadow ray, else a spawned ray, else a
// waiting one.
#if MAX_RECURSION_DEPTH > 1 && !NO_REFLECTION && !NO_TRANSMISSION && !NO_SPLIT
#define TASK_STACK 1
#define MAX_TASKS MAX_RECURSION_DEPTH
#else
#define TASK_STACK 0
#endif
#if MODE_COLOR && READS_LIGHTS
#define SHADOW_RAYS 1
#else
#define SHADOW_RAYS 0
#endif

// A ray's weight in the tree: a number (Phong: products of kr, kt), or a colour where PBR materials
// weigh rays by their Fresnel and base colour. WEIGHT_MAX: its largest component (the ε cut-off).
#if PBR_SHADING
#define Weight vec3
#define WEIGHT_MAX(w) max((w).r, max((w).g, (w).b))
#else
#define Weight float
#define WEIGHT_MAX(w) (w)
#endif
struct Task {
    vec3 o;
    vec3 d;
    Weight weight;
    int level;
    int skip;
    int far_id;
};


Surface surface_at(vec3 o, vec3 d, Hit h) {
    Surface s;
    s.p = o + h.t * d;
#if FEATURE_SHAPES
    if (h.id >= u_shape_base) { shape_surface(h, s); return s; }
#endif
#if FEATURE_TRIANGLES
    if (h.id >= u_tri_base) { triangle_surface(d, h, s); return s; }
#endif
    if (h.id < u_num_spheres) {
        // From the centre's offset (o − c) + t·d, not from p − c: far from the origin
        // p is rounded to float32's spacing there (0.0625 at 1e6), which can exceed
        // the radius and even make p − c zero (a NaN normal); o − c is exact there.
        vec3 rel = (o - h.sphere.xyz) + h.t * d;
        float len = length(rel);
        s.n = len > 0.0 ? rel / len : -d;   // len = 0 only where float32 cannot resolve the sphere
#if READS_MATERIALS
        s.mat = int((h.key >> SPHERE_MAT_SHIFT) & SPHERE_MAT_MASK);
#endif
    } else {
        int i = PLANE_INDEX(h.id - u_num_spheres);
        s.n = normalize(u_plane_normal[i]);
#if READS_MATERIALS
        s.mat = u_plane_mat[i];
#endif
    }
#if FEATURE_TRIANGLES
    s.ng = s.n;   // spheres and planes: one normal
#endif
    return s;
}

// The glTF metallic-roughness kind (FEATURE_PBR): its inputs at a hit and its BRDF, for Whitted's
// shading below and the path integrator's BSDF (shaders/bsdf_pbr_path.glsl).
#if PBR_SHADING
//@INCLUDE pbr_inputs.glsl
//@INCLUDE bsdf_pbr.glsl
#endif

// Emission, the environment and the path integrator (shaders/lighting.glsl) with the material's
// BSDF it calls (shaders/bsdf_phong.glsl).
#if FEATURE_LIGHTING
//@INCLUDE bsdf_phong.glsl
//@INCLUDE lighting.glsl
#endif
void main() {
    LAYOUT_INIT();
    method_init();
#if READS_MATERIALS && (MATERIAL_TEXTURE || FEATURE_PBR)
    g_mat_shift = row_shift(textureSize(u_materials, 0));
#endif
#if FEATURE_LIGHTING
    EMISSION_INIT();
    ENV_MAP_INIT();
    ENV_CDF_INIT();
#endif
#if PATH
    path_main();
#else
    // The point of the frame's sample grid (u_resolution) this fragment traces: a pass
    // traces one sub-pixel of every pixel (renderer/gpu/gpu_layout.py, PASS_BINDINGS); the
    // pixel-centre pass has scale 1 and offset 0.5, so px is gl_FragCoord.x itself. Every
    // term is a small integer or half: exact, so a pass equals one draw of the whole grid.
    // gl_FragCoord.y grows upwards; image row 0 is the top row.
    float px = (gl_FragCoord.x - 0.5) * u_pass_scale + u_pass_offset.x;
    float row = u_resolution.y - ((gl_FragCoord.y - 0.5) * u_pass_scale + u_pass_offset.y);
    float u = (2.0 * px / u_resolution.x - 1.0) * u_half_extent.x;
    float v = (1.0 - 2.0 * row / u_resolution.y) * u_half_extent.y;
    vec3 dir = normalize(u_cam_forward + u * u_cam_right + v * u_cam_up);

    vec3 color = vec3(0.0);
    int deepest = 0;
    float primary_t = -1.0;
    int primary_id = NO_PRIM;
    vec3 primary_n = vec3(0.0);

#if PRIMARY_ONLY
#if FIRST_HITS_SPHERES
    // The primary ray's test of intersect_scene (test_sphere, no ray to skip), for one sphere.
    Hit h0 = Hit(intersect_sphere(u_cam_pos, dir, v_sphere, false), SPHERE_ID(v_key), v_sphere, v_key);
    if (h0.t >= BIG) discard;
#elif FIRST_HITS_TILES
    // The tile's spheres in order of their near bounds: once the next one's bound lies beyond the
    // best hit, neither it nor any after it can be nearer (a bound equal to it may still tie).
    Hit h0 = Hit(BIG, NO_PRIM, vec4(0.0), 0u);
    int entry_shift = row_shift(textureSize(u_tile_entries, 0));
    int end = int(v_list.x + v_list.y);
    for (int i = int(v_list.x); i < end; i++) {
        uvec4 b = texelFetch(u_tile_entries, texel(TILE_ENTRY_TEXELS * i + 1, entry_shift), 0);
        if (uintBitsToFloat(b.y) > h0.t) break;
        vec4 sp = uintBitsToFloat(texelFetch(u_tile_entries, texel(TILE_ENTRY_TEXELS * i, entry_shift), 0));
        float t = intersect_sphere(u_cam_pos, dir, sp, false);
        int id = SPHERE_ID(b.x);
        if (closer(t, id, h0.t, h0.id)) h0 = Hit(t, id, sp, b.x);
    }
#else
    Hit h0 = intersect_scene(Query(u_cam_pos, dir, NO_PRIM, NO_PRIM, BIG, false));
#endif
    if (h0.id != NO_PRIM) {
        Surface s0 = surface_at(u_cam_pos, dir, h0);
        primary_t = h0.t; primary_id = h0.id; primary_n = s0.n; deepest = 1;
    }
#if FIRST_HITS
    // t's order as depth (shaders/depth_order.glsl): exact, so ≤ keeps what closer() keeps.
    gl_FragDepth = h0.id == NO_PRIM ? 1.0 : depth_of(h0.t);
#endif
#else
#if TASK_STACK
    Task tasks[MAX_TASKS];
    int n_tasks = 0;
#endif
    Task k = Task(u_cam_pos, dir, Weight(1.0), 1, NO_PRIM, NO_PRIM);   // the radiance ray being shaded
    Query q = Query(k.o, k.d, k.skip, k.far_id, BIG, false);   // the ray this iteration traces
    // Shading state of the current hit (light: the next light to try).
    int light = 0;
    Hit h;
    Surface s;
    Material m;
    vec3 nf;
    vec3 contrib = vec3(0.0);
#if PBR_SHADING
    // The current hit's PBR inputs (pbr_hit: its material is of that kind), the weights of the rays it
    // spawns (w_r, w_t: kr and kt of a Phong hit), and how far the ray went through surfaces it passed.
    bool pbr_hit = false;
    PbrInputs pin;
    Weight w_r = Weight(0.0), w_t = Weight(0.0);
    float passed = 0.0;
#define KR w_r
#define KT w_t
#else
#define KR m.reflective
#define KT m.transmissive
#endif
#if FEATURE_TEXTURES
    // Ray cones: the distance the ray tree travelled to k's origin (and to a spawned ray's, t_dist); as
    // mirrors and refractions keep the pixel's spread, the cone's width at a hit is spread × distance.
    float cone_spread = cone_pixel_spread(u_pass_scale), k_dist = 0.0, t_dist = 0.0;
#if TASK_STACK
    float task_dist[MAX_TASKS];
#endif
#endif
    while (true) {
        Hit hq = intersect_scene(q);
        bool live;   // the current radiance ray hit something: its lights and children are next
        if (q.any_hit) {
            if (hq.id == NO_PRIM) color += contrib;   // the light is visible
            light++;
            live = true;
        } else {
            live = hq.id != NO_PRIM;
#if FEATURE_LIGHTING
#if READS_ENVIRONMENT
            if (!live) color += k.weight * u_environment;   // what a ray that meets nothing sees
#endif
#if READS_ENVIRONMENT_MAP
            if (!live) color += k.weight * ENV_RADIANCE_AT(k.d);   // … or the image, along the ray
#endif
#endif
            if (live) {
                h = hq;
                s = surface_at(k.o, k.d, h);
#if FEATURE_TEXTURES
                g_cone_width = cone_footprint(cone_spread * (k_dist + h.t), k.d, s.ng);   // pbr_inputs' cone_width
#endif
#if PBR_SHADING
                // Whitted's PBR rule (docs/SHADING.md, "PBR"): a surface the ray passes (culled back
                // face, alpha below the cutoff; blend: coverage ≤ ½) lets it go on unchanged; a back
                // face met from inside attenuates it (KHR_materials_volume) before it is shaded.
                vec3 ng_k = s.n;
#if FEATURE_TRIANGLES
                ng_k = s.ng;
#endif
                bool front_k = dot(k.d, ng_k) < 0.0;
                if (pbr_passes(s.mat, h.id, s.p, s.n, front_k, 0.5)) {
                    int skip, far_id;
                    exclusion(h.id, s.n, k.d, skip, far_id);
                    passed += h.t;
#if FEATURE_TEXTURES
                    k_dist += h.t;   // the cone goes on from the passed surface
#endif
                    k.o = s.p; k.skip = skip; k.far_id = far_id;
                    q = Query(k.o, k.d, k.skip, k.far_id, BIG, false);
                    continue;
                }
                pbr_hit = MATERIAL_KIND(s.mat) == KIND_PBR;
                if (pbr_hit) {
                    pin = pbr_inputs(s.mat, h.id, s.p, s.n, g_cone_width);
                    if (!front_k) k.weight *= pbr_attenuation(s.mat, h.t);
                }
#endif
                if (k.level == 1) { primary_t = h.t; primary_id = h.id; primary_n = s.n; }
#if PBR_SHADING
                if (k.level == 1) primary_t += passed;
#endif
                deepest = max(deepest, k.level);
#if READS_MATERIALS
                m = material_at(s.mat);
#endif
                nf = dot(k.d, s.n) < 0.0 ? s.n : -s.n;
#if FEATURE_TRIANGLES
                nf = dot(k.d, s.ng) < 0.0 ? s.n : -s.n;   // the side by the geometric normal
#endif
#if PBR_SHADING
                if (pbr_hit) {
                    nf = dot(nf, s.n) > 0.0 ? pin.n : -pin.n;   // the normal map's, on the same side
                    float c = max(dot(nf, -k.d), 0.0);
                    vec3 fr = pbr_fresnel(pin.base_color, pin.metallic, pbr_f0_of(pbr_ior(s.mat)), c);
                    float smooth_share = (1.0 - pin.roughness) * (1.0 - pin.roughness);
                    w_r = fr * smooth_share;
                    w_t = (1.0 - pin.metallic) * pin.transmission * (1.0 - pbr_dielectric_fresnel(pbr_f0_of(pbr_ior(s.mat)), c))
                        * pin.base_color;
                    m.ior = pbr_ior(s.mat);
                } else {
                    w_r = Weight(m.reflective);
                    w_t = Weight(m.transmissive);
                }
#endif
#if MODE_COLOR
#if PBR_SHADING
                if (pbr_hit) {   // not for the share that refracts
                    float opaque = 1.0 - (1.0 - pin.metallic) * pin.transmission;
                    color += k.weight * (PBR_AMBIENT * pin.occlusion * opaque) * pin.base_color;
                } else
#endif
                color += k.weight * m.ambient * m.color;   // Phong's ambient term
#endif
#if FEATURE_LIGHTING && READS_EMISSION
                if (dot(nf, s.n) > 0.0) color += k.weight * emission_at(s.mat);   // the side its normal faces
#endif
                light = 0;
            }
        }
#if SHADOW_RAYS
        // The next light that faces the surface: its shadow ray.
        if (live) {
            bool shadow = false;
            for (; light < LIGHT_LOOP; light++) {
                if (LIGHTS_END(light)) break;
                vec3 to_light = u_light_pos[light] - s.p;
                float dist = length(to_light);
                vec3 l = to_light / dist;
                float cos_l = dot(nf, l);
                if (cos_l > 0.0) {
#if PBR_SHADING
                    // The glTF BRDF · cos under irradiance π · the light's colour (a white Lambert
                    // surface facing it shows the colour, as Phong's kd = 1 does).
                    if (pbr_hit) {
                        contrib = k.weight * u_light_color[light] * (PBR_PI * cos_l)
                                * pbr_brdf(pin.base_color, pin.metallic, pbr_alpha_of(pin.roughness),
                                           pbr_f0_of(pbr_ior(s.mat)), pin.transmission, 1.0, nf, -k.d, l);
                    } else {
#endif
                    vec3 r = 2.0 * cos_l * nf - l;
                    float x = dot(r, -k.d);
                    float spec = x > 0.0 ? pow(x, m.shininess) : 0.0;
                    contrib = k.weight * u_light_color[light] * (m.diffuse * cos_l * m.color + m.specular * spec);
#if PBR_SHADING
                    }
#endif
                    int skip, far_id;
                    exclusion(h.id, s.n, l, skip, far_id);
                    q = Query(s.p, l, skip, far_id, dist, true);
                    shadow = true;
                    break;
                }
            }
            if (shadow) continue;
        }
#endif
        // The lights are done: the rays the hit spawns, else one that waits.
        bool next = false;
        Task t;
#if MAX_RECURSION_DEPTH > 1
        if (live && k.level < MAX_RECURSION_DEPTH) {
            vec3 n = s.n;
#if FEATURE_TEXTURES
            t_dist = k_dist + h.t;   // both spawned rays start at the hit
#endif
#if !NO_REFLECTION
            if (WEIGHT_MAX(KR) > 0.0 && WEIGHT_MAX(k.weight * KR) >= u_min_weight) {
                vec3 r = k.d - 2.0 * dot(k.d, n) * n;
                int skip, far_id;
                exclusion(h.id, n, r, skip, far_id);
                t = Task(s.p, r, k.weight * KR, k.level + 1, skip, far_id);
                next = true;
            }
#endif
#if !NO_TRANSMISSION
            if (WEIGHT_MAX(KT) > 0.0 && WEIGHT_MAX(k.weight * KT) >= u_min_weight) {
                bool entering = dot(k.d, n) < 0.0;
#if FEATURE_TRIANGLES
                entering = dot(k.d, s.ng) < 0.0;   // enters by the geometric normal, bends about n
#endif
                float eta = entering ? 1.0 / m.ior : m.ior;
                vec3 nn = entering ? n : -n;
                float cos_i = -dot(k.d, nn);
                float kk = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                vec3 t_dir = kk < 0.0 ? k.d - 2.0 * dot(k.d, nn) * nn      // total internal reflection
                                      : normalize(eta * k.d + (eta * cos_i - sqrt(kk)) * nn);
                int skip, far_id;
                exclusion(h.id, n, t_dir, skip, far_id);
#if TASK_STACK
#if FEATURE_TEXTURES
                if (next) task_dist[n_tasks] = t_dist;
#endif
                if (next) { tasks[n_tasks] = t; n_tasks++; }   // the reflected ray waits
#endif
                t = Task(s.p, t_dir, k.weight * KT, k.level + 1, skip, far_id);
                next = true;
            }
#endif
        }
#endif
#if TASK_STACK
#if FEATURE_TEXTURES
        if (!next && n_tasks > 0) t_dist = task_dist[n_tasks - 1];
#endif
        if (!next && n_tasks > 0) { n_tasks--; t = tasks[n_tasks]; next = true; }
#endif
        if (!next) break;
        k = t;
#if PBR_SHADING
        passed = 0.0;
#endif
#if FEATURE_TEXTURES
        k_dist = t_dist;
#endif
        q = Query(k.o, k.d, k.skip, k.far_id, BIG, false);
    }
#endif

    vec3 image;
#if MODE_COLOR
    image = color;
#elif MODE_RECURSION
    image = recursion_color(deepest);
#elif MODE_DEPTH
    image = primary_id == NO_PRIM ? vec3(0.0) : vec3(u_target_distance / (u_target_distance + primary_t));
#elif MODE_PRIMID
    image = primary_id == NO_PRIM ? vec3(0.0)
          : fract(float(primary_id) * vec3(0.6180340, 0.7548777, 0.5698403)) * 0.8 + 0.2;
#elif MODE_NORMAL
    image = primary_id == NO_PRIM ? vec3(0.0) : 0.5 * (primary_n + 1.0);
#elif MODE_HEAT
    image = min(vec3(0.05 * float(g_counters.z), 0.2 * float(g_counters.y), 0.2 * float(g_counters.x)), vec3(1.0));
#endif
#if IMAGE_ONLY
    // The bytes of RenderResult.image_u8, floor(255·clamp(c, 0, 1) + 0.5), made here: the
    // RGBA8 target stores k / 255 as k exactly (its own conversion rounds differently).
    o_image = vec4(floor(255.0 * clamp(image, 0.0, 1.0) + 0.5) / 255.0, 1.0);
#else
    o_image = vec4(image, float(primary_id));
    o_hit = vec4(primary_n, primary_t);
#endif
#endif
}
