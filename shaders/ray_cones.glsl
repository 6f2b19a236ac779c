// Ray cones for the textures' mip levels (Akenine-Möller et al., "Improved Shader and Texture Level
// of Detail Using Ray Cones", JCGT 2021; docs/SHADING.md, "Textures"): one whole chunk, compiled
// where FEATURE_TEXTURES is 1. A ray carries a cone of width w at its origin (0 at the camera) and
// spread angle γ (the primary ray's: one pixel's angle); along a segment of length t, w grows by
// γ·t. A mirror or a smooth refraction keeps γ (the surface's curvature is not added); a rough or
// diffuse bounce widens it (cone_after_bounce). At a hit the footprint is w / |cos| of the ray to the
// geometric normal, which the integrators store in g_cone_width for pbr_inputs (its cone_width).
#if FEATURE_TEXTURES
float g_cone_width = 0.0;

// One pixel's angle at the image's centre (the paper's eq. 30), on a grid `scale` times finer.
float cone_pixel_spread(float scale) {
    return atan(2.0 * u_half_extent.y / (u_resolution.y * scale));
}

// The footprint on the surface of a cone of width w met along d: w / |cos(d, ng)|.
float cone_footprint(float w, vec3 d, vec3 ng) {
    return w / max(abs(dot(d, ng)), 1e-6);
}

// The spread after a bounce whose sampled direction has pdf `pdf` (per steradian): a delta lobe
// (`specular`) keeps it; any other lobe widens it to at least the full angle of a cone of solid
// angle 1/pdf (2·sqrt(1/(π·pdf)): a GGX lobe of small α gives a narrow cone, a Lambert lobe a wide
// one), at most CONE_WIDE_SPREAD, what a diffuse bounce gives.
const float CONE_WIDE_SPREAD = 1.0;   // radians
float cone_after_bounce(float spread, float pdf, bool specular) {
    if (specular) return spread;
    float lobe = pdf > 0.0 ? 2.0 * sqrt(1.0 / (3.14159265 * pdf)) : CONE_WIDE_SPREAD;
    return max(spread, min(lobe, CONE_WIDE_SPREAD));
}
#else
#define g_cone_width 0.0
#endif
