// A depth monotonic in t, exact: the bits of a positive float32 are ordered as
// the floats, so t in [2^-62, 2^64) maps one-to-one onto the normal floats of
// [2^-126, 1) by shifting the exponent by 64 (no rounding; clear depth 1.0
// means "no hit"). t outside that range is clamped to its ends, where two
// different t can tie (the lower id wins, as for exactly equal t).
float depth_of(float t) {
    uint b = floatBitsToUint(t);
    b = clamp(b, 65u << 23, (191u << 23) - 1u);
    return uintBitsToFloat(b - (64u << 23));
}
