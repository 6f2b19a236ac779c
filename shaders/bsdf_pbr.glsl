// The glTF 2.0 metallic-roughness BRDF (the specification's appendix B; docs/SHADING.md, "PBR"):
// a dielectric, the Fresnel mix (Schlick, F0 = ((ior − 1)/(ior + 1))²) of a GGX specular lobe
// (α = roughness², Smith's height-correlated masking-shadowing) over a Lambert diffuse lobe of the
// base colour, KHR_materials_transmission replacing that diffuse share by refraction; a metal, GGX
// with F0 = the base colour; the two mixed by metallic. Whitted's shading (raytrace.frag) and the path
// integrator's sampling (shaders/bsdf_pbr_path.glsl) both evaluate it here; the inputs at a hit come
// from pbr_inputs (shaders/pbr_inputs.glsl). Compiled where the scene has a PBR material (FEATURE_PBR).
const float PBR_PI = 3.14159265358979;
// GGX α below this is a mirror float32 cannot sample (D grows as 1/α²): roughness 0 is traced as α =
// PBR_MIN_ALPHA, a lobe narrower than a pixel's footprint in every scene the service renders.
const float PBR_MIN_ALPHA = 1.0e-3;

float pbr_alpha_of(float roughness) { return max(roughness * roughness, PBR_MIN_ALPHA); }

// The dielectric's reflectance at normal incidence from its index of refraction (KHR_materials_ior).
float pbr_f0_of(float ior) {
    float r = (ior - 1.0) / (ior + 1.0);
    return r * r;
}

// Schlick's weight (1 − c)⁵ of the grazing reflectance: F = F0 + (1 − F0) · this.
float pbr_schlick_weight(float c) {
    float k = 1.0 - clamp(c, 0.0, 1.0);
    float k2 = k * k;
    return k2 * k2 * k;
}

// The dielectric's Fresnel reflectance (Schlick) at cos θ = c; 0 for F0 = 0 (ior 1: no interface, so
// nothing reflects, where Schlick's formula would still give (1 − c)⁵).
float pbr_dielectric_fresnel(float f0, float c) {
    return f0 > 0.0 ? f0 + (1.0 - f0) * pbr_schlick_weight(c) : 0.0;
}

// GGX's distribution of normals D(m) at cos θm = n_m, a2 = α².
float pbr_ggx_d(float n_m, float a2) {
    float k = n_m * n_m * (a2 - 1.0) + 1.0;
    return a2 / (PBR_PI * k * k);
}

// Smith's height-correlated masking-shadowing over the microfacet BRDF's denominator:
// V = G2 / (4 |n·o| |n·i|) (the specification's V_GGX).
float pbr_smith_v(float n_o, float n_i, float a2) {
    float go = n_i * sqrt(n_o * n_o * (1.0 - a2) + a2);
    float gi = n_o * sqrt(n_i * n_i * (1.0 - a2) + a2);
    return 0.5 / max(go + gi, 1e-30);
}

// The specular Fresnel seen at cos θ = c from the normal: the dielectric's Schlick reflectance
// (F0 from ior) where metallic is 0, the base colour's where it is 1 (Whitted's reflected ray and the
// lobe choice of the path integrator weigh by it).
vec3 pbr_fresnel(vec3 base, float metallic, float f0, float c) {
    float s = pbr_schlick_weight(c);
    return mix(vec3(pbr_dielectric_fresnel(f0, c)), base + (1.0 - base) * s, metallic);
}

// The reflective part of the BRDF, f(wo → wi) about unit n (no cosine): (1 − metallic) · [(1 − F(n·wo))
// (1 − transmission) base/π + spec_share · F · D · V] + metallic · F_metal · D · V, F at the half vector
// but the diffuse share's at the view: the specification's (1 − F(wo·h)) lets a white dielectric
// reflect up to 1.5× the light it receives at grazing views (docs/SHADING.md, "PBR").
// The transmissive share is refraction (Whitted: the refracted ray; paths: bsdf_pbr_path.glsl).
// spec_share: the dielectric's specular weight (1 in Whitted's shading; 1 − transmission in the path
// integrator, whose rough dielectric carries the rest).
vec3 pbr_brdf(vec3 base, float metallic, float alpha, float f0, float transmission, float spec_share, vec3 n,
              vec3 wo, vec3 wi) {
    float n_o = dot(n, wo), n_i = dot(n, wi);
    if (n_o <= 0.0 || n_i <= 0.0) return vec3(0.0);
    vec3 h = normalize(wo + wi);
    float s = pbr_schlick_weight(max(dot(wo, h), 0.0));
    float a2 = alpha * alpha;
    float spec = pbr_ggx_d(max(dot(n, h), 0.0), a2) * pbr_smith_v(n_o, n_i, a2);
    float fd = pbr_dielectric_fresnel(f0, dot(wo, h));
    float fv = pbr_dielectric_fresnel(f0, n_o);
    vec3 fm = base + (1.0 - base) * s;
    vec3 dielectric = ((1.0 - fv) * (1.0 - transmission) / PBR_PI) * base + vec3(spec_share * fd * spec);
    return mix(dielectric, fm * spec, metallic);
}

// KHR_materials_volume: the share of light left after a distance t inside material mat
// (Beer–Lambert, attenuation_color after attenuation_distance; distance 0: none).
vec3 pbr_attenuation(int mat, float t) {
    float d = pbr_attenuation_distance(mat);
    if (d <= 0.0) return vec3(1.0);
    return exp(log(max(pbr_attenuation_color(mat), vec3(1e-30))) * (t / d));
}

// Whether a ray goes on through material mat's surface unchanged (docs/SHADING.md, "PBR"): a single-
// sided surface (double_sided false) met from its back (front false: the side its geometric normal
// does not face) is culled, as a rasteriser culls it, unless it transmits (a refracting volume needs
// its inside); alpha mask: coverage below alpha_cutoff; alpha blend: coverage ≤ u (u uniform in [0, 1):
// stochastic coverage; Whitted passes 0.5). n: the surface's shading normal at p of primitive prim.
bool pbr_passes(int mat, int prim, vec3 p, vec3 n, bool front, float u) {
    if (MATERIAL_KIND(mat) != KIND_PBR) return false;
    if (!front && pbr_double_sided(mat) < 0.5 && pbr_transmission(mat) <= 0.0) return true;
    int mode = int(pbr_alpha_mode(mat) + 0.5);
    if (mode == 0) return false;
    float a = pbr_inputs(mat, prim, p, n, g_cone_width).alpha;
    return mode == 1 ? a < pbr_alpha_cutoff(mat) : a <= u;
}
