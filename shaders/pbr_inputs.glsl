// What a glTF metallic-roughness material (renderer/materials/pbr.py) shows at a hit point: its
// factors, times its textures and the mesh's vertex colours where it has them (docs/SHADING.md,
// "Textures"). The BSDF (shaders/bsdf_pbr.glsl) and the Whitted shading read only this record, so
// where the numbers come from (a factor, a texel of the right mip level, a vertex) is this file's
// business alone. pbr_<name>(m) reads parameter <name> of the PBR record of material m.
//
// pbr_inputs(mat, prim, p, n, cone_width): material mat at point p of primitive prim, whose
// interpolated shading normal (outward, unit) is n; cone_width is the ray cone's width at p in world
// units (the texture footprint: it picks the mip level).
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
    return s;
}
