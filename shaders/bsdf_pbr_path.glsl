// The PBR kind's BSDF for the path integrator (docs/SHADING.md, "PBR"): the glTF BRDF of
// shaders/bsdf_pbr.glsl as three lobes — Lambert diffuse (cosine sampling), GGX reflection (the
// normals visible from wo, Heitz 2018) and, for KHR_materials_transmission, the rough dielectric of
// Walter et al. (the Phong kind's code: reflection with the exact Fresnel probability, else
// refraction tinted by the base colour) — one chosen per sample with a probability from an estimate
// of its weight at wo. The diffuse and GGX reflection lobes are one mixture: f is their sum, the pdf
// their lobe-probability-weighted sum (next-event estimation meets them, MIS with the lights); the
// rough dielectric, as the Phong kind's, is met by BSDF sampling alone (pdf 0: its emission counts
// whole). bsdf_phong.glsl's surface_record, bsdf_eval and bsdf_sample dispatch here by the kind.

// r's PBR part from material mat: the inputs at the hit (pbr_inputs: factors, textures, the normal
// map), and the lobe probabilities in w_diffuse, w_reflect, w_transmit (summing 1; all 0: black).
void pbr_surface(inout SurfaceRecord r, int mat) {
    PbrInputs s = pbr_inputs(mat, r.prim, r.p, r.n, g_cone_width);
    r.kind = KIND_PBR;
    r.n = s.n;
    r.nf = r.front ? s.n : -s.n;
    r.color = s.base_color;
    r.metallic = s.metallic;
    r.transmission = s.transmission;
    r.alpha = pbr_alpha_of(s.roughness);
    r.ior = pbr_ior(mat);
    r.f0 = pbr_f0_of(r.ior);
    vec3 lum = vec3(0.2126, 0.7152, 0.0722);
    float c = max(dot(r.nf, r.wo), 0.0);
    float fd = pbr_dielectric_fresnel(r.f0, c);
    float dielectric = 1.0 - r.metallic;
    float e_spec = dielectric * (1.0 - r.transmission) * fd + r.metallic * dot(pbr_fresnel(r.color, 1.0, 0.0, c), lum);
    float e_diff = dielectric * (1.0 - r.transmission) * (1.0 - fd) * dot(r.color, lum);
    float e_trans = dielectric * r.transmission;
    float total = e_spec + e_diff + e_trans;
    float k = total > 0.0 ? 1.0 / total : 0.0;
    r.w_diffuse = e_diff * k;
    r.w_reflect = e_spec * k;
    r.w_transmit = e_trans * k;
}

// The diffuse and GGX reflection lobes: f(wo → wi) and the mixture's pdf.
vec3 pbr_bsdf_eval(SurfaceRecord r, vec3 wi, out float pdf) {
    float n_i = dot(r.nf, wi);
    pdf = r.w_diffuse * max(n_i, 0.0) / PI;
    if (r.w_reflect > 0.0) pdf += r.w_reflect * ggx_eval(r.nf, r.wo, wi, r.alpha).y;
    return pbr_brdf(r.color, r.metallic, r.alpha, r.f0, r.transmission, 1.0 - r.transmission, r.nf, r.wo, wi);
}

BsdfSample pbr_bsdf_sample(SurfaceRecord r, float uc, vec2 u) {
    BsdfSample bs = BsdfSample(vec3(0.0), vec3(1.0), 0.0, 0, true);
    if (uc < r.w_diffuse + r.w_reflect) {
        if (uc < r.w_diffuse) {
            bs.wi = cosine_direction(r.nf, u.x, u.y);
            bs.lobe = LOBE_DIFFUSE;
        } else {
            vec3 mh = ggx_visible_normal(r.nf, r.wo, r.alpha, u.x, u.y);
            bs.wi = 2.0 * dot(r.wo, mh) * mh - r.wo;
            bs.lobe = LOBE_GLOSSY;
        }
        // One sample of the mixture: f · cos over the mixture's pdf (both lobes' f in f).
        float pdf;
        vec3 f = pbr_bsdf_eval(r, bs.wi, pdf);
        float n_i = dot(r.nf, bs.wi);
        if (n_i <= 0.0 || pdf <= 0.0 || dot(r.nf, r.wo) <= 0.0) {
            bs.valid = false;
        } else {
            bs.weight = f * (n_i / pdf);
            bs.pdf = pdf;
        }
    } else if (r.w_transmit > 0.0) {
        // The rough dielectric (bsdf_phong.glsl's transmissive lobe): F and 1 − F cancel against
        // their probabilities, D and G1(wo) against the visible normals' density; the lobe's weight
        // (1 − metallic) · transmission over its probability, the refracted light tinted by the base colour.
        float eta = r.front ? 1.0 / r.ior : r.ior;
        vec3 nn = r.front ? r.n : -r.n;
        bs.lobe = LOBE_TRANSMISSION | LOBE_GLOSSY;
        float n_o = dot(nn, r.wo);
        vec3 mh = ggx_visible_normal(nn, r.wo, r.alpha, u.x, u.y);
        float o_m = dot(r.wo, mh);
        float u3 = clamp((uc - r.w_diffuse - r.w_reflect) / r.w_transmit, 0.0, 1.0);
        if (o_m <= 0.0 || n_o <= 0.0) {
            bs.valid = false;
        } else {
            float k = 1.0 - eta * eta * (1.0 - o_m * o_m);
            bool reflect_m = k <= 0.0 || u3 < fresnel_dielectric(o_m, eta);
            bs.wi = reflect_m ? 2.0 * o_m * mh - r.wo : normalize(-eta * r.wo + (eta * o_m - sqrt(max(k, 0.0))) * mh);
            float n_i = dot(nn, bs.wi);
            float share = (1.0 - r.metallic) * r.transmission / r.w_transmit;
            if (reflect_m ? n_i <= 0.0 : n_i >= 0.0) bs.valid = false;
            else bs.weight = (reflect_m ? vec3(share) : share * r.color) * smith_g1(abs(n_i), r.alpha);
        }
    } else {
        bs.valid = false;
    }
    return bs;
}
