#version 300 es
// First hits by rasterisation, per tile (renderer/frame/first_hits.py, tile_lists): one instance per
// tile some sphere's rectangle meets; the tracer's fragment shader (FIRST_HITS_TILES) tests the
// tile's list.
in vec2 a_corner;   // (0, 0) … (1, 1): the quad's corner
in vec4 a_rect;     // per instance: the tile (x0, y0, x1, y1), normalised device coordinates
in uvec2 a_list;    // per instance: its list's first entry and length
flat out uvec2 v_list;
void main() {
    v_list = a_list;
    gl_Position = vec4(mix(a_rect.xy, a_rect.zw, a_corner), 0.0, 1.0);
}
