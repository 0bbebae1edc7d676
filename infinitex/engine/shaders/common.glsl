// Shared integer helpers. Prepended to every pass after the #version line and
// the #defines (SUB_S: subpass grid size s; MODEL_APPEARANCE or MODEL_COLOR).
// Integer conventions: engine/fixed.py.

const int SHIFT_BIAS = 1 << 30;

// Chris Wellons' lowbias32: a well-mixed 32-bit integer hash.
uint lowbias32(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

// H(p, l, seed) in [-1024, 1023] per axis (1024ths of [-1, 1)).
ivec2 hash2(ivec2 g, int level, uint seed) {
    uint s = lowbias32(seed);
    s = lowbias32(uint(level) ^ s);
    uint v = lowbias32(uint(g.y) ^ s);
    v = lowbias32(uint(g.x) ^ v);
    return ivec2(int(v & 2047u) - 1024, int((v >> 11) & 2047u) - 1024);
}

// floor(x / 2^s) without relying on the sign behaviour of >> (|x| < 2^30).
ivec4 floor_shift(ivec4 x, int s) {
    return ((x + ivec4(SHIFT_BIAS)) >> s) - ivec4(SHIFT_BIAS >> s);
}

// Scratch buffers are quadrant-packed (LH05 3.6): local pixel p of phase
// p mod s lives in block (p mod s) at offset p div s, so each subpass
// rewrites one contiguous block. p must be non-negative.
ivec2 packed_texel(ivec2 p, ivec2 qdims) {
    return (p % SUB_S) * qdims + p / SUB_S;
}

// The effective r_l in 1024ths for randomness field values E (exemplar) and
// C (canvas) in 1/32768ths (engine/controls/fields.py: modulated_rq).
int modulated_rq(int rq, uint E, uint C) {
    uint t = (E * C + 16384u) >> 15;
    return int(min(1024u, (uint(rq) * t + 16384u) >> 15));
}

// Placed features (engine/controls/features.py Feature, LH05 4.3). Table texture, one
// row per feature: (p_F,l.x, p_F,l.y, frac.x + 16 frac.y, radius in 1/16 level
// pixels), (u_F.x, u_F.y, -, -). A pixel whose center lies within the radius
// takes S = (u_F + h (g - p_F,l)) mod m; later features win. With a period n
// (toroidal output) offsets wrap modulo n.
uniform int nfeat;
uniform isampler2D features;

ivec2 apply_features(ivec2 g, ivec2 s, int h, int m, int period) {
    for (int i = 0; i < nfeat; i++) {
        ivec4 a = texelFetch(features, ivec2(0, i), 0);
        ivec2 d = g - a.xy;
        if (period > 0) {
            d = ((d + period / 2) & (period - 1)) - period / 2;
        }
        int lim = (a.w >> 4) + 2;
        if (abs(d.x) > lim || abs(d.y) > lim) {
            continue;
        }
        ivec2 d16 = d * 16 + 8 - ivec2(a.z & 15, a.z >> 4);
        if (d16.x * d16.x + d16.y * d16.y <= a.w * a.w) {
            s = (texelFetch(features, ivec2(1, i), 0).xy + h * d) & (m - 1);
        }
    }
    return s;
}
