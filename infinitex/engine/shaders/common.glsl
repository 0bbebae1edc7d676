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

// The 32 hash bits of pixel g at a level (engine/fixed.py hash_bits).
uint hash_bits(ivec2 g, int level, uint seed) {
    uint s = lowbias32(seed);
    s = lowbias32(uint(level) ^ s);
    uint v = lowbias32(uint(g.y) ^ s);
    return lowbias32(uint(g.x) ^ v);
}

// H(p, l, seed) in [-1024, 1023] per axis (1024ths of [-1, 1)): bits 0-21.
ivec2 hash2(ivec2 g, int level, uint seed) {
    uint v = hash_bits(g, level, seed);
    return ivec2(int(v & 2047u) - 1024, int((v >> 11) & 2047u) - 1024);
}

// Which parent texel pixel g of a level is upsampled from (engine/fixed.py
// parent_step): floor(g / 2) + the step returned, 0, or per axis, one time in
// four (x: bits 22 and 23 of the pixel's hash both set, y: bits 24 and 25; gm: g
// wrapped to the period), the step to the nearest other one (+1 for an odd g,
// -1 for an even g). Inside a coherent
// patch either parent predicts the same coordinate; at a seam the child takes
// a side at random, so a coarse texel's border does not come down the pyramid
// as a straight line (dithered = 0: the plain rule, on lattices, whose seams
// belong on cell borders). A level a period makes constant stays so: all its
// pixels wrap to gm = 0 and take the same step.
ivec2 parent_step(ivec2 gm, int level, uint seed, int dithered) {
    if (dithered == 0)
        return ivec2(0);
    uint v = hash_bits(gm, level, seed);
    ivec2 d = ivec2(int((v >> 22) & (v >> 23) & 1u), int((v >> 24) & (v >> 25) & 1u));
    return d * (2 * (gm & 1) - 1);
}

// floor(x / 2^s) without relying on the sign behaviour of >> (|x| < 2^30).
ivec4 floor_shift(ivec4 x, int s) {
    return ((x + ivec4(SHIFT_BIAS)) >> s) - ivec4(SHIFT_BIAS >> s);
}

// Scratch buffers are quadrant-packed (LH05 3.6): local pixel p of phase
// p mod s lives in block (p mod s) at offset p div s, so each subpass
// rewrites one contiguous block. Block (i, j) starts at boff + (i, j) bstride
// (stages.block_layout: each block centred on a corner of llvmpipe's tiles).
// p must be non-negative.
uniform ivec2 bstride;
uniform ivec2 boff;

ivec2 packed_texel(ivec2 p, ivec2 qdims) {
    return boff + (p % SUB_S) * bstride + p / SUB_S;
}

uniform ivec2 active_phase;   // the phase a subpass rewrites (correct.frag, fidelity.frag)
ivec2 block_texel;            // the computed pixel's texel in its block, less boff (set by main)

// The effective r_l in 1024ths for randomness field values E (exemplar) and
// C (canvas) in 1/32768ths (engine/controls/fields.py: modulated_rq).
int modulated_rq(int rq, uint E, uint C) {
    uint t = (E * C + 16384u) >> 15;
    return int(min(1024u, (uint(rq) * t + 16384u) >> 15));
}

// Placed features (engine/controls/features.py Feature, LH05 4.4). Table texture, one
// row per feature (2 texels, TABLE_ROW = 512 rows a texture row): (p_F,l.x, p_F,l.y,
// frac.x + 16 frac.y, radius in 1/16 level pixels), (u_F.x, u_F.y, -, -). A pixel whose
// center lies within the radius takes S = (u_F + h (g - p_F,l)) mod m; later features
// win. With a period n (toroidal output) offsets wrap modulo n. A pixel tests only the
// features listed for its cell (features.py feature_bins: 2^fcell_shift level pixels
// from fcell_origin, or of g mod n with a period), in table order: the same result as
// testing them all, at the cost of the features that reach it.
uniform int nfeat;
uniform isampler2D features;
uniform isampler2D fcells;      // per cell: (first entry, count)
uniform isampler2D fentries;    // the cells' lists of table rows, ENTRY_ROW = 4096 a texture row
uniform ivec2 fcell_origin;
uniform ivec2 fcell_dims;
uniform int fcell_shift;

ivec2 apply_features_hit(ivec2 g, ivec2 s, int h, int m, int period, inout bool hit) {
    if (nfeat == 0) {
        return s;
    }
    ivec2 q = period > 0 ? (g & (period - 1)) : g - fcell_origin;
    ivec2 cell = texelFetch(fcells, clamp(q >> fcell_shift, ivec2(0), fcell_dims - 1), 0).xy;
    for (int j = cell.x; j < cell.x + cell.y; j++) {
        int i = texelFetch(fentries, ivec2(j & 4095, j >> 12), 0).x;
        ivec2 row = ivec2(2 * (i & 511), i >> 9);
        ivec4 a = texelFetch(features, row, 0);
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
            s = (texelFetch(features, row + ivec2(1, 0), 0).xy + h * d) & (m - 1);
            hit = true;
        }
    }
    return s;
}

ivec2 apply_features(ivec2 g, ivec2 s, int h, int m, int period) {
    bool hit = false;
    return apply_features_hit(g, s, h, m, period, hit);
}

#ifdef DIRECTION
// Anisometric synthesis (engine/controls/direction.py; engine/fixed.py has the
// same functions for the oracle). A coordinate F is in 1/256 exemplar px; a
// state texel holds its nearest texel (.xy, wrapped) and the remainder (.zw,
// in [-128, 128)). J is Q12 (j00, j01, j10, j11), one per region pixel.
uniform isampler2D dfield;    // J_l over this scratch region (row-major local pixels)

ivec2 full_q8(ivec4 v) {
    return v.xy * 256 + v.zw;
}

// (nearest texel wrapped to [0, m), remainder) of F.
ivec4 split_q8(ivec2 F, int m) {
    F &= 256 * m - 1;
    ivec2 r = (F + 128) >> 8;  // F >= 0 here
    return ivec4(r & (m - 1), F - (r << 8));
}

// The nearest texel of F, not wrapped (|F| < 2^29).
ivec2 nearest_q8(ivec2 F) {
    return floor_shift(ivec4(F + 128, 0, 0), 8).xy;
}

// h (J d) in 1/256 px: floor(h (J d) / 16).
ivec2 jmul(ivec4 J, ivec2 d, int h) {
    return floor_shift(ivec4(h * (J.x * d.x + J.y * d.y), h * (J.z * d.x + J.w * d.y), 0, 0), 4).xy;
}

// A level grown past the exemplar's resolution (a direction field's scale):
// both axes' texel steps through J, h J e_x and h J e_y, are under one exemplar
// pixel. Such a level is upsampled only (synthesis magnification, LH05 5): the
// correction and the fidelity stage leave it, having no finer exemplar detail to
// match. |J e|^2 in Q24 is under 2^29 (entries within 2^14), h at most 2 here.
bool beyond_exemplar(ivec4 J, int h) {
    if (h > 2) return false;
    int c = max(J.x * J.x + J.z * J.z, J.y * J.y + J.w * J.w);
    return c < (h == 1 ? 16777216 : 4194304);
}

// A level's jitter Jit (whole exemplar pixels) in 1/256 px under a direction
// field: scaled with the texture by the power of two nearest its area scale
// (det J in Q24): grown s times, it jitters about s times less in exemplar
// pixels, as much in its own texels; a turn or a stretch leaves it whole.
ivec2 jitter_q8(ivec4 J, ivec2 jit) {
    int det = J.x * J.w - J.y * J.z;
    ivec2 q = jit * 256;
    if (det < 2097152) return floor_shift(ivec4(q, 0, 0), 2).xy;  // s > 2^1.5
    if (det < 8388608) return floor_shift(ivec4(q, 0, 0), 1).xy;  // s > 2^0.5
    if (det > 134217728) return q * 4;                             // s < 2^-1.5
    if (det > 33554432) return q * 2;                              // s < 2^-0.5
    return q;
}

// floor(a / b) for b > 0.
int floor_div(int a, int b) {
    return a >= 0 ? a / b : -((b - 1 - a) / b);
}
#endif

#ifdef ATLAS
// Synthesis in a mesh's texture atlas (LH06 6; engine/surface/atlas.py). Per
// texel of the region: (its own chart or -1, the chart its link serves or -1,
// the link's target texel, level-global). A pixel of chart c reading texel q
// reads q itself when q is c's, else q's link when that serves c (the texel of
// the adjacent chart across c's border: the same surface point), else q. So a
// neighborhood near a chart's border reads across the seam (the indirection map).
uniform isampler2D links;     // over this scratch region (row-major local pixels)
int reader = -1;              // the chart of the pixel being computed (set by main)

ivec2 atlas_texel(ivec2 q, ivec2 dims, ivec2 origin) {
    ivec2 c = clamp(q, ivec2(0), dims - 1);
    ivec4 L = texelFetch(links, c, 0);
    return (reader >= 0 && L.x != reader && L.y == reader) ? clamp(L.zw - origin, ivec2(0), dims - 1) : c;
}
#define STATE_TEXEL(q) atlas_texel(q, dims, origin)

// Features placed on the model (engine/surface/features.py): table rows of 3
// texels, (p in 1/8 finest texels, reach in level texels, r_l in exemplar px),
// (u_F, chart, -), J (Q12). A texel of that chart whose centre x (finest
// texels) has |J (x - p)| <= r_l takes F = u_F + J (x - p); later rows win.
ivec4 apply_features_atlas(ivec2 g, ivec4 q, int h, int m, int chart) {
    if (nfeat == 0 || chart < 0) {
        return q;
    }
    ivec2 cell = texelFetch(fcells, clamp((g - fcell_origin) >> fcell_shift, ivec2(0), fcell_dims - 1), 0).xy;
    for (int j = cell.x; j < cell.x + cell.y; j++) {
        int i = texelFetch(fentries, ivec2(j & 4095, j >> 12), 0).x;
        ivec2 row = ivec2(3 * (i & 511), i >> 9);
        ivec4 a = texelFetch(features, row, 0);
        ivec4 b = texelFetch(features, row + ivec2(1, 0), 0);
        ivec2 d = g - ivec2(floor_div(a.x, 8 * h), floor_div(a.y, 8 * h));
        if (b.z != chart || abs(d.x) > a.z || abs(d.y) > a.z) {
            continue;
        }
        ivec2 D = clamp((2 * g + 1) * (4 * h) - a.xy, ivec2(-65535), ivec2(65535));
        ivec4 J = texelFetch(features, row + ivec2(2, 0), 0);
        ivec2 e = ivec2(J.x * D.x + J.y * D.y, J.z * D.x + J.w * D.y);  // 2^-15 exemplar px
        int R = a.w << 15;
        if (abs(e.x) > R || abs(e.y) > R) {
            continue;
        }
        ivec2 e4 = floor_shift(ivec4(e, 0, 0), 11).xy;
        if (uint(e4.x * e4.x) + uint(e4.y * e4.y) <= uint(16 * a.w) * uint(16 * a.w)) {
            q = split_q8(b.xy * 256 + floor_shift(ivec4(e, 0, 0), 7).xy, m);
        }
    }
    return q;
}
#else
#define STATE_TEXEL(q) clamp(q, ivec2(0), dims - 1)
#endif

#ifdef LABELS
// Texture by numbers (engine/controls/labels.py): two-label mixes packed as
// i1 | i2 << 4 | w1 << 8 | w2 << 16 (| painted share << 24 on the canvas side).
uniform usampler2D lab_exemplar;  // m x m, the exemplar texels' mixes at this level
uniform usampler2D lab_canvas;    // the region's canvas mixes, at unpacked positions p
uniform isampler2D lab_seeds;     // SEED_COUNT x 16: per label, exemplar texels of it
uniform int lab_weight;           // W_l

uint lab_weight_of(uint e, uint i) {
    return (e & 15u) == i ? (e >> 8) & 255u : (((e >> 4) & 15u) == i ? (e >> 16) & 255u : 0u);
}

// (((D * share) >> 8) * W_l) >> 4, D = |t|^2 + |e|^2 - 2 t.e (labels.py label_cost).
uint label_cost(uint t, uint e) {
    uint share = t >> 24;
    if (share == 0u) {
        return 0u;
    }
    uint t1 = t & 15u, t2 = (t >> 4) & 15u, w1 = (t >> 8) & 255u, w2 = (t >> 16) & 255u;
    uint v1 = (e >> 8) & 255u, v2 = (e >> 16) & 255u;
    uint te = w1 * lab_weight_of(e, t1) + (t2 != t1 ? w2 * lab_weight_of(e, t2) : 0u);
    uint D = w1 * w1 + w2 * w2 + v1 * v1 + v2 * v2 - 2u * te;
    return (((D * share) >> 8) * uint(lab_weight)) >> 4;
}
#endif

// NEIGHBOR_TEXEL(p, d): the scratch texel of local pixel p + d, p the pixel a
// subpass computes. INSIDE (params.subpass_rects: every read of a computed
// pixel stays inside the region, so nothing is clamped): p's phase is
// active_phase, so that of p + d and its block follow from d, and the texel is
// p's own plus a uniform offset (|d| <= 3 SUB_S).
#if defined(INSIDE) && (SUB_S == 2 || SUB_S == 4)
#define NEIGHBOR_TEXEL(p, d) (boff + ((active_phase + (d) + 4 * SUB_S) & (SUB_S - 1)) * bstride \
                              + block_texel + (active_phase + (d) + 4 * SUB_S) / SUB_S - 4)
#else
#define NEIGHBOR_TEXEL(p, d) packed_texel(STATE_TEXEL((p) + (d)), qdims)
#endif
