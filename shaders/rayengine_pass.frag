// Ray engine: the full-screen passes of one generation (one per define).
// PASS_PRIMARY  camera rays of the W×H image (texels beyond it: no ray)
// PASS_MASK     nothing drawn; the host counts and stencil-marks live rays
// PASS_SURFACE  hit point, outward normal and facing side of each hit
// PASS_SHADE    Whitted/Phong local colour of each hit (weighted, blended
//               additively into the frame) and its reflected and transmitted
//               rays (the next generation's two layers); raytrace.frag's
//               formulas, docs/SHADING.md.
uniform highp sampler2D u_ray_o;
uniform highp sampler2D u_ray_d;
uniform highp sampler2D u_hit;
uniform highp sampler2D u_surf0;
uniform highp sampler2D u_surf1;
uniform highp sampler2D u_blocked0;    // lights 0–3 (channel = light % 4): 1 = shadowed
uniform highp sampler2D u_blocked1;    // lights 4–7

// The camera (u_cam_*, u_half_extent, u_resolution = the image's W × H; the target
// may be padded) and u_min_weight are declared in the header (renderer/gpu/gpu_layout.py).
uniform int u_level;                   // generation of these rays (primary = 1)
uniform int u_max_level;               // recursion depth traced
uniform int u_shade;                   // 1: colour (lights); 0: only the next rays

#if PASS_SURFACE
layout(location = 0) out vec4 o_surf0;
layout(location = 1) out vec4 o_surf1;
#elif PASS_SHADE
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_refl_o;
layout(location = 2) out vec4 o_refl_d;
layout(location = 3) out vec4 o_trans_o;
layout(location = 4) out vec4 o_trans_d;
#elif PASS_PRIMARY
layout(location = 0) out vec4 o_ray_o;
layout(location = 1) out vec4 o_ray_d;
#else
out vec4 o_out;
#endif

struct Material {
    vec3 color;
    float ambient, diffuse, specular, shininess, reflective, transmissive, ior;
};

// Texel k of material m's record, read by the header's accessors material_<name>(m) (renderer/materials).
#define MATERIAL_TEXEL(m, k) texelFetch(u_materials, texel((m) * MATERIAL_TEXELS + (k), shift), 0)
Material fetch_material(int m) {
    int shift = row_shift(textureSize(u_materials, 0));
    return Material(material_color(m), material_ambient(m), material_diffuse(m), material_specular(m),
                    material_shininess(m), material_reflective(m), material_transmissive(m), material_ior(m));
}

int material_of(int id) {
    if (id < u_num_spheres)
        return int(texelFetch(u_sphere_mat, texel(id, row_shift(textureSize(u_spheres, 0))), 0).x);
    return u_plane_mat[id - u_num_spheres];
}

bool blocked(ivec2 px, int light) {
    vec4 b = light < 4 ? texelFetch(u_blocked0, px, 0) : texelFetch(u_blocked1, px, 0);
    int c = light - 4 * (light / 4);
    return (c == 0 ? b.x : c == 1 ? b.y : c == 2 ? b.z : b.w) > 0.0;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
#if PASS_PRIMARY
    // raytrace.frag's camera ray; gl_FragCoord.y grows upwards, image row 0 is the top row
    float fx = gl_FragCoord.x;
    float row = u_resolution.y - gl_FragCoord.y;
    float u = (2.0 * fx / u_resolution.x - 1.0) * u_half_extent.x;
    float v = (1.0 - 2.0 * row / u_resolution.y) * u_half_extent.y;
    vec3 dir = normalize(u_cam_forward + u * u_cam_right + v * u_cam_up);
    bool inside = gl_FragCoord.x < u_resolution.x && gl_FragCoord.y < u_resolution.y;
    o_ray_o = vec4(u_cam_pos, -1.0);
    o_ray_d = vec4(dir, inside ? 1.0 : 0.0);
#elif PASS_MASK
    if (texelFetch(u_ray_d, px, 0).w <= 0.0) discard;
    o_out = vec4(0.0);
#else
    vec4 rd = texelFetch(u_ray_d, px, 0);
    if (rd.w <= 0.0) discard;
    vec4 h = texelFetch(u_hit, px, 0);
    int id = int(h.y);
    if (id < 0) discard;
    vec4 ro = texelFetch(u_ray_o, px, 0);
    vec3 o = ro.xyz, d = rd.xyz;
    float weight = rd.w;
#if PASS_SURFACE
    vec3 p = o + h.x * d;
    vec3 n;
    if (id < u_num_spheres) {
        // (p − c)/r formed as ((o − c) + t d)/r: the same vector, but it keeps its
        // direction when p and c round to the same float32 (radius far below the
        // spacing of the coordinates, e.g. 1e-3 at 1e6)
        vec4 sp = fetch_sphere(id);
        n = normalize(((o - sp.xyz) + h.x * d) / sp.w);
    } else {
        n = normalize(u_plane_normal[id - u_num_spheres]);
    }
    o_surf0 = vec4(p, float(id));
    o_surf1 = vec4(n, dot(d, n) < 0.0 ? 1.0 : -1.0);
#else   // PASS_SHADE
    vec4 s0 = texelFetch(u_surf0, px, 0);
    vec4 s1 = texelFetch(u_surf1, px, 0);
    vec3 p = s0.xyz, n = s1.xyz, nf = s1.w * n;
    Material m = fetch_material(material_of(id));
    vec3 color = vec3(0.0);
    if (u_shade == 1) {
        color += weight * m.ambient * m.color;
        for (int light = 0; light < MAX_LIGHTS; light++) {
            if (light >= u_num_lights) break;
            vec3 to_light = u_light_pos[light] - p;
            float dist = length(to_light);
            vec3 l = to_light / dist;
            float cos_l = dot(nf, l);
            if (cos_l > 0.0 && !blocked(px, light)) {
                vec3 r = 2.0 * cos_l * nf - l;
                float x = dot(r, -d);
                float spec = x > 0.0 ? pow(x, m.shininess) : 0.0;
                color += weight * u_light_color[light] * (m.diffuse * cos_l * m.color + m.specular * spec);
            }
        }
    }
    o_color = vec4(color, 0.0);
    o_refl_o = vec4(0.0); o_refl_d = vec4(0.0); o_trans_o = vec4(0.0); o_trans_d = vec4(0.0);
    if (u_level < u_max_level) {
        if (m.reflective > 0.0 && weight * m.reflective >= u_min_weight) {
            vec3 r = d - 2.0 * dot(d, n) * n;
            o_refl_o = vec4(p, encode_code(id, n, r));
            o_refl_d = vec4(r, weight * m.reflective);
        }
        if (m.transmissive > 0.0 && weight * m.transmissive >= u_min_weight) {
            bool entering = dot(d, n) < 0.0;
            float eta = entering ? 1.0 / m.ior : m.ior;
            vec3 nn = entering ? n : -n;
            float cos_i = -dot(d, nn);
            float kk = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            vec3 t_dir = kk < 0.0 ? d - 2.0 * dot(d, nn) * nn      // total internal reflection
                                  : normalize(eta * d + (eta * cos_i - sqrt(kk)) * nn);
            o_trans_o = vec4(p, encode_code(id, n, t_dir));
            o_trans_d = vec4(t_dir, weight * m.transmissive);
        }
    }
#endif
#endif
}
