// Emission, the environment and the path integrator (docs/SHADING.md): one whole chunk that
// raytrace.frag includes and compiles where FEATURE_LIGHTING is 1 (a variant that carries
// EMISSION, ENVIRONMENT or PATH: renderer/frame/shader_source.py); raytrace.frag's main calls
// path_main where PATH is defined, and its Whitted loop adds emission and the environment.
// path_main's parts for triangles and shapes are #if FEATURE_TRIANGLES / FEATURE_SHAPES blocks;
// the material it shades with is behind the BSDF of shaders/bsdf_phong.glsl.

#if READS_EMISSION
int g_emission_shift;
// The radiance material m emits on the side its surface's normal faces.
vec3 emission_at(int m) { return texelFetch(u_emission, texel(m, g_emission_shift), 0).rgb; }
#define EMISSION_INIT() g_emission_shift = row_shift(textureSize(u_emission, 0))
#else
vec3 emission_at(int m) { return vec3(0.0); }
#define EMISSION_INIT()
#endif
#if READS_ENVIRONMENT
#define ENV_RADIANCE u_environment
#else
#define ENV_RADIANCE vec3(0.0)
#endif
#if READS_ENVIRONMENT_MAP
// An equirectangular environment image (docs/FORMATS.md, "Environment"; renderer/materials/envmap.py, whose
// NumPy twin of each function the tests compare with): u = atan2(x, −z)/2π + rotation, v = acos(y)/π;
// bilinear between texels as Mitsuba's envmap (column i at u = (i + ½)/W, row j at v = j/(H − 1)).
const float ENV_PI = 3.14159265358979;
int g_env_shift;
vec3 env_texel(int i, int j) { return texelFetch(u_env_map, texel(j * u_env_size.x + i, g_env_shift), 0).rgb; }
vec2 env_uv(vec3 d) {
    float u = atan(d.x, -d.z) * (0.5 / ENV_PI) + u_env_u_offset;
    return vec2(u - floor(u), acos(clamp(d.y, -1.0, 1.0)) * (1.0 / ENV_PI));
}
vec3 env_lookup(vec2 uv) {
    int w = u_env_size.x, h = u_env_size.y;
    float s = uv.x * float(w) - 0.5;
    float fs = floor(s);
    int i0 = int(fs);
    i0 = i0 < 0 ? i0 + w : (i0 >= w ? i0 - w : i0);
    int i1 = i0 + 1 == w ? 0 : i0 + 1;
    float t = uv.y * float(h - 1);
    int j0 = clamp(int(floor(t)), 0, h - 2);
    float fx = s - fs, fy = t - float(j0);
    vec3 a = mix(env_texel(i0, j0), env_texel(i1, j0), fx);
    vec3 b = mix(env_texel(i0, j0 + 1), env_texel(i1, j0 + 1), fx);
    return u_env_scale * mix(a, b, fy);
}
#define ENV_RADIANCE_AT(d) env_lookup(env_uv(d))
#define ENV_MAP_INIT() g_env_shift = row_shift(textureSize(u_env_map, 0))
#else
#define ENV_RADIANCE_AT(d) ENV_RADIANCE
#define ENV_MAP_INIT()
#endif
#if READS_ENVIRONMENT_SAMPLING
// Importance sampling of the image (renderer/materials/envmap.py): a patch row from the marginal CDF, a patch
// from the row's conditional one (binary searches), then a point uniform in the patch's (u, v).
int g_env_cdf_shift;
float env_cdf(int k) { return texelFetch(u_env_cdf, texel(k, g_env_cdf_shift), 0).r; }
// The first index in [base, base + n) whose CDF value exceeds x (n − 1 if none).
int env_search(int base, int n, float x) {
    int lo = 0, hi = n - 1;
    for (int k = 0; k < 13; k++) {   // 2^13 > MAX_ENV_WIDTH
        if (lo >= hi) break;
        int mid = (lo + hi) / 2;
        if (env_cdf(base + mid) > x) hi = mid; else lo = mid + 1;
    }
    return lo;
}
// The pdf per steradian of direction d (P(patch) · W · (H − 1) / (2π² sin θ)).
float env_pdf(vec3 d) {
    int w = u_env_size.x, rows = u_env_size.y - 1;
    vec2 uv = env_uv(d);
    float sin_t = sqrt(max(0.0, 1.0 - d.y * d.y));
    if (sin_t <= 0.0) return 0.0;
    float s = uv.x * float(w) - 0.5;
    int i = int(floor(s));
    i = i < 0 ? i + w : (i >= w ? i - w : i);
    int j = clamp(int(floor(uv.y * float(rows))), 0, rows - 1);
    int m = rows * w;
    float pm = env_cdf(m + j) - (j > 0 ? env_cdf(m + j - 1) : 0.0);
    float pc = env_cdf(j * w + i) - (i > 0 ? env_cdf(j * w + i - 1) : 0.0);
    return pm * pc * float(w * rows) / (2.0 * ENV_PI * ENV_PI * sin_t);
}
vec3 env_sample(float u1, float u2, out float pdf) {
    int w = u_env_size.x, rows = u_env_size.y - 1;
    int m = rows * w;
    int j = env_search(m, rows, u1);
    float lo = j > 0 ? env_cdf(m + j - 1) : 0.0;
    float fy = clamp((u1 - lo) / max(env_cdf(m + j) - lo, 1e-30), 0.0, 1.0);
    int i = env_search(j * w, w, u2);
    lo = i > 0 ? env_cdf(j * w + i - 1) : 0.0;
    float fx = clamp((u2 - lo) / max(env_cdf(j * w + i) - lo, 1e-30), 0.0, 1.0);
    float u = (float(i) + 0.5 + fx) / float(w) - u_env_u_offset;
    float theta = ENV_PI * (float(j) + fy) / float(rows);
    float phi = 2.0 * ENV_PI * u;
    vec3 d = vec3(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
    pdf = env_pdf(d);
    return d;
}
#define ENV_CDF_INIT() g_env_cdf_shift = row_shift(textureSize(u_env_cdf, 0))
#else
#define ENV_CDF_INIT()
#endif

#if PATH
// ---- the path integrator (docs/SHADING.md, "Path integrator") ----------------------------
// The material's BSDF is shaders/bsdf_phong.glsl (the surface record, bsdf_eval, bsdf_sample,
// bsdf_pdf); here: the camera's rays, next-event estimation (sample_light) and the path's loop.
// What the scene lacks is not compiled in (renderer/frame/features.py, PATH_REMOVALS): every lane runs
// all of the loop's code, used or not. The host names a removal only where it says something; the
// rest follow here: no light kind where nothing emits.
#if !READS_EMISSION
#undef NO_SPHERE_LIGHTS
#undef NO_TRIANGLE_LIGHTS
#undef NO_SHAPE_LIGHTS
#define NO_SPHERE_LIGHTS 1
#define NO_TRIANGLE_LIGHTS 1
#define NO_SHAPE_LIGHTS 1
#endif
#if GUIDES
// The denoiser's guides (renderer/image/denoise.py), sums over the pass's samples: the first hit's albedo
// as its lobes reflect (bsdf_albedo; a miss: the environment clamped to [0, 1]) and its outward
// normal (a miss: 0).
layout(location = 2) out vec4 o_albedo;
layout(location = 3) out vec4 o_normal;
#endif
// Random numbers: a function of (pixel, sample index, dimension) alone, so sample i of a pixel
// is the same path in whichever pass traces it. The pixel's position in it: the R2 rank-1
// lattice (Roberts) in the sample index, Cranley–Patterson-rotated per pixel; every other
// dimension an integer hash (Wellons's lowbias32) of all three.
uint hash_u(uint x) {
    x ^= x >> 16; x *= 0x7feb352du;
    x ^= x >> 15; x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}
uint g_pixel_seed;
uint g_sample_seed;
uint g_dim;
float unit_float(uint h) { return float(h >> 8) * (1.0 / 16777216.0); }   // [0, 1), 24 bits
float rnd() {
    g_dim += 1u;
    return unit_float(hash_u(g_sample_seed ^ hash_u(g_dim * 0x9e3779b9u + g_pixel_seed)));
}
vec2 pixel_jitter(uint i) {
    // i · (1/φ₂, 1/φ₂²) mod 1 in 32-bit fixed point (exact for every i), plus the pixel's rotation.
    uvec2 a = uvec2(3242174889u, 2447445414u) * i;
    vec2 shift = vec2(unit_float(hash_u(g_pixel_seed ^ 0xa511e9b3u)), unit_float(hash_u(g_pixel_seed ^ 0x63d83595u)));
    return fract(vec2(a >> 8u) * (1.0 / 16777216.0) + shift);
}

#if !NO_SHAPE_LIGHTS
// A point uniform in area on emitting surface k (u_emit_patch_*, renderer/gpu/gpu_layout.py
// shape_patches) and its outward normal n.
vec3 patch_point(int k, float u1, float u2, out vec3 n) {
    vec4 a = u_emit_patch_a[k], b = u_emit_patch_b[k], c = u_emit_patch_c[k];
    vec3 t, bt;
    basis(b.xyz, t, bt);
    float phi = 2.0 * PI * u2;
    vec3 radial = cos(phi) * t + sin(phi) * bt;
    int kind = int(c.y);
    if (kind == PATCH_DISK) {
        // An annulus: r² uniform between the inner and the outer radius's squares.
        n = b.xyz;
        return a.xyz + sqrt(mix(b.w * b.w, a.w * a.w, u1)) * radial;
    }
    if (kind == PATCH_SIDE) {
        // A frustum's side: the area at height z grows with the radius there, linear in z, so r² is
        // uniform between the end radii's squares (a cylinder, or all but one: z uniform).
        float dr = b.w - a.w;
        float r = sqrt(mix(a.w * a.w, b.w * b.w, u1));
        float z = abs(dr) > 1e-3 * max(a.w, b.w) ? (r - a.w) / dr * c.x : u1 * c.x;
        n = normalize(c.x * radial - dr * b.xyz);
        return a.xyz + z * b.xyz + r * radial;
    }
    // A torus: the tube's angle v with density ∝ R + r·cos v (the area element), by rejection
    // (each try is accepted with probability ≥ (R − r) / (R + r); the last is kept after 16).
    float v = 2.0 * PI * u1;
    for (int i = 0; i < 16; i++) {
        if (rnd() * (a.w + b.w) <= a.w + b.w * cos(v)) break;
        v = 2.0 * PI * rnd();
    }
    n = cos(v) * radial + sin(v) * b.xyz;
    return a.xyz + a.w * radial + b.w * n;
}
#endif

// The ray of sample i through the pixel at window position frag (gl_FragCoord.xy), from the camera:
// a point of the pixel's box jittered by the sample's place in the lattice (and the random numbers
// of the sample started).
void camera_ray(uint i, vec2 frag, out vec3 o, out vec3 d) {
    g_sample_seed = hash_u(i ^ 0x27d4eb2fu);
    g_dim = 0u;
    vec2 j = pixel_jitter(i);
    // The pixel's box: its lower-left corner (in rows from the top) plus the jitter.
    float px = floor(frag.x) + j.x;
    float row = u_resolution.y - (floor(frag.y) + j.y);
    float u = (2.0 * px / u_resolution.x - 1.0) * u_half_extent.x;
    float v = (1.0 - 2.0 * row / u_resolution.y) * u_half_extent.y;
    o = u_cam_pos;
    d = normalize(u_cam_forward + u * u_cam_right + v * u_cam_up);
}

// The shadow ray from r's point along unit l, meeting blockers nearer than t_max. With PBR materials
// it finds the nearest blocker (not any): one that lets light through (alpha, a culled back face:
// pbr_passes) sends the shadow ray on from it, and a blocker behind it must not be skipped.
#if FEATURE_PBR
#define SHADOW_ANY_HIT false
#else
#define SHADOW_ANY_HIT true
#endif
Query shadow_query(SurfaceRecord r, vec3 l, float t_max) {
    int skip, far_id;
    exclusion(r.prim, r.n, l, skip, far_id);
    return Query(r.p, l, skip, far_id, t_max, SHADOW_ANY_HIT);
}

// The power heuristic's weight of light sampling for a light sample of density p_l (solid angle)
// whose direction the BSDF would choose with density p_bsdf.
float light_weight(float p_l, float p_bsdf) {
    return p_l * p_l / (p_l * p_l + p_bsdf * p_bsdf);
}

// Next-event estimation's light kinds, in the order a vertex samples them; the point lights and the
// emitting spheres one light after another (nee_index), the others one sample each.
const int NEE_POINT = 0;
const int NEE_SPHERES = 1;
const int NEE_TRIANGLES = 2;
const int NEE_SHAPES = 3;
const int NEE_ENVIRONMENT = 4;
const int NEE_DONE = 5;

// The vertex's next light sample (pbrt's SampleLd, one shadow ray at a time, as the loop traces
// every ray at its one intersect_scene): from light kind `kind`, light `index` on, the first that
// lights r's non-specular lobes; true with its shadow ray q and contrib, the radiance it adds
// (times beta) if nothing blocks it; false when every light is done. Each sampled light is weighted
// by the power heuristic against BSDF sampling (the point lights, deltas, are not). After a shadow
// ray of the point lights or the spheres the caller moves index on; the other kinds move `kind`
// on here.
bool sample_light(SurfaceRecord r, vec3 beta, inout int kind, inout int index, inout Query q, inout vec3 contrib) {
    float pdf;
    if (kind == NEE_POINT) {
#if SHADOW_RAYS
        for (; index < LIGHT_LOOP; index++) {
            if (LIGHTS_END(index)) break;
            vec3 to_light = u_light_pos[index] - r.p;
            float dist2 = dot(to_light, to_light);
            float dist = sqrt(dist2);
            vec3 l = to_light / dist;
            float cos_l = dot(r.nf, l);
            if (cos_l > 0.0 && dist > 0.0) {
                // Intensity I = color_light · u_light_scale, E = I cos / r².
                vec3 f = bsdf_eval(r, l, pdf);
                contrib = beta * f * u_light_color[index] * (u_light_scale * cos_l / dist2);
                q = shadow_query(r, l, dist);
                return true;
            }
        }
#endif
        kind = NEE_SPHERES;
        index = 0;
    }
    if (kind == NEE_SPHERES) {
#if !NO_SPHERE_LIGHTS
        // A direction in the cone the sphere fills (uniform in solid angle).
        for (; index < MAX_SAMPLED_SPHERES; index++) {
            if (index >= u_num_emitters) break;
            vec4 e = u_emitter_sphere[index];
            vec3 to_c = e.xyz - r.p;
            float dist2 = dot(to_c, to_c);
            float sin2 = e.w * e.w / dist2;
            float u1 = rnd(), u2 = rnd();
            if (!(sin2 < 1.0)) continue;   // the vertex is inside (or on) it: not sampled
            float cone = sin2 / (1.0 + sqrt(1.0 - sin2));   // 1 − cos θmax, without cancellation
            float cos_t = 1.0 - u1 * cone;
            float sin_t = sqrt(max(0.0, 1.0 - cos_t * cos_t));
            float phi = 2.0 * PI * u2;
            vec3 t, b;
            basis(to_c * inversesqrt(dist2), t, b);
            vec3 l = normalize(sin_t * cos(phi) * t + sin_t * sin(phi) * b + cos_t * to_c * inversesqrt(dist2));
            float cos_l = dot(r.nf, l);
            float te = intersect_sphere(r.p, l, e, false);
            if (cos_l <= 0.0 || te >= BIG) continue;
            float p_l = 1.0 / (2.0 * PI * cone);
            vec3 f = bsdf_eval(r, l, pdf);
            contrib = beta * f * u_emitter_radiance[index] * (cos_l * light_weight(p_l, pdf) / p_l);
            q = shadow_query(r, l, te * (1.0 - 1e-4));   // blockers before the sphere
            return true;
        }
#endif
        kind = NEE_TRIANGLES;
    }
    if (kind == NEE_TRIANGLES) {
        kind = NEE_SHAPES;
#if !NO_TRIANGLE_LIGHTS
        // One emitting triangle, picked with probability ∝ its area, a point uniform on it (pdf in
        // solid angle dist² / (A cos θ_light), A their total area).
        if (u_num_emit_tris > 0) {
            float pick = rnd(), b1 = rnd(), b2 = rnd();
            int k = 0;
            for (int i = 0; i < MAX_SAMPLED_TRIANGLES; i++) {
                if (i >= u_num_emit_tris || pick < u_emit_tri_cdf[i]) break;
                k = i + 1;
            }
            k = min(k, u_num_emit_tris - 1);
            float su = sqrt(b1);
            vec3 e1 = u_emit_tri_e1[k], e2 = u_emit_tri_e2[k];
            vec3 x = u_emit_tri_v0[k] + su * (1.0 - b2) * e1 + su * b2 * e2;   // uniform in the triangle
            vec3 to_x = x - r.p;
            float dist2 = dot(to_x, to_x);
            float dist = sqrt(dist2);
            vec3 l = to_x / dist;
            vec3 ng_l = normalize(cross(e1, e2));
            float cos_light = -dot(l, ng_l);             // > 0: the side its winding faces, which emits
            float cos_l = dot(r.nf, l);
            if (dist > 0.0 && cos_light > 0.0 && cos_l > 0.0) {
                float p_l = dist2 / (u_emit_tri_area * cos_light);
                vec3 f = bsdf_eval(r, l, pdf);
                contrib = beta * f * u_emit_tri_radiance[k] * (cos_l * light_weight(p_l, pdf) / p_l);
                q = shadow_query(r, l, dist * (1.0 - 1e-4));
                return true;
            }
        }
#endif
    }
    if (kind == NEE_SHAPES) {
        kind = NEE_ENVIRONMENT;
#if !NO_SHAPE_LIGHTS
        // One surface of the emitting analytic shapes (a side, a cap, a disk, a torus), picked with
        // probability ∝ its area, a point uniform on it: the same pdf as the triangles'.
        if (u_num_emit_patches > 0) {
            float pick = rnd(), u1 = rnd(), u2 = rnd();
            int k = 0;
            for (int i = 0; i < MAX_SAMPLED_SHAPE_PATCHES; i++) {
                if (i >= u_num_emit_patches || pick < u_emit_patch_cdf[i]) break;
                k = i + 1;
            }
            k = min(k, u_num_emit_patches - 1);
            vec3 ng_l;
            vec3 to_x = patch_point(k, u1, u2, ng_l) - r.p;
            float dist2 = dot(to_x, to_x);
            float dist = sqrt(dist2);
            vec3 l = to_x / dist;
            float cos_light = -dot(l, ng_l);             // > 0: the side its normal faces, which emits
            float cos_l = dot(r.nf, l);
            if (dist > 0.0 && cos_light > 0.0 && cos_l > 0.0) {
                float p_l = dist2 / (u_emit_patch_area * cos_light);
                vec3 f = bsdf_eval(r, l, pdf);
                contrib = beta * f * u_emit_patch_radiance[k] * (cos_l * light_weight(p_l, pdf) / p_l);
                q = shadow_query(r, l, dist * (1.0 - 1e-4));
                return true;
            }
        }
#endif
    }
    if (kind == NEE_ENVIRONMENT) {
        kind = NEE_DONE;
#if READS_ENVIRONMENT_SAMPLING
        // One direction from the image's importance sampling (a bright sun seen in a rough metal is
        // found this way), a shadow ray to infinity.
        float u1 = rnd(), u2 = rnd();
        float p_l;
        vec3 l = env_sample(u1, u2, p_l);
        float cos_l = dot(r.nf, l);
        if (p_l > 0.0 && cos_l > 0.0) {
            vec3 f = bsdf_eval(r, l, pdf);
            contrib = beta * f * ENV_RADIANCE_AT(l) * (cos_l * light_weight(p_l, pdf) / p_l);
            q = shadow_query(r, l, BIG);
            return true;
        }
#endif
    }
    return false;
}

// The power heuristic's weight of BSDF sampling for the emission of hit h (geometric normal ng), met
// along d from prev_p, where the BSDF chose d with density prev_pdf (0: a lobe next-event estimation
// does not light, or the camera: weight 1). Emitters that next-event estimation samples get the
// weight against their light pdf; every other (planes, spheres past the sampled ones) is met by BSDF
// sampling alone.
float emission_weight(Hit h, vec3 ng, vec3 d, vec3 prev_p, float prev_pdf) {
    float w = 1.0;
#if !NO_SPHERE_LIGHTS
    if (prev_pdf > 0.0 && h.id < u_num_spheres && h.id <= u_emitter_last) {
        vec3 to_c = h.sphere.xyz - prev_p;
        float sin2 = h.sphere.w * h.sphere.w / dot(to_c, to_c);
        if (sin2 < 1.0) w = light_weight(prev_pdf, 1.0 / (2.0 * PI * (sin2 / (1.0 + sqrt(1.0 - sin2)))));
    }
#endif
#if FEATURE_TRIANGLES
    // An emitting triangle (all are sampled, when any is).
    if (prev_pdf > 0.0 && h.id >= u_tri_base && u_num_emit_tris > 0) {
        float cos_light = -dot(d, ng);
        w = light_weight(prev_pdf, h.t * h.t / (u_emit_tri_area * max(cos_light, 1e-12)));
    }
#endif
#if FEATURE_SHAPES
    // An emitting shape's surface (all are sampled, when any is): the triangles' pdf over the shapes' area.
    if (h.id >= u_shape_base) {
        w = 1.0;
#if !NO_SHAPE_LIGHTS
        if (prev_pdf > 0.0 && u_num_emit_patches > 0)
            w = light_weight(prev_pdf, h.t * h.t / (u_emit_patch_area * max(-dot(d, ng), 1e-12)));
#endif
    }
#endif
    return w;
}

// … and for the environment image met along d (1 where it is not sampled).
float environment_weight(vec3 d, float prev_pdf) {
#if READS_ENVIRONMENT_SAMPLING
    if (prev_pdf > 0.0) return light_weight(prev_pdf, env_pdf(d));
#endif
    return 1.0;
}

// A sample's radiance as it reaches the pixel: NaN, infinity or a negative value (a float
// accident, never light) counts as 0, so no such value reaches an image.
vec3 valid_radiance(vec3 c) {
    return all(lessThan(abs(c), vec3(BIG))) ? max(c, vec3(0.0)) : vec3(0.0);
}

#if FEATURE_PBR
// Whether shadow ray q's blocker h lets light through (alpha, a culled back face: pbr_passes; the
// blend's coin tossed per blocker, as a path would meet it): then q becomes the ray going on from it.
bool shadow_passes(inout Query q, Hit h) {
    Surface s = surface_at(q.o, q.d, h);
    vec3 ng = s.n;
#if FEATURE_TRIANGLES
    ng = s.ng;
#endif
    if (!pbr_passes(s.mat, h.id, s.p, s.n, dot(q.d, ng) < 0.0, rnd())) return false;
    int skip, far_id;
    exclusion(h.id, s.n, q.d, skip, far_id);
    q = Query(s.p, q.d, skip, far_id, q.t_max - h.t, false);
    return true;
}

// Whether the path's ray q passes surface s of its hit h (record r): alpha mask below the cutoff,
// blend with probability 1 − alpha, a culled back face; then q becomes the ray going on unchanged.
bool path_passes(inout Query q, Hit h, Surface s, SurfaceRecord r) {
    if (!pbr_passes(s.mat, h.id, s.p, s.n, r.front, rnd())) return false;
    int skip, far_id;
    exclusion(h.id, s.n, q.d, skip, far_id);
    q = Query(s.p, q.d, skip, far_id, BIG, false);
    return true;
}
#endif

// The path integrator: u_sample_count samples of this pixel, each a path from the camera; at every
// vertex its emission (MIS-weighted), next-event estimation (sample_light, one shadow ray per
// iteration), then a direction from the BSDF and Russian roulette. One intersect_scene serves every
// ray (camera, bounce, shadow), so the loop is a small state machine.
void path_main() {
    g_pixel_seed = hash_u(uint(gl_FragCoord.x) ^ hash_u(uint(gl_FragCoord.y) + 0x632be5abu));
    vec3 sum = vec3(0.0);
    float primary_t = -1.0;
    int primary_id = NO_PRIM;
    vec3 primary_n = vec3(0.0);
#if GUIDES
    vec3 albedo_sum = vec3(0.0), normal_sum = vec3(0.0);
#endif
    int done = 0;            // samples of this pass finished
    bool start = true;       // the next iteration begins sample u_sample_start + done
    vec3 L = vec3(0.0);      // the sample's radiance so far
    vec3 beta = vec3(1.0);   // its path throughput
    int segments = 0;        // segments of the path traced so far (the camera's is 1)
    vec3 o = vec3(0.0), d = vec3(0.0);
    Query q;
    SurfaceRecord r;         // the current vertex
    bool vertex = false;     // the path stands on r and may go on from it
    int nee_kind = NEE_DONE, nee_index = 0;   // the vertex's next light sample (sample_light)
    vec3 contrib = vec3(0.0);                 // … and what its shadow ray in flight adds if unblocked
    vec3 prev_p = vec3(0.0);  // the vertex the current segment left, and bsdf_sample's pdf there
    float prev_pdf = 0.0;
#if FEATURE_PBR
    bool shadow = false;      // the ray in flight is a shadow ray (SHADOW_ANY_HIT is false)
#define IS_SHADOW shadow
#define SHADOW_STARTS shadow = true
#else
#define IS_SHADOW q.any_hit
#define SHADOW_STARTS
#endif
#if FEATURE_TEXTURES
    float cone_w = 0.0, cone_spread = 0.0;   // the ray cone at the segment's origin (shaders/ray_cones.glsl)
#endif
    while (true) {
        if (start) {
            camera_ray(uint(u_sample_start + done), gl_FragCoord.xy, o, d);
            L = vec3(0.0); beta = vec3(1.0); segments = 1; prev_pdf = 0.0;
#if FEATURE_TEXTURES
            cone_w = 0.0; cone_spread = cone_pixel_spread(1.0);
#endif
            q = Query(o, d, NO_PRIM, NO_PRIM, BIG, false);
            start = false;
        }
        Hit h = intersect_scene(q);
#if FEATURE_PBR
        if (shadow && h.id != NO_PRIM && shadow_passes(q, h)) continue;
#endif
        if (IS_SHADOW) {
            if (h.id == NO_PRIM) L += contrib;   // the light is visible
            if (nee_kind <= NEE_SPHERES) nee_index++;
#if FEATURE_PBR
            shadow = false;
#endif
        } else if (h.id == NO_PRIM) {
            L += environment_weight(d, prev_pdf) * beta * ENV_RADIANCE_AT(d);
#if GUIDES
            if (segments == 1) albedo_sum += clamp(ENV_RADIANCE_AT(d), 0.0, 1.0);
#endif
            vertex = false;
        } else {
            Surface s = surface_at(o, d, h);
#if FEATURE_TEXTURES
            cone_w += cone_spread * h.t;
            g_cone_width = cone_footprint(cone_w, d, s.ng);   // pbr_inputs' cone_width
#endif
            vec3 ng = s.n;
#if FEATURE_TRIANGLES
            ng = s.ng;   // emission and the side a path meets: by the geometric normal
#endif
            r = surface_record(s.p, s.n, ng, -d, h.id, s.mat);
#if FEATURE_PBR
            if (path_passes(q, h, s, r)) { o = q.o; continue; }   // no vertex, no segment counted
            if (!r.front && r.kind == KIND_PBR) beta *= pbr_attenuation(s.mat, h.t);   // Beer–Lambert
#endif
            if (segments == 1 && done == 0) {   // the pass's first sample gives primid, normal, depth
                primary_t = h.t; primary_id = h.id; primary_n = s.n;
            }
            if (r.front) L += emission_weight(h, ng, d, prev_p, prev_pdf) * beta * emission_at(s.mat);
#if GUIDES
            if (segments == 1) { albedo_sum += bsdf_albedo(r); normal_sum += s.n; }
#endif
            vertex = segments < MAX_RECURSION_DEPTH;   // a next segment (shadow or bounce) fits
            nee_kind = bsdf_is_non_specular(r) ? NEE_POINT : NEE_DONE;
            nee_index = 0;
        }
        if (vertex && nee_kind != NEE_DONE && sample_light(r, beta, nee_kind, nee_index, q, contrib)) {
            SHADOW_STARTS;
            continue;
        }
        if (vertex) {
            vertex = false;
            float uc = rnd();
            float u1 = rnd(), u2 = rnd();
            BsdfSample bs = bsdf_sample(r, uc, vec2(u1, u2));
            prev_p = r.p;
            prev_pdf = bs.pdf;
            bool go = bs.valid;
            if (go) beta *= bs.weight;
#if FEATURE_TEXTURES
            cone_spread = cone_after_bounce(cone_spread, bs.pdf, (bs.lobe & LOBE_SPECULAR) != 0);
#endif
            // Russian roulette from the fourth segment on: survive with p, weight 1/p (unbiased).
            if (go && segments >= 3) {
                float p = min(max(beta.r, max(beta.g, beta.b)), 0.95);
                if (rnd() >= p) go = false;
                else beta /= p;
            }
            if (go) {
                int skip, far_id;
                exclusion(r.prim, r.n, bs.wi, skip, far_id);
                o = r.p;
                d = bs.wi;
                segments++;
                q = Query(o, d, skip, far_id, BIG, false);
                continue;
            }
        }
        // The path has ended (missed, absorbed, out of segments or of roulette): the next sample.
        sum += valid_radiance(L);
        done++;
        if (done >= u_sample_count) break;
        start = true;
    }
    o_image = vec4(sum, float(primary_id));
    o_hit = vec4(primary_n, primary_t);
#if GUIDES
    o_albedo = vec4(albedo_sum, 0.0);
    o_normal = vec4(normal_sum, 0.0);
#endif
}
#endif
