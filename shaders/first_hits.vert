#version 300 es
// First hits by rasterisation (renderer/frame/first_hits.py): one instance per sphere, a quad over
// the window rectangle its primary rays can meet (computed on the host, in float64, widened by
// a fragment); the tracer's fragment shader (FIRST_HITS_SPHERES) tests that sphere alone.
in vec2 a_corner;   // (0, 0) … (1, 1): the quad's corner
in vec4 a_rect;     // per instance: the rectangle's corners (x0, y0, x1, y1), normalised device coordinates
in vec4 a_sphere;   // per instance: centre and radius, the float32 values the records hold
in uint a_key;      // per instance: the sphere's record key (id | material << SPHERE_MAT_SHIFT)
flat out vec4 v_sphere;
flat out uint v_key;
void main() {
    v_sphere = a_sphere;
    v_key = a_key;
    gl_Position = vec4(mix(a_rect.xy, a_rect.zw, a_corner), 0.0, 1.0);
}
