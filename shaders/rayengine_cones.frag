// Hierarchical ray engine, §4: one enclosing cone per tile of TILE × TILE
// rays, one fragment per tile. RADIANCE: the rays of u_ray_o/u_ray_d (live
// where the weight > 0); SHADOW: the shadow rays of light u_light from the
// surfaces u_surf0/u_surf1. renderer/accel/hre_cones.py is the same algorithm in
// NumPy (and documents it); keep the two in step.
//
// 1. Incremental construction (Szécsi §4): start with the zero-angle cone of
//    the first live ray; for each further ray (a) if its direction is outside
//    the cone's solid angle, widen it: far generator e = x cos φ + q sin φ,
//    x ← normalize(e + r), cos φ ← x·r; (b) if its origin is outside the cone,
//    translate the apex backwards along the far generator until the near
//    generator passes through the origin: a ← a − e t, t = |g|² / −(e·g).
// 2. Certification (ours, for conservativeness in float32): with the final
//    apex and axis, φ ← the largest angle from the axis of any ray direction
//    and of any origin (seen from the apex), plus a margin, and the slack ←
//    the largest rounding error of an origin − apex. Every ray of the tile
//    then lies within `slack` of the cone whatever the rounding in step 1.
// Output: o_cone0 = (apex, φ), o_cone1 = (axis, slack); φ = -2: no live ray
// in the tile (not drawn at all); φ = -1: no useful cone (φ > PHI_MAX, or a
// degenerate step): the tile is drawn for every primitive.
uniform highp sampler2D u_ray_o;
uniform highp sampler2D u_ray_d;
uniform highp sampler2D u_surf0;
uniform highp sampler2D u_surf1;
uniform int u_light;
layout(location = 0) out vec4 o_cone0;
layout(location = 1) out vec4 o_cone1;

const float PHI_MAX = 1.4;                 // beyond: no cull (the cone must stay convex, < π/2)
const float SIN_MIN = 1.0e-3;              // a cone must open this much before it can move its apex
const float ANGLE_MARGIN = 1.0e-5;

bool live_ray(ivec2 px, out vec3 p, out vec3 r) {
#if SHADOW
    float dist;
    int skip, far_id;
    return shadow_ray_at(u_surf0, u_surf1, px, u_light, p, r, dist, skip, far_id);
#else
    vec4 rd = texelFetch(u_ray_d, px, 0);
    if (!(rd.w > 0.0)) return false;
    p = texelFetch(u_ray_o, px, 0).xyz;
    r = rd.xyz;
    return true;
#endif
}

vec3 perpendicular(vec3 x) {
    vec3 y = abs(x.x) < 0.5 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    return normalize(cross(x, y));
}

float angle_between(vec3 u, vec3 v) {      // accurate for small angles too
    return atan(length(cross(u, v)), dot(u, v));
}

void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * TILE;
    vec3 a = vec3(0.0), x = vec3(0.0, 0.0, 1.0);
    float cphi = 1.0, sphi = 0.0;
    int count = 0;
    bool give_up = false;
    for (int j = 0; j < TILE; j++) {
        for (int i = 0; i < TILE; i++) {
            vec3 p, r;
            if (!live_ray(base + ivec2(i, j), p, r)) continue;
            count++;
            if (count == 1) { a = p; x = r; continue; }
            if (give_up) continue;
            // (a) widen the cone to take the direction
            float xr = dot(x, r);
            if (xr < cphi) {
                vec3 q = xr * x - r;
                float ql = length(q);
                if (!(ql > 0.0)) { give_up = true; continue; }         // r = −x
                q /= ql;
                vec3 e = x * cphi + q * sphi;
                vec3 s = e + r;
                float sl = length(s);
                if (!(sl > 1.0e-6)) { give_up = true; continue; }
                x = s / sl;
                cphi = min(dot(x, r), 1.0);
                sphi = sqrt(max(0.0, 1.0 - cphi * cphi));
                if (cphi < cos(PHI_MAX)) { give_up = true; continue; }
            }
            // (b) translate the apex to take the origin
            vec3 c = p - a;
            float cl = length(c);
            float xc = dot(x, c);
            if (cl > 0.0 && xc < cphi * cl) {
                if (sphi < SIN_MIN) { sphi = SIN_MIN; cphi = sqrt(1.0 - SIN_MIN * SIN_MIN); }
                vec3 q = xc * x - c;
                float ql = length(q);
                q = ql > 1.0e-7 * cl ? q / ql : perpendicular(x);
                vec3 e = x * cphi + q * sphi;
                vec3 nn = x * cphi - q * sphi;
                vec3 g = c - dot(nn, c) * nn;
                float eg = dot(e, g);
                if (!(eg < 0.0)) { give_up = true; continue; }
                a -= e * (dot(g, g) / -eg);
            }
        }
    }
    if (count == 0) {
        o_cone0 = vec4(0.0, 0.0, 0.0, -2.0);
        o_cone1 = vec4(0.0, 0.0, 1.0, 0.0);
        return;
    }
    // certification: every ray within `slack` of the cone (a, x, phi)
    x = normalize(x);
    float phi = 0.0, slack = 0.0;
    float la = length(a);
    for (int j = 0; j < TILE; j++) {
        for (int i = 0; i < TILE; i++) {
            vec3 p, r;
            if (!live_ray(base + ivec2(i, j), p, r)) continue;
            phi = max(phi, angle_between(x, r));
            vec3 c = p - a;
            float tol = 4.0 * EPS32 * (length(p) + la);
            slack = max(slack, tol);
            if (length(c) > tol) phi = max(phi, angle_between(x, c));
        }
    }
    phi += ANGLE_MARGIN;
    bool useless = give_up || !(phi <= PHI_MAX) || any(isnan(a)) || any(isinf(a)) || !(slack < 1.0e30);
    o_cone0 = vec4(a, useless ? -1.0 : phi);
    o_cone1 = vec4(x, slack);
}
