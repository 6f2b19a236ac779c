// What a glTF metallic-roughness material (renderer/materials/pbr.py) shows at a hit point: its
// factors, times its textures and the mesh's vertex colours where it has them (docs/SHADING.md,
// "Textures"). The BSDF (shaders/bsdf_pbr.glsl) and the Whitted shading read only this record, so
// where the numbers come from (a factor, a texel of the right mip level, a vertex) is this file's
// business alone. pbr_<name>(m) reads parameter <name> of the PBR record of material m.
//
// pbr_inputs(mat, prim, p, n, cone_width): material mat at point p of primitive prim, whose
// interpolated shading normal (outward, unit) is n; cone_width is the ray cone's footprint at p in
// world units (its width there over |cos| of its incidence: g_cone_width of shaders/ray_cones.glsl,
// which the integrators keep), which picks the mip level.
//
// Textures, vertex colours and tangents exist on triangles only (FEATURE_TEXTURES,
// FEATURE_VERTEX_COLORS, FEATURE_TANGENTS: renderer/gpu/texture_layout.py); elsewhere the factors stand.
//@INCLUDE textures.glsl
struct PbrInputs {
    vec3 base_color;    // linear RGB
    float alpha;        // coverage, 0 … 1
    float metallic;
    float roughness;    // perceptual: GGX α = roughness²
    vec3 emissive;      // emitted radiance, linear RGB (emissive × strength × texture)
    float occlusion;    // the ambient term's factor (1: none)
    float transmission;
    vec3 n;             // the shading normal after the normal map (unit, outward)
};

#if FEATURE_TEXTURES
// A hit's texture coordinates: both UV sets at p, and the triangle's level terms (Δ of each set).
struct PbrUv {
    vec2 uv[2];
    vec2 lod;
};

// Barycentric weights of p in triangle j (its corners from u_triangles): p's projection on the
// triangle's plane, exact where p lies on it.
vec3 triangle_weights(int j, vec3 p) {
    vec3 a = uintBitsToFloat(TRI_RECORD(j, 0).xyz);
    vec3 e1 = uintBitsToFloat(TRI_RECORD(j, 1).xyz) - a;
    vec3 e2 = uintBitsToFloat(TRI_RECORD(j, 2).xyz) - a;
    vec3 g = cross(e1, e2);
    float gg = dot(g, g);
    if (gg <= 0.0) return vec3(1.0, 0.0, 0.0);
    vec3 w = p - a;
    float b1 = dot(cross(w, e2), g) / gg;
    float b2 = dot(cross(e1, w), g) / gg;
    return vec3(1.0 - b1 - b2, b1, b2);
}

PbrUv pbr_uv(int j, vec3 b) {
    PbrUv t;
    t.uv[0] = b.x * tri_uv_uv0_a(j) + b.y * tri_uv_uv0_b(j) + b.z * tri_uv_uv0_c(j);
    t.uv[1] = b.x * tri_uv_uv1_a(j) + b.y * tri_uv_uv1_b(j) + b.z * tri_uv_uv1_c(j);
    t.lod = tri_uv_lod(j);
    return t;
}

// Texture `tex` of a slot at the hit: the slot's UV set through uv' = M·uv + offset (M row-major),
// at the ray cones' level log2(footprint) + Δ + ½·log2(width·height·|det M|) (the transform scales
// the UV area by |det M|).
vec4 pbr_slot(int tex, float texcoord, vec4 m, vec2 offset, PbrUv t, float cone_width) {
    int set = texcoord > 0.5 ? 1 : 0;
    vec2 uv = t.uv[set];
    vec2 st = vec2(m.x * uv.x + m.y * uv.y, m.z * uv.x + m.w * uv.y) + offset;
    float area = float(texture_width(tex)) * float(texture_height(tex)) * abs(m.x * m.w - m.y * m.z);
    float level = cone_width > 0.0 && area > 0.0 ? log2(cone_width) + t.lod[set] + 0.5 * log2(area) : 0.0;
    return texture_sample(tex, st, level);
}
#endif

PbrInputs pbr_inputs(int mat, int prim, vec3 p, vec3 n, float cone_width) {
    PbrInputs s;
    s.base_color = pbr_base_color(mat);
    s.alpha = pbr_alpha(mat);
    s.metallic = pbr_metallic(mat);
    s.roughness = pbr_roughness(mat);
    s.emissive = pbr_emissive(mat) * pbr_emissive_strength(mat);
    s.occlusion = 1.0;
    s.transmission = pbr_transmission(mat);
    s.n = n;
#if FEATURE_TEXTURES || FEATURE_VERTEX_COLORS || FEATURE_TANGENTS
    int j = prim - u_tri_base;
    bool on_triangle = prim >= u_tri_base;   // (ids: spheres, planes, triangles, shapes)
#if FEATURE_SHAPES
    on_triangle = on_triangle && prim < u_shape_base;
#endif
    if (on_triangle) {
        vec3 b = triangle_weights(j, p);
#if FEATURE_VERTEX_COLORS
        vec4 vc = b.x * uintBitsToFloat(u_tri_colors_at(TRIANGLE_TEXELS * j))
                + b.y * uintBitsToFloat(u_tri_colors_at(TRIANGLE_TEXELS * j + 1))
                + b.z * uintBitsToFloat(u_tri_colors_at(TRIANGLE_TEXELS * j + 2));
        s.base_color *= vc.rgb;
        s.alpha *= vc.a;
#endif
#if FEATURE_TEXTURES
        PbrUv t = pbr_uv(j, b);
        int k = int(pbr_base_color_texture(mat));
        if (k >= 0) {
            vec4 c = pbr_slot(k, pbr_base_color_texcoord(mat), pbr_base_color_uv_matrix(mat),
                              pbr_base_color_uv_offset(mat), t, cone_width);
            s.base_color *= c.rgb;
            s.alpha *= c.a;
        }
        k = int(pbr_metallic_roughness_texture(mat));
        if (k >= 0) {
            vec4 c = pbr_slot(k, pbr_metallic_roughness_texcoord(mat), pbr_metallic_roughness_uv_matrix(mat),
                              pbr_metallic_roughness_uv_offset(mat), t, cone_width);
            s.metallic *= c.b;
            s.roughness *= c.g;
        }
        k = int(pbr_emissive_texture(mat));
        if (k >= 0) {
            s.emissive *= pbr_slot(k, pbr_emissive_texcoord(mat), pbr_emissive_uv_matrix(mat),
                                   pbr_emissive_uv_offset(mat), t, cone_width).rgb;
        }
        k = int(pbr_occlusion_texture(mat));
        if (k >= 0) {
            float ao = pbr_slot(k, pbr_occlusion_texcoord(mat), pbr_occlusion_uv_matrix(mat),
                                pbr_occlusion_uv_offset(mat), t, cone_width).r;
            s.occlusion = 1.0 + pbr_occlusion_strength(mat) * (ao - 1.0);
        }
        k = int(pbr_transmission_texture(mat));
        if (k >= 0) {
            s.transmission *= pbr_slot(k, pbr_transmission_texcoord(mat), pbr_transmission_uv_matrix(mat),
                                       pbr_transmission_uv_offset(mat), t, cone_width).r;
        }
#if FEATURE_TANGENTS
        k = int(pbr_normal_texture(mat));
        if (k >= 0) {
            // The tangent frame at p: the corners' tangents blended, made orthogonal to n
            // (Gram–Schmidt), the bitangent w·(n × t) (glTF's); the map's XY scaled by normal_scale.
            // n is the outward normal, so a back face's map bends the same surface alike.
            vec4 t0 = uintBitsToFloat(u_tri_tangents_at(TRIANGLE_TEXELS * j));
            vec4 tb = b.x * t0 + b.y * uintBitsToFloat(u_tri_tangents_at(TRIANGLE_TEXELS * j + 1))
                    + b.z * uintBitsToFloat(u_tri_tangents_at(TRIANGLE_TEXELS * j + 2));
            vec3 tt = tb.xyz - n * dot(n, tb.xyz);
            float tl = length(tt);
            if (tl > 0.0) {
                tt /= tl;
                vec3 bt = (t0.w < 0.0 ? -1.0 : 1.0) * cross(n, tt);
                vec3 m = pbr_slot(k, pbr_normal_texcoord(mat), pbr_normal_uv_matrix(mat),
                                  pbr_normal_uv_offset(mat), t, cone_width).xyz * 2.0 - 1.0;
                m.xy *= pbr_normal_scale(mat);
                vec3 nm = m.x * tt + m.y * bt + m.z * n;
                float nl = length(nm);
                if (nl > 0.0) s.n = nm / nl;
            }
        }
#endif
#endif
    }
#endif
    return s;
}
