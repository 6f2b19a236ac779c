// Texture lookups (docs/SHADING.md, "Textures"): one whole chunk, compiled where FEATURE_TEXTURES is
// 1 (renderer/gpu/texture_layout.py packs what it reads). Texture k lies in layer texture_layer(k) of
// u_textures, its level l at (x0 >> l, y0 >> l) of the array's level l, ⌈width / 2^l⌉ ×
// ⌈height / 2^l⌉ texels; its record texture_<field>(k) says where, its size, levels and sampler. Every fetch is a texelFetch: the wrap mode
// applies to the integer texel index (what GL's wrap does to a filter's taps), an sRGB texel is
// decoded to linear before it is mixed, bilinear within a level (four texels) or the nearest one,
// and two levels mixed by the level's fraction. The hardware's filter could do neither per layer:
// a layer's wrap, and decoding mixed sRGB and linear layers of one array.
// renderer/oracle/reference.py's texture_sample is the float64 twin the tests compare with.
#if FEATURE_TEXTURES
vec3 srgb_decode(vec3 c) {
    return mix(c * (1.0 / 12.92), pow((c + 0.055) * (1.0 / 1.055), vec3(2.4)), step(vec3(0.04045), c));
}

// Texel index i of a side of n texels, wrapped by mode (0 repeat, 1 clamp, 2 mirror). Through floats:
// GLSL ES leaves % of a negative integer undefined; exact below 2^24.
int wrap_index(int i, int n, uint mode) {
    if (mode == 1u) return clamp(i, 0, n - 1);
    if (mode == 2u) {
        int p = 2 * n;
        int m = i - p * int(floor(float(i) / float(p)));
        return m < n ? m : p - 1 - m;
    }
    return i - n * int(floor(float(i) / float(n)));
}

// Texel (x, y) of a level whose corner in the array is at.xy, in layer at.z.
vec4 texel_at(ivec3 at, int x, int y, int level, bool srgb) {
    vec4 c = texelFetch(u_textures, ivec3(at.x + x, at.y + y, at.z), level);
    if (srgb) c.rgb = srgb_decode(c.rgb);
    return c;
}

// Texture k at uv (U right, V down the image; (0, 0) its top-left corner) in one mip level.
vec4 texture_level(int k, vec2 uv, int level, uint word) {
    ivec2 size = ivec2((ivec2(int(texture_width(k)), int(texture_height(k))) + (1 << level) - 1) >> level);
    uint ws = word & 3u, wt = (word >> 2) & 3u;
    bool srgb = ((word >> 5) & 1u) != 0u;
    ivec3 at = ivec3(int(texture_x0(k)) >> level, int(texture_y0(k)) >> level, int(texture_layer(k)));
    vec2 s = uv * vec2(size);
    if (((word >> 4) & 1u) != 0u) {
        ivec2 i = ivec2(floor(s));
        return texel_at(at, wrap_index(i.x, size.x, ws), wrap_index(i.y, size.y, wt), level, srgb);
    }
    s -= 0.5;
    vec2 f0 = floor(s);
    vec2 f = s - f0;
    ivec2 i0 = ivec2(f0);
    int x0 = wrap_index(i0.x, size.x, ws), x1 = wrap_index(i0.x + 1, size.x, ws);
    int y0 = wrap_index(i0.y, size.y, wt), y1 = wrap_index(i0.y + 1, size.y, wt);
    vec4 a = mix(texel_at(at, x0, y0, level, srgb), texel_at(at, x1, y0, level, srgb), f.x);
    vec4 b = mix(texel_at(at, x0, y1, level, srgb), texel_at(at, x1, y1, level, srgb), f.x);
    return mix(a, b, f.y);
}

// Texture k at uv and mip level `level` (fractional: the two levels around it mixed; clamped to
// the texture's levels), linear RGBA.
vec4 texture_sample(int k, vec2 uv, float level) {
    uint word = texture_wrap_s(k) | (texture_wrap_t(k) << 2) | (texture_nearest(k) << 4) | (texture_srgb(k) << 5);
    float top = float(int(texture_levels(k)) - 1);
    float lv = clamp(level, 0.0, top);
    int l0 = int(floor(lv));
    float f = lv - float(l0);
    vec4 c = texture_level(k, uv, l0, word);
    if (f > 0.0) c = mix(c, texture_level(k, uv, l0 + 1, word), f);
    return c;
}
#endif
