// The Phong material's BSDF for the path integrator (docs/SHADING.md, "Materials"): a Lambert lobe
// (weight diffuse, albedo color), a reflective lobe (weight reflective: a mirror, or GGX of α =
// roughness with F = 1) and a transmissive one (weight transmissive: smooth glass of index ior, or
// Walter et al.'s rough dielectric), chosen with their weights' probabilities (scaled to sum 1
// where they exceed it). The integrator sees it through the surface record and three functions,
// as pbrt's BxDF: bsdf_eval (f and its pdf), bsdf_sample (a direction, its weight f·cos/pdf, its
// pdf and lobe) and bsdf_pdf. A material kind is one such file (renderer/materials).
#if PATH
const float PI = 3.14159265358979;
// What the scene lacks is not compiled in (renderer/frame/features.py, PATH_REMOVALS): no rough lobe where
// nothing reflects or transmits.
#if NO_REFLECTION && NO_TRANSMISSION && !NO_ROUGHNESS
#undef NO_ROUGHNESS
#define NO_ROUGHNESS 1
#endif

// The kind of lobe a sampled direction came from (pbrt's BxDFFlags, the part the integrator uses).
const int LOBE_DIFFUSE = 1;
const int LOBE_GLOSSY = 2;         // a GGX lobe
const int LOBE_SPECULAR = 4;       // a delta lobe: a mirror, smooth glass
const int LOBE_TRANSMISSION = 8;

// A path vertex as the BSDF sees it, its material's parameters read once from the record.
struct SurfaceRecord {
    vec3 p;          // the point
    vec3 n;          // outward shading normal
    vec3 nf;         // the shading normal on wo's side
    vec3 wo;         // unit, towards where the path came from
    bool front;      // wo on the side the geometric normal faces
    int prim;        // the primitive hit (a ray leaving it: exclusion())
    vec3 color;      // the diffuse lobe's albedo
    float w_diffuse, w_reflect, w_transmit;   // lobe weights, summing ≤ 1
    float alpha;     // GGX α of the reflective and transmissive lobes (0: smooth)
    float ior;       // inside / outside
#if FEATURE_PBR
    int kind;        // the material's kind (KIND_PHONG, KIND_PBR)
    float metallic, transmission, f0;   // the PBR kind's (w_*: its lobes' probabilities)
#endif
};

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

// Fresnel reflectance of a smooth dielectric: cos_i > 0 the incident cosine, eta = n_i / n_t.
float fresnel_dielectric(float cos_i, float eta) {
    float sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i);
    if (sin2_t >= 1.0) return 1.0;   // total internal reflection
    float cos_t = sqrt(1.0 - sin2_t);
    float rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

// A direction bsdf_sample chose: weight = f · cos / (the density it was drawn with), pdf =
// bsdf_pdf(wi) where a lobe next-event estimation lights chose it (the power heuristic's BSDF side)
// and 0 where a delta or rough transmission did (the emission it meets then counts whole); lobe: the
// LOBE_* flags; valid false: absorbed, or masked (below the horizon its lobe allows).
struct BsdfSample {
    vec3 wi;
    vec3 weight;
    float pdf;
    int lobe;
    bool valid;
};

// The other kinds' BSDFs, which share the record, the helpers above and the sample's struct; the
// functions below dispatch to them by the record's kind.
#if FEATURE_PBR
//@INCLUDE bsdf_pbr_path.glsl
#endif

SurfaceRecord surface_record(vec3 p, vec3 n, vec3 ng, vec3 wo, int prim, int mat) {
    SurfaceRecord r;
    r.p = p;
    r.n = n;
    r.wo = wo;
    r.front = dot(wo, ng) > 0.0;
    r.nf = r.front ? n : -n;
    r.prim = prim;
#if FEATURE_PBR
    if (MATERIAL_KIND(mat) == KIND_PBR) {
        pbr_surface(r, mat);
        return r;
    }
    r.kind = KIND_PHONG;
#endif
    r.color = material_color(mat);
    r.w_diffuse = material_diffuse(mat);
    r.w_reflect = 0.0;
    r.w_transmit = 0.0;
#if !NO_REFLECTION
    r.w_reflect = material_reflective(mat);
#endif
#if !NO_TRANSMISSION
    r.w_transmit = material_transmissive(mat);
#endif
    float total = r.w_diffuse + r.w_reflect + r.w_transmit;
    if (total > 1.0) { r.w_diffuse /= total; r.w_reflect /= total; r.w_transmit /= total; }
#if NO_ROUGHNESS
    r.alpha = 0.0;   // the GGX code then folds away
#else
    r.alpha = material_roughness(mat);
#endif
    r.ior = material_ior(mat);
    return r;
}

// Whether the BSDF has lobes that next-event estimation lights (diffuse, GGX reflection): the smooth
// mirror and glass are deltas no light sample can meet, and rough transmission is left to BSDF sampling.
bool bsdf_is_non_specular(SurfaceRecord r) {
#if FEATURE_PBR
    if (r.kind == KIND_PBR) return r.w_diffuse + r.w_reflect > 0.0;
#endif
    return r.w_diffuse > 0.0 || (r.w_reflect > 0.0 && r.alpha > 0.0);
}

// The surface's albedo as its lobes reflect (the denoiser's guide): w_d · colour + w_r + w_t.
vec3 bsdf_albedo(SurfaceRecord r) {
#if FEATURE_PBR
    if (r.kind == KIND_PBR) return r.color;   // the PBR kind's guide: its base colour
#endif
    return r.w_diffuse * r.color + vec3(r.w_reflect + r.w_transmit);
}

// f(wo → wi) of the lobes next-event estimation lights (the diffuse and the GGX one; no cosine),
// and in pdf the density with which bsdf_sample chooses wi among them (each lobe with its weight's
// probability). The deltas and rough transmission contribute nothing here.
vec3 bsdf_eval(SurfaceRecord r, vec3 wi, out float pdf) {
#if FEATURE_PBR
    if (r.kind == KIND_PBR) return pbr_bsdf_eval(r, wi, pdf);
#endif
    vec3 f = (r.w_diffuse / PI) * r.color;
    pdf = r.w_diffuse * max(dot(r.nf, wi), 0.0) / PI;
    if (r.w_reflect > 0.0 && r.alpha > 0.0) {
        vec2 g = ggx_eval(r.nf, r.wo, wi, r.alpha);
        f += vec3(r.w_reflect * g.x);
        pdf += r.w_reflect * g.y;
    }
    return f;
}

float bsdf_pdf(SurfaceRecord r, vec3 wi) {
    float pdf;
    bsdf_eval(r, wi, pdf);
    return pdf;
}

// One lobe chosen by uc with its weight's probability (none: absorbed), a direction from it by u.
BsdfSample bsdf_sample(SurfaceRecord r, float uc, vec2 u) {
#if FEATURE_PBR
    if (r.kind == KIND_PBR) return pbr_bsdf_sample(r, uc, u);
#endif
    BsdfSample bs = BsdfSample(vec3(0.0), vec3(1.0), 0.0, 0, true);
    vec3 d = -r.wo;
    if (uc < r.w_diffuse) {
        bs.wi = cosine_direction(r.nf, u.x, u.y);
        bs.weight = r.color;
        bs.lobe = LOBE_DIFFUSE;
    } else if (uc < r.w_diffuse + r.w_reflect) {
        if (r.alpha > 0.0) {
            // GGX, F = 1: a microfacet normal from the normals visible from wo (Heitz 2018), reflection
            // about it; D and G1(wo) cancel against the density, so the weight is G1 of the new
            // direction, never above 1 (Mitsuba's roughconductor with sample_visible).
            vec3 mh = ggx_visible_normal(r.nf, r.wo, r.alpha, u.x, u.y);
            float o_m = dot(r.wo, mh);
            bs.wi = 2.0 * o_m * mh - r.wo;
            float n_o = dot(r.nf, r.wo), n_i = dot(r.nf, bs.wi);
            bs.lobe = LOBE_GLOSSY;
            if (o_m <= 0.0 || n_i <= 0.0 || n_o <= 0.0) bs.valid = false;
            else bs.weight = vec3(smith_g1(n_i, r.alpha));
        } else {
            bs.wi = d - 2.0 * dot(d, r.n) * r.n;
            bs.lobe = LOBE_SPECULAR;
        }
    } else if (uc < r.w_diffuse + r.w_reflect + r.w_transmit) {
        float eta = r.front ? 1.0 / r.ior : r.ior;
        vec3 nn = r.front ? r.n : -r.n;
        bs.lobe = LOBE_TRANSMISSION | (r.alpha > 0.0 ? LOBE_GLOSSY : LOBE_SPECULAR);
        if (r.alpha > 0.0) {
            // A rough dielectric (Walter et al. 2007), GGX of α = roughness as the reflective lobe's: a
            // microfacet normal m from the normals visible from wo (Heitz 2018), reflection about it
            // with the Fresnel probability F(wo·m), else refraction through it; that choice reuses uc,
            // uniform again within the lobe's share. F and 1 − F cancel against their probabilities,
            // D and G1(wo) against the density: the weight is G1 of the new direction, never above 1
            // (Mitsuba's roughdielectric with sample_visible). A direction on the wrong side of the
            // surface for its kind (reflected below it, refracted above it) is masked.
            float n_o = dot(nn, r.wo);
            vec3 mh = ggx_visible_normal(nn, r.wo, r.alpha, u.x, u.y);
            float o_m = dot(r.wo, mh);
            float u3 = (uc - r.w_diffuse - r.w_reflect) / r.w_transmit;
            if (o_m <= 0.0 || n_o <= 0.0) {
                bs.valid = false;
            } else {
                float k = 1.0 - eta * eta * (1.0 - o_m * o_m);
                bool reflect_m = k <= 0.0 || u3 < fresnel_dielectric(o_m, eta);
                bs.wi = reflect_m ? 2.0 * o_m * mh - r.wo : normalize(eta * d + (eta * o_m - sqrt(max(k, 0.0))) * mh);
                float n_i = dot(nn, bs.wi);
                if (reflect_m ? n_i <= 0.0 : n_i >= 0.0) bs.valid = false;
                else bs.weight = vec3(smith_g1(abs(n_i), r.alpha));
            }
        } else {
            // A smooth dielectric: reflect with Fresnel's probability, else refract.
            float cos_i = -dot(d, nn);
            float f = fresnel_dielectric(abs(cos_i), eta);
            if (u.x < f) {
                bs.wi = d - 2.0 * dot(d, nn) * nn;
            } else {
                float k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                bs.wi = normalize(eta * d + (eta * cos_i - sqrt(max(k, 0.0))) * nn);
            }
        }
    } else {
        bs.valid = false;
    }
    if (bs.valid && (bs.lobe == LOBE_DIFFUSE || bs.lobe == LOBE_GLOSSY)) bs.pdf = bsdf_pdf(r, bs.wi);
    return bs;
}
#endif
