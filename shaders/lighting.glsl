// Emission, the environment and the path integrator (docs/SHADING.md): one whole chunk that
// raytrace.frag includes and compiles where FEATURE_LIGHTING is 1 (a variant that carries
// EMISSION, ENVIRONMENT or PATH: renderer/shader_source.py); raytrace.frag's main calls
// path_main where PATH is defined, and its Whitted loop adds emission and the environment. The
// TRIANGLES and SHAPES mark lines inside path_main are the last marks (a legacy the
// assembler fills from shaders/path_legacy.glsl).

#ifdef READS_EMISSION
int g_emission_shift;
// The radiance material m emits on the side its surface's normal faces.
vec3 emission_at(int m) { return texelFetch(u_emission, texel(m, g_emission_shift), 0).rgb; }
#define EMISSION_INIT() g_emission_shift = row_shift(textureSize(u_emission, 0))
#else
vec3 emission_at(int m) { return vec3(0.0); }
#define EMISSION_INIT()
#endif
#ifdef READS_ENVIRONMENT
#define ENV_RADIANCE u_environment
#else
#define ENV_RADIANCE vec3(0.0)
#endif
#ifdef READS_ENVIRONMENT_MAP
// An equirectangular environment image (docs/FORMATS.md, "Environment"; renderer/envmap.py, whose
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
#ifdef READS_ENVIRONMENT_SAMPLING
// Importance sampling of the image (renderer/envmap.py): a patch row from the marginal CDF, a patch
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

#ifdef PATH
// ---- the path integrator (docs/SHADING.md, "Path integrator") ----------------------------
const float PI = 3.14159265358979;
// What the scene lacks is not compiled in (renderer/features.py, PATH_REMOVALS): every lane runs
// all of the loop's code, used or not. The host names a removal only where it says something; the
// rest follow here: no rough lobe where nothing reflects or transmits, no light kind where nothing emits.
#if defined(NO_REFLECTION) && defined(NO_TRANSMISSION) && !defined(NO_ROUGHNESS)
#define NO_ROUGHNESS
#endif
#ifndef READS_EMISSION
#define NO_SPHERE_LIGHTS
#define NO_TRIANGLE_LIGHTS
#define NO_SHAPE_LIGHTS
#endif
#ifdef GUIDES
// The denoiser's guides (renderer/denoise.py), sums over the pass's samples: the first hit's albedo
// as its lobes reflect (w_d · colour + w_r + w_t; a miss: the environment clamped to [0, 1]) and
// its outward normal (a miss: 0).
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

// The GGX α of material m's reflective and transmissive lobes (the third texel's z; Whitted's Material
// has no use for it). 0 where no material is rough: the GGX code then folds away.
float roughness_at(int m) {
#if defined(NO_ROUGHNESS)
    return 0.0;
#elif defined(MATERIAL_TEXTURE)
    return texelFetch(u_materials, texel(m * MATERIAL_TEXELS + 2, g_mat_shift), 0).z;
#else
    return u_material_vecs[m * MATERIAL_TEXELS + 2].z;
#endif
}

// An orthonormal basis around unit n (Duff et al. 2017).
void basis(vec3 n, out vec3 t, out vec3 b) {
    float sgn = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + sgn * n.x * n.x * a, sgn * c, -sgn * n.x);
    b = vec3(c, sgn + n.y * n.y * a, -n.y);
}

vec3 cosine_direction(vec3 n, float u1, float u2) {
    float r = sqrt(u1);
    float phi = 2.0 * PI * u2;
    vec3 t, b;
    basis(n, t, b);
    return normalize(r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0.0, 1.0 - u1)) * n);
}

#ifndef NO_SHAPE_LIGHTS
// A point uniform in area on emitting surface k (u_emit_patch_*, renderer/gpu_layout.py
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

// Smith's masking of GGX (α) for a direction at cos θ = c to the normal.
float smith_g1(float c, float alpha) {
    float c2 = c * c;
    float tan2 = max(0.0, 1.0 - c2) / max(c2, 1e-12);
    return 2.0 / (1.0 + sqrt(1.0 + alpha * alpha * tan2));
}

// A GGX (α) microfacet normal drawn from the normals visible from wo about n (Heitz 2018,
// "Sampling the GGX Distribution of Visible Normals"): density D_wo(m) = G1(wo) max(0, wo·m) D(m) / (n·wo).
// Against the full distribution D(m) cos θm, the weights of the lobes that use it are bounded
// (G1 of the new direction) instead of growing as (wo·m) / (n·m) for the rare m far from n.
vec3 ggx_visible_normal(vec3 n, vec3 wo, float a, float u1, float u2) {
    vec3 t, b;
    basis(n, t, b);
    vec3 vh = normalize(vec3(a * dot(wo, t), a * dot(wo, b), dot(n, wo)));   // wo, stretched to α = 1
    float len2 = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = len2 > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u1), phi = 2.0 * PI * u2;
    float p1 = r * cos(phi), p2 = r * sin(phi);
    float sv = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - sv) * sqrt(max(0.0, 1.0 - p1 * p1)) + sv * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    vec3 ml = normalize(vec3(a * nh.x, a * nh.y, max(nh.z, 0.0)));
    return ml.x * t + ml.y * b + ml.z * n;
}

// The GGX lobe (α, F = 1, separable Smith masking) for wo → wi about n: (f, pdf per steradian of its
// sampling, D_wo(m) / (4 o·m) = G1(wo) D(m) / (4 n·o), the visible normals); (0, 0) below either horizon.
vec2 ggx_eval(vec3 n, vec3 wo, vec3 wi, float alpha) {
    float n_o = dot(n, wo), n_i = dot(n, wi);
    if (n_o <= 0.0 || n_i <= 0.0) return vec2(0.0);
    vec3 mh = normalize(wo + wi);
    float n_m = dot(n, mh), o_m = dot(wo, mh);
    if (n_m <= 0.0 || o_m <= 0.0) return vec2(0.0);
    float a2 = alpha * alpha;
    float k = n_m * n_m * (a2 - 1.0) + 1.0;
    float dm = a2 / (PI * k * k);
    float f = dm * smith_g1(n_o, alpha) * smith_g1(n_i, alpha) / (4.0 * n_o * n_i);
    return vec2(f, dm * smith_g1(n_o, alpha) / (4.0 * n_o));
}
// The lobes next-event estimation lights, the diffuse and the GGX one together, for wo → wi about nf:
// (f, the pdf with which BSDF sampling chooses wi — each lobe with its weight's probability). The
// smooth mirror and glass are deltas: no light sample can meet them.
vec4 lobes_eval(vec3 nf, vec3 wo, vec3 wi, float w_d, vec3 albedo, float w_r, float alpha) {
    vec3 f = (w_d / PI) * albedo;
    float pdf = w_d * max(dot(nf, wi), 0.0) / PI;
    if (w_r > 0.0 && alpha > 0.0) {
        vec2 g = ggx_eval(nf, wo, wi, alpha);
        f += vec3(w_r * g.x);
        pdf += w_r * g.y;
    }
    return vec4(f, pdf);
}

// Fresnel reflectance of a smooth dielectric: cos_i > 0 the incident cosine, eta = n_i / n_t.
float fresnel_dielectric(float cos_i, float eta) {
    float sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return 1.0;   // total internal reflection
    float cos_t = sqrt(1.0 - sin2_t);
    float rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// A sample's radiance as it reaches the pixel: NaN, infinity or a negative value (a float
// accident, never light) counts as 0, so no such value reaches an image.
vec3 valid_radiance(vec3 c) {
    return all(lessThan(abs(c), vec3(BIG))) ? max(c, vec3(0.0)) : vec3(0.0);
}

void path_main() {
    g_pixel_seed = hash_u(uint(gl_FragCoord.x) ^ hash_u(uint(gl_FragCoord.y) + 0x632be5abu));
    vec3 sum = vec3(0.0);
    float primary_t = -1.0;
    int primary_id = NO_PRIM;
    vec3 primary_n = vec3(0.0);
#ifdef GUIDES
    vec3 albedo_sum = vec3(0.0), normal_sum = vec3(0.0);
#endif

    int done = 0;            // samples of this pass finished
    bool start = true;       // the next iteration begins sample u_sample_start + done
    vec3 L = vec3(0.0);      // the sample's radiance so far
    vec3 beta = vec3(1.0);   // its path throughput
    int segments = 0;        // segments of the path traced so far (the camera's is 1)
    int light = 0;           // the next point light to try at the current vertex
    vec3 o = vec3(0.0), d = vec3(0.0);
    int skip = NO_PRIM, far_id = NO_PRIM;
    Query q;
    Hit h;
    Surface s;
    Material m;
    vec3 nf = vec3(0.0);
    float w_diffuse = 0.0, w_reflect = 0.0, w_transmit = 0.0;   // the vertex's lobe weights, summing ≤ 1
    vec3 contrib = vec3(0.0);
    bool vertex = false;     // the path stands on a surface and may go on from it
    bool front = false;      // … on the side its normal faces
    float roughness = 0.0;
    int emitter = 0;             // the next emitting sphere to sample at the current vertex
    int shadow_kind = 0;         // the shadow ray in flight: 0 a point light's, 1 a sphere's, 2 a triangle's
    bool tri_done = false;       // the vertex's emitting-triangle sample is taken
    bool patch_done = false;     // … and its emitting-shape sample (shadow kind 4)
#ifdef READS_ENVIRONMENT_SAMPLING
    bool env_done = false;       // … and its environment-image sample (shadow kind 3)
#endif
    vec3 prev_p = vec3(0.0);     // the vertex the current segment left, and the pdf (solid angle) with
    float prev_pdf = 0.0;        // which its diffuse and GGX lobes together chose it (0: a smooth lobe, the camera)
    bool lit = false;            // the vertex has a lobe that next-event estimation lights (diffuse, GGX)
    while (true) {
        if (start) {
            uint i = uint(u_sample_start + done);
            g_sample_seed = hash_u(i ^ 0x27d4eb2fu);
            g_dim = 0u;
            vec2 j = pixel_jitter(i);
            // The pixel's box: its lower-left corner (in rows from the top) plus the jitter.
            float px = floor(gl_FragCoord.x) + j.x;
            float row = u_resolution.y - (floor(gl_FragCoord.y) + j.y);
            float u = (2.0 * px / u_resolution.x - 1.0) * u_half_extent.x;
            float v = (1.0 - 2.0 * row / u_resolution.y) * u_half_extent.y;
            o = u_cam_pos;
            d = normalize(u_cam_forward + u * u_cam_right + v * u_cam_up);
            skip = NO_PRIM; far_id = NO_PRIM;
            L = vec3(0.0); beta = vec3(1.0); segments = 1; prev_pdf = 0.0;
            q = Query(o, d, skip, far_id, BIG, false);
            start = false;
        }
        Hit hq = intersect_scene(q);
        if (q.any_hit) {
            if (hq.id == NO_PRIM) L += contrib;   // the light is visible
            if (shadow_kind == 0) light++;
            else if (shadow_kind == 1) emitter++;
            else tri_done = true;
        } else if (hq.id == NO_PRIM) {
#ifdef READS_ENVIRONMENT_SAMPLING
            // The image is sampled by next-event estimation too: the power heuristic's weight of
            // BSDF sampling where the diffuse or the GGX lobe chose the direction.
            float w_env = 1.0;
            if (prev_pdf > 0.0) {
                float p_l = env_pdf(d);
                w_env = prev_pdf * prev_pdf / (prev_pdf * prev_pdf + p_l * p_l);
            }
            L += w_env * beta * ENV_RADIANCE_AT(d);
#else
            L += beta * ENV_RADIANCE_AT(d);
#endif
#ifdef GUIDES
            if (segments == 1) albedo_sum += clamp(ENV_RADIANCE_AT(d), 0.0, 1.0);
#endif
            vertex = false;
        } else {
            h = hq;
            s = surface_at(o, d, h);
            vec3 ng = s.n;
//@TRIANGLES path_ng
            if (segments == 1 && done == 0) {   // the pass's first sample gives primid, normal, depth
                primary_t = h.t; primary_id = h.id; primary_n = s.n;
            }
            m = material_at(s.mat);
            roughness = roughness_at(s.mat);
            front = dot(d, ng) < 0.0;
            nf = front ? s.n : -s.n;
            if (front) {
                // An emitting sphere that next-event estimation samples too: the power heuristic's weight
                // of BSDF sampling (its diffuse and GGX lobes' pdf against the sphere's cone); every other
                // emitter (planes, triangles, spheres past the sampled ones) is met by BSDF sampling alone.
                float w = 1.0;
#ifndef NO_SPHERE_LIGHTS
                if (prev_pdf > 0.0 && h.id < u_num_spheres && h.id <= u_emitter_last) {
                    vec3 to_c = h.sphere.xyz - prev_p;
                    float sin2 = h.sphere.w * h.sphere.w / dot(to_c, to_c);
                    if (sin2 < 1.0) {
                        float p_l = 1.0 / (2.0 * PI * (sin2 / (1.0 + sqrt(1.0 - sin2))));
                        w = prev_pdf * prev_pdf / (prev_pdf * prev_pdf + p_l * p_l);
                    }
                }
#endif
//@TRIANGLES path_emit_mis
//@SHAPES path_emit_mis
                L += w * beta * emission_at(s.mat);
            }
            // Lobe weights: diffuse, reflective, transmissive; scaled to sum 1 where they exceed it.
            w_diffuse = m.diffuse; w_reflect = 0.0; w_transmit = 0.0;
#ifndef NO_REFLECTION
            w_reflect = m.reflective;
#endif
#ifndef NO_TRANSMISSION
            w_transmit = m.transmissive;
#endif
            float total = w_diffuse + w_reflect + w_transmit;
            if (total > 1.0) { w_diffuse /= total; w_reflect /= total; w_transmit /= total; }
#ifdef GUIDES
            if (segments == 1) {
                albedo_sum += w_diffuse * m.color + vec3(w_reflect + w_transmit);
                normal_sum += s.n;
            }
#endif
            light = 0;
            emitter = 0;
            tri_done = false;
            patch_done = false;
#ifdef READS_ENVIRONMENT_SAMPLING
            env_done = false;
#endif
            vertex = segments < MAX_RECURSION_DEPTH;   // a next segment (shadow or bounce) fits
            lit = w_diffuse > 0.0 || (w_reflect > 0.0 && roughness > 0.0);
        }
#ifdef SHADOW_RAYS
        // Next-event estimation: the next point light, lighting the diffuse and GGX lobes (a delta light: no MIS).
        if (vertex && lit) {
            bool shadow = false;
            for (; light < LIGHT_LOOP; light++) {
                if (LIGHTS_END(light)) break;
                vec3 to_light = u_light_pos[light] - s.p;
                float dist2 = dot(to_light, to_light);
                float dist = sqrt(dist2);
                vec3 l = to_light / dist;
                float cos_l = dot(nf, l);
                if (cos_l > 0.0 && dist > 0.0) {
                    // f = w_d · color / π, intensity I = color_light · u_light_scale, E = I cos / r².
                    vec3 f = lobes_eval(nf, -d, l, w_diffuse, m.color, w_reflect, roughness).rgb;
                    contrib = beta * f * u_light_color[light] * (u_light_scale * cos_l / dist2);
                    int sk, fa;
                    exclusion(h.id, s.n, l, sk, fa);
                    q = Query(s.p, l, sk, fa, dist, true);
                    shadow = true;
                    break;
                }
            }
            shadow_kind = 0;
            if (shadow) continue;
        }
#endif
#ifndef NO_SPHERE_LIGHTS
        // Next-event estimation to the emitting spheres: a direction in the cone the sphere fills
        // (uniform in solid angle), weighted by the power heuristic against BSDF sampling.
        if (vertex && lit) {
            bool shadow = false;
            for (; emitter < MAX_SAMPLED_SPHERES; emitter++) {
                if (emitter >= u_num_emitters) break;
                vec4 e = u_emitter_sphere[emitter];
                vec3 to_c = e.xyz - s.p;
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
                float cos_l = dot(nf, l);
                float te = intersect_sphere(s.p, l, e, false);
                if (cos_l <= 0.0 || te >= BIG) continue;
                float p_l = 1.0 / (2.0 * PI * cone);
                vec4 fl = lobes_eval(nf, -d, l, w_diffuse, m.color, w_reflect, roughness);
                float w = p_l * p_l / (p_l * p_l + fl.w * fl.w);
                contrib = beta * fl.rgb * u_emitter_radiance[emitter] * (cos_l * w / p_l);
                int sk, fa;
                exclusion(h.id, s.n, l, sk, fa);
                q = Query(s.p, l, sk, fa, te * (1.0 - 1e-4), true);   // blockers before the sphere
                shadow = true;
                break;
            }
            shadow_kind = 1;
            if (shadow) continue;
        }
#endif
        // … and to the emitting triangles: one, picked with probability ∝ its area, a point uniform on it
        // (pdf in solid angle dist² / (A cos θ_light), A their total area), the power heuristic again.
#ifndef NO_TRIANGLE_LIGHTS
        if (vertex && lit && !tri_done && u_num_emit_tris > 0) {
            float pick = rnd(), b1 = rnd(), b2 = rnd();
            tri_done = true;
            int k = 0;
            for (int i = 0; i < MAX_SAMPLED_TRIANGLES; i++) {
                if (i >= u_num_emit_tris || pick < u_emit_tri_cdf[i]) break;
                k = i + 1;
            }
            k = min(k, u_num_emit_tris - 1);
            float su = sqrt(b1);
            vec3 e1 = u_emit_tri_e1[k], e2 = u_emit_tri_e2[k];
            vec3 x = u_emit_tri_v0[k] + su * (1.0 - b2) * e1 + su * b2 * e2;   // uniform in the triangle
            vec3 to_x = x - s.p;
            float dist2 = dot(to_x, to_x);
            float dist = sqrt(dist2);
            vec3 l = to_x / dist;
            vec3 ng_l = normalize(cross(e1, e2));
            float cos_light = -dot(l, ng_l);             // > 0: the side its winding faces, which emits
            float cos_l = dot(nf, l);
            if (dist > 0.0 && cos_light > 0.0 && cos_l > 0.0) {
                float p_l = dist2 / (u_emit_tri_area * cos_light);
                vec4 fl = lobes_eval(nf, -d, l, w_diffuse, m.color, w_reflect, roughness);
                float w = p_l * p_l / (p_l * p_l + fl.w * fl.w);
                contrib = beta * fl.rgb * u_emit_tri_radiance[k] * (cos_l * w / p_l);
                int sk, fa;
                exclusion(h.id, s.n, l, sk, fa);
                q = Query(s.p, l, sk, fa, dist * (1.0 - 1e-4), true);
                shadow_kind = 2;
                continue;
            }
        }
#endif
#ifndef NO_SHAPE_LIGHTS
        // … and to the emitting analytic shapes: one of their surfaces (a side, a cap, a disk, a torus),
        // picked with probability ∝ its area, a point uniform on it: the same pdf as the triangles'.
        if (vertex && lit && !patch_done && u_num_emit_patches > 0) {
            float pick = rnd(), u1 = rnd(), u2 = rnd();
            patch_done = true;
            int k = 0;
            for (int i = 0; i < MAX_SAMPLED_SHAPE_PATCHES; i++) {
                if (i >= u_num_emit_patches || pick < u_emit_patch_cdf[i]) break;
                k = i + 1;
            }
            k = min(k, u_num_emit_patches - 1);
            vec3 ng_l;
            vec3 to_x = patch_point(k, u1, u2, ng_l) - s.p;
            float dist2 = dot(to_x, to_x);
            float dist = sqrt(dist2);
            vec3 l = to_x / dist;
            float cos_light = -dot(l, ng_l);             // > 0: the side its normal faces, which emits
            float cos_l = dot(nf, l);
            if (dist > 0.0 && cos_light > 0.0 && cos_l > 0.0) {
                float p_l = dist2 / (u_emit_patch_area * cos_light);
                vec4 fl = lobes_eval(nf, -d, l, w_diffuse, m.color, w_reflect, roughness);
                float w = p_l * p_l / (p_l * p_l + fl.w * fl.w);
                contrib = beta * fl.rgb * u_emit_patch_radiance[k] * (cos_l * w / p_l);
                int sk, fa;
                exclusion(h.id, s.n, l, sk, fa);
                q = Query(s.p, l, sk, fa, dist * (1.0 - 1e-4), true);
                shadow_kind = 4;
                continue;
            }
        }
#endif
#ifdef READS_ENVIRONMENT_SAMPLING
        // … and to the environment image: one direction from its importance sampling, lighting the
        // diffuse and the GGX lobe, the power heuristic against their sampling together (a bright
        // sun seen in a rough metal is found this way), a shadow ray to infinity.
        if (vertex && lit && !env_done) {
            env_done = true;
            float u1 = rnd(), u2 = rnd();
            float p_l;
            vec3 l = env_sample(u1, u2, p_l);
            float cos_l = dot(nf, l);
            if (p_l > 0.0 && cos_l > 0.0) {
                vec4 fl = lobes_eval(nf, -d, l, w_diffuse, m.color, w_reflect, roughness);
                float w = p_l * p_l / (p_l * p_l + fl.w * fl.w);
                contrib = beta * fl.rgb * ENV_RADIANCE_AT(l) * (cos_l * w / p_l);
                int sk, fa;
                exclusion(h.id, s.n, l, sk, fa);
                q = Query(s.p, l, sk, fa, BIG, true);
                shadow_kind = 3;
                continue;
            }
        }
#endif
        if (vertex) {
            // BSDF sampling: one lobe, chosen with its weight's probability (none: absorbed).
            float pick = rnd();
            float u1 = rnd(), u2 = rnd();
            vec3 nd = vec3(0.0);
            bool go = true;
            prev_pdf = 0.0;
            prev_p = s.p;
            if (pick < w_diffuse) {
                nd = cosine_direction(nf, u1, u2);
                beta *= m.color;
            } else if (pick < w_diffuse + w_reflect) {
                if (roughness > 0.0) {
                    // GGX (α = roughness), F = 1: a microfacet normal from the normals visible from wo
                    // (Heitz 2018), reflection about it; D and G1(wo) cancel against the density, so the
                    // weight is G1 of the new direction, never above 1 (Mitsuba's roughconductor with
                    // sample_visible).
                    float a = roughness;
                    vec3 wo = -d;
                    vec3 mh = ggx_visible_normal(nf, wo, a, u1, u2);
                    float o_m = dot(wo, mh);
                    nd = 2.0 * o_m * mh - wo;
                    float n_o = dot(nf, wo), n_i = dot(nf, nd);
                    if (o_m <= 0.0 || n_i <= 0.0 || n_o <= 0.0) go = false;
                    else beta *= smith_g1(n_i, a);
                } else {
                    nd = d - 2.0 * dot(d, s.n) * s.n;
                }
            } else if (pick < w_diffuse + w_reflect + w_transmit) {
                bool entering = front;
                float eta = entering ? 1.0 / m.ior : m.ior;
                vec3 nn = entering ? s.n : -s.n;
                if (roughness > 0.0) {
                    // A rough dielectric (Walter et al. 2007), GGX of α = roughness as the reflective lobe's: a
                    // microfacet normal m from the normals visible from wo (Heitz 2018), reflection about it
                    // with the Fresnel probability F(wo·m), else refraction through it. F and 1 − F cancel
                    // against their probabilities, D and G1(wo) against the density: the weight is G1 of the
                    // new direction nd, never above 1 (Mitsuba's roughdielectric with sample_visible). A
                    // direction on the wrong side of the surface for its kind (reflected below it, refracted
                    // above it) is masked: the path ends there.
                    float a = roughness;
                    vec3 wo = -d;
                    float n_o = dot(nn, wo);
                    vec3 mh = ggx_visible_normal(nn, wo, a, u1, u2);
                    float o_m = dot(wo, mh);
                    float u3 = rnd();
                    if (o_m <= 0.0 || n_o <= 0.0) {
                        go = false;
                    } else {
                        float k = 1.0 - eta * eta * (1.0 - o_m * o_m);
                        bool reflect_m = k <= 0.0 || u3 < fresnel_dielectric(o_m, eta);
                        nd = reflect_m ? 2.0 * o_m * mh - wo : normalize(eta * d + (eta * o_m - sqrt(max(k, 0.0))) * mh);
                        float n_i = dot(nn, nd);
                        if (reflect_m ? n_i <= 0.0 : n_i >= 0.0) go = false;
                        else beta *= smith_g1(abs(n_i), a);
                    }
                } else {
                    // A smooth dielectric: reflect with Fresnel's probability, else refract.
                    float cos_i = -dot(d, nn);
                    float f = fresnel_dielectric(abs(cos_i), eta);
                    if (u1 < f) {
                        nd = d - 2.0 * dot(d, nn) * nn;
                    } else {
                        float k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                        nd = normalize(eta * d + (eta * cos_i - sqrt(max(k, 0.0))) * nn);
                    }
                }
            } else {
                go = false;
            }
            if (go && (pick < w_diffuse || (pick < w_diffuse + w_reflect && roughness > 0.0)))
                prev_pdf = lobes_eval(nf, -d, nd, w_diffuse, m.color, w_reflect, roughness).w;
            // Russian roulette from the fourth segment on: survive with p, weight 1/p (unbiased).
            if (go && segments >= 3) {
                float p = min(max(beta.r, max(beta.g, beta.b)), 0.95);
                if (rnd() >= p) go = false;
                else beta /= p;
            }
            vertex = false;
            if (go) {
                exclusion(h.id, s.n, nd, skip, far_id);
                o = s.p;
                d = nd;
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
#ifdef GUIDES
    o_albedo = vec4(albedo_sum, 0.0);
    o_normal = vec4(normal_sum, 0.0);
#endif
}
#endif
