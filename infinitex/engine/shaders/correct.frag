// One correction subpass (LH05 3.1, 3.3; LH06 4) over a quadrant-packed
// scratch buffer: pixels of phase `active_phase` are rewritten (only their
// block is rendered, and of it what the strip needs: params.subpass_rects).
// For each rewritten pixel p:
//   N_S(p) = projected synthesized neighborhood
//     MODEL_APPEARANCE: for each diagonal d, sum over d' in {d, (d.x,0), (0,d.y)}
//                       of A_l[S[p+d'] + h (d - d')]   (3x the LH06 average)
//     MODEL_COLOR:      E_l[S[p+d]], d in [-2,2]^2     (LH05)
//   candidates u = C^i(S[p+d] - h d), d in [-1,1]^2, i = 1..k (k = 0: u = S[p+d] - h d)
//   keep the u minimizing psi(i) ||N_S(p) - N_E(u)||^2, first one on ties;
//   a u inside the avoid mask costs more than any other (engine/controls/avoid.py).
// LABELS (texture by numbers, engine/controls/labels.py): every candidate's cost
//   also has label_cost(canvas mix at p, exemplar mix at u), and a pixel with a
//   painted share tries one texel of its main label (lab_seeds, picked by hash)
//   after the k-coherence candidates, psi-weighted like the walk's.
// DIRECTION (anisometric, LH06 5; engine/controls/direction.py), coordinates F
//   in 1/256 px, J = J_l(p): diagonal d's three samples come from the immediate
//   neighbors d' in {s, (s.x,0), (0,s.y)}, s the signs of J^-1 d (0 as +1), at
//   F[p+d'] + 256 h d - jmul(J, d', h); the color model's tap d from the neighbor
//   d' = round(J^-1 d) (clamped to [-2, 2]), the same way; a sample reads its
//   nearest texel. Candidates: C^i(nearest texel of F[p+d] - jmul(J, d, h)), with
//   that coordinate's remainder; the label seed keeps none, the walk the best's.
// ATLAS (a mesh's texture atlas, LH06 6): every neighbor read goes through the
//   region's indirection map (common.glsl atlas_texel), so it crosses chart seams.
// All arithmetic is integer (engine/fixed.py), so results are exact.

uniform isampler2D src;       // current state, packed
uniform ivec2 dims;           // scratch size in pixels (multiple of s)
uniform ivec2 qdims;          // dims / s
#ifdef MODEL_APPEARANCE
uniform usampler2D feat;      // A_l, 8 dims packed in 4 (gpu.pack8)
#else
uniform isampler2D feat;      // colors
#endif
uniform usampler2D nbhd;      // N_E, 8 dims packed in 4
uniform isampler2D sim01;     // C^1(u).xy, C^2(u).xy
uniform isampler2D sim23;     // C^3(u).xy, C^4(u).xy
// K: the similarity sets' size k (0..4), a define so the candidate loop unrolls.
uniform int h;
uniform int m;
uniform int shift;
uniform int psi;              // (1 + kappa) in sixteenths
// The projection, row r as P[2r] (dims 0-3) and P[2r+1] (dims 4-7). PROJ_FLOAT (gpu.py
// LevelTextures.proj_exact_in_float): in floats, where every product and partial sum
// is an integer below 2^24, so exact (and on a CPU much cheaper than integer products).
// PROJ_TABLE (the appearance model): the projection per exemplar texel instead
// (gpu.py LevelTextures.table; integers before the shift), summed.
#ifdef PROJ_TABLE
uniform isampler2DArray ptable;
#endif
#ifdef PROJ_FLOAT
#define PVEC vec4
#define PSCALAR float
uniform vec4 P[2 * PROJ_ROWS];
#else
#define PVEC ivec4
#define PSCALAR int
uniform ivec4 P[2 * PROJ_ROWS];
#endif
// TBN10 coherent random walk after the k-coherence candidates: `walk` steps
// around the current best, radius m/2 halved each step (stops below 2), each
// offset from the hash of the pixel's global position (mod the level's period),
// the level, the seed and the subpass. Candidates stay within [border, m-1-border]
// on a non-toroidal exemplar (border < 0: toroidal, wrap).
uniform int walk;
uniform ivec2 origin;         // global level-l position of scratch pixel (0, 0)
uniform int level;
uniform uint walk_seed;       // the synthesis seed mixed with the subpass number
uniform int period;           // n_l, or 0
uniform int border;
uniform usampler2D avoid;     // AVOID: exemplar regions to avoid (controls.ExemplarMask), m x m, 1 = avoid
const uint AVOIDED = 0xfffffffeu;

out ivec4 result;

ivec2 fetch_s(ivec2 p, ivec2 d) {
    return texelFetch(src, NEIGHBOR_TEXEL(p, d), 0).xy;
}

#ifdef DIRECTION
ivec2 fetch_f(ivec2 p, ivec2 d) {
    return full_q8(texelFetch(src, NEIGHBOR_TEXEL(p, d), 0));
}
#endif

// Unpack gpu.pack8: dims 0-3 (lo) and 4-7 (hi) of an 8-dim int16 vector.
void unpack8(uvec4 v, out ivec4 lo, out ivec4 hi) {
    lo = ivec4(v & 0xffffu) - 32768;
    hi = ivec4(v >> 16) - 32768;
}

void add_tap(int row, PSCALAR value, inout PVEC lo, inout PVEC hi) {
    lo += value * P[2 * row];
    hi += value * P[2 * row + 1];
}

// The squared distance (clamped) of gpu.pack8's v from the projected neighborhood,
// given as lo + 32768 and hi + 32768 (the unpacking's offset folded in).
int distance8(uvec4 v, ivec4 lo_b, ivec4 hi_b) {
    ivec4 e0 = ivec4(v & 0xffffu) - lo_b;
    ivec4 e1 = ivec4(v >> 16) - hi_b;
    ivec4 sq = e0 * e0 + e1 * e1;
    return min(sq.x + sq.y + sq.z + sq.w, DIST_CLAMP);
}

#ifdef AVOID
#define AVOIDS(u) (texelFetch(avoid, u, 0).r != 0u)
#else
#define AVOIDS(u) false
#endif

#ifdef PROJ_TABLE
// Diagonal t of the appearance model's neighborhood added to lo, hi from the tables.
#define APPEARANCE_DIAGONAL(t) { \
        ivec2 d = ivec2((t & 1) * 2 - 1, (t >> 1) * 2 - 1); \
        ivec2 u1 = S[(d.y + 1) * 3 + d.x + 1] & wrap;            /* d' = d */ \
        ivec2 u2 = (S[4 + d.x] + ivec2(0, h * d.y)) & wrap;      /* d' = (d.x, 0) */ \
        ivec2 u3 = (S[4 + 3 * d.y] + ivec2(h * d.x, 0)) & wrap;  /* d' = (0, d.y) */ \
        lo += texelFetch(ptable, ivec3(u1, 2 * t), 0) + texelFetch(ptable, ivec3(u2, 2 * t), 0) \
            + texelFetch(ptable, ivec3(u3, 2 * t), 0); \
        hi += texelFetch(ptable, ivec3(u1, 2 * t + 1), 0) + texelFetch(ptable, ivec3(u2, 2 * t + 1), 0) \
            + texelFetch(ptable, ivec3(u3, 2 * t + 1), 0); \
    }
#else
// Diagonal t of the appearance model's neighborhood (DIAGONALS order) added to lo, hi:
// rows 8 t + c (c < 4) take dims c of the three samples' sum, rows 8 t + 4 + c dims 4 + c.
#define APPEARANCE_DIAGONAL(t) { \
        ivec2 d = ivec2((t & 1) * 2 - 1, (t >> 1) * 2 - 1); \
        ivec2 u1 = S[(d.y + 1) * 3 + d.x + 1] & wrap;            /* d' = d */ \
        ivec2 u2 = (S[4 + d.x] + ivec2(0, h * d.y)) & wrap;      /* d' = (d.x, 0) */ \
        ivec2 u3 = (S[4 + 3 * d.y] + ivec2(h * d.x, 0)) & wrap;  /* d' = (0, d.y) */ \
        ivec4 a0, a1, b0, b1, c0, c1; \
        unpack8(texelFetch(feat, u1, 0), a0, a1); \
        unpack8(texelFetch(feat, u2, 0), b0, b1); \
        unpack8(texelFetch(feat, u3, 0), c0, c1); \
        PVEC f0 = PVEC(a0 + b0 + c0), f1 = PVEC(a1 + b1 + c1); \
        lo += f0.x * P[16 * t] + f0.y * P[16 * t + 2] + f0.z * P[16 * t + 4] + f0.w * P[16 * t + 6] \
            + f1.x * P[16 * t + 8] + f1.y * P[16 * t + 10] + f1.z * P[16 * t + 12] + f1.w * P[16 * t + 14]; \
        hi += f0.x * P[16 * t + 1] + f0.y * P[16 * t + 3] + f0.z * P[16 * t + 5] + f0.w * P[16 * t + 7] \
            + f1.x * P[16 * t + 9] + f1.y * P[16 * t + 11] + f1.z * P[16 * t + 13] + f1.w * P[16 * t + 15]; \
    }
#endif

// Tap t of the color model's 5x5 neighborhood (COLOR_TAPS order) added to lo, hi.
#define COLOR_TAP(t) { \
        ivec2 d = ivec2(t % 5 - 2, t / 5 - 2); \
        ivec2 u = (all(lessThanEqual(abs(d), ivec2(1))) ? S[(d.y + 1) * 3 + d.x + 1] : fetch_s(p, d)) & wrap; \
        PVEC col = PVEC(texelFetch(feat, u, 0)); \
        for (int c = 0; c < NCH; ++c) { \
            add_tap(t * NCH + c, col[c], lo, hi); \
        } \
    }

// What the candidates of a pixel are compared with, and the best so far (set by main).
ivec2 S[9];           // 3x3 neighbors, row-major, S[4] = the pixel
ivec4 lo_b, hi_b;     // the projected neighborhood, offset as distance8 takes it
uint best;
ivec2 best_u;
ivec2 best_r;         // DIRECTION: the remainder of the best
#ifdef DIRECTION
ivec2 F9[9];
ivec4 Jp;
#endif
#ifdef LABELS
uint lab_t;
#endif

// The k-coherence candidates from neighbor j (row-major 3x3, j = 4 the pixel itself).
void try_neighbor(const int j) {
    ivec2 d = ivec2(j % 3 - 1, j / 3 - 1);
#ifdef DIRECTION
    ivec4 bq = split_q8(F9[j] - jmul(Jp, d, h), m);
    ivec2 base = bq.xy;
#else
    ivec2 base = (S[j] - h * d) & (m - 1);
#endif
#if K > 0
    ivec4 s01 = texelFetch(sim01, base, 0);
#endif
#if K > 2
    ivec4 s23 = texelFetch(sim23, base, 0);
#endif
    for (int i = 0; i < max(K, 1); ++i) {
#if K == 0
        // No similarity sets: the coherent candidate itself, kept off
        // a non-toroidal exemplar's border band like the walk's.
        ivec2 u = border < 0 ? base : clamp(base, ivec2(border), ivec2(m - 1 - border));
#elif K <= 2
        ivec2 u = i == 0 ? s01.xy : s01.zw;
#else
        ivec2 u = i == 0 ? s01.xy : (i == 1 ? s01.zw : (i == 2 ? s23.xy : s23.zw));
#endif
        uint cost = uint(distance8(texelFetch(nbhd, u, 0), lo_b, hi_b)) * uint(i == 0 ? PSI_ONE : psi);
#ifdef LABELS
        cost += label_cost(lab_t, texelFetch(lab_exemplar, u, 0).r);
#endif
        if (AVOIDS(u)) cost = AVOIDED;
        if (cost < best) {
            best = cost;
            best_u = u;
#ifdef DIRECTION
            best_r = bq.zw;
#endif
        }
    }
}

void main() {
    // Only the block of the active phase is rendered (stages.subpass_draws).
    ivec2 X = ivec2(gl_FragCoord.xy);
    ivec4 here = texelFetch(src, X, 0);
    block_texel = X - boff - active_phase * bstride;
    ivec2 p = block_texel * SUB_S + active_phase;
    int wrap = m - 1;
#ifdef ATLAS
    reader = texelFetch(links, p, 0).x;
#endif

#ifdef DIRECTION
    for (int j = 0; j < 9; ++j) {  // one read a neighbor: its texel and its coordinate
        ivec4 v = j == 4 ? here : texelFetch(src, NEIGHBOR_TEXEL(p, ivec2(j % 3 - 1, j / 3 - 1)), 0);
        S[j] = v.xy;
        F9[j] = full_q8(v);
    }
#else
    for (int j = 0; j < 9; ++j) {
        ivec2 d = ivec2(j % 3 - 1, j / 3 - 1);
        S[j] = j == 4 ? here.xy : fetch_s(p, d);
    }
#endif

    PVEC lo = PVEC(0);
    PVEC hi = PVEC(0);
#ifdef DIRECTION
    Jp = texelFetch(dfield, p, 0);
    if (beyond_exemplar(Jp, h)) {  // grown past the exemplar's pixels: upsampling alone
        result = here;
        return;
    }
#ifdef MODEL_APPEARANCE
    for (int t = 0; t < 4; ++t) {
        ivec2 d = ivec2((t & 1) * 2 - 1, (t >> 1) * 2 - 1);
        ivec2 phi = ivec2(Jp.w * d.x - Jp.y * d.y, Jp.x * d.y - Jp.z * d.x);
        ivec2 sg = ivec2(phi.x >= 0 ? 1 : -1, phi.y >= 0 ? 1 : -1);
        ivec4 a0 = ivec4(0), a1 = ivec4(0);
        for (int i = 0; i < 3; ++i) {
            ivec2 dp = i == 0 ? sg : (i == 1 ? ivec2(sg.x, 0) : ivec2(0, sg.y));
            ivec2 u = nearest_q8(F9[(dp.y + 1) * 3 + dp.x + 1] + 256 * h * d - jmul(Jp, dp, h)) & wrap;
            ivec4 b0, b1;
            unpack8(texelFetch(feat, u, 0), b0, b1);
            a0 += b0;
            a1 += b1;
        }
        PVEC f0 = PVEC(a0), f1 = PVEC(a1);
        for (int c = 0; c < 4; ++c) {
            add_tap(t * 8 + c, f0[c], lo, hi);
            add_tap(t * 8 + 4 + c, f1[c], lo, hi);
        }
    }
#else
    int det = Jp.x * Jp.w - Jp.y * Jp.z;
    for (int t = 0; t < 25; ++t) {
        ivec2 d = ivec2(t % 5 - 2, t / 5 - 2);
        ivec2 num = 8192 * ivec2(Jp.w * d.x - Jp.y * d.y, Jp.x * d.y - Jp.z * d.x) + det;
        ivec2 dp = clamp(ivec2(floor_div(num.x, 2 * det), floor_div(num.y, 2 * det)), ivec2(-2), ivec2(2));
        ivec2 F = all(lessThanEqual(abs(dp), ivec2(1))) ? F9[(dp.y + 1) * 3 + dp.x + 1] : fetch_f(p, dp);
        ivec2 u = nearest_q8(F + 256 * h * d - jmul(Jp, dp, h)) & wrap;
        PVEC col = PVEC(texelFetch(feat, u, 0));
        for (int c = 0; c < NCH; ++c) {
            add_tap(t * NCH + c, col[c], lo, hi);
        }
    }
#endif
#elif defined(MODEL_APPEARANCE)
    // Written out per diagonal: the projection's indices are constants (in a
    // loop the compiler reads the uniform array lane by lane: 1.3x the time).
    APPEARANCE_DIAGONAL(0)
    APPEARANCE_DIAGONAL(1)
    APPEARANCE_DIAGONAL(2)
    APPEARANCE_DIAGONAL(3)
#else
    // COLOR_TAPS order, written out (constant indices, as APPEARANCE_DIAGONAL).
    COLOR_TAP(0) COLOR_TAP(1) COLOR_TAP(2) COLOR_TAP(3) COLOR_TAP(4)
    COLOR_TAP(5) COLOR_TAP(6) COLOR_TAP(7) COLOR_TAP(8) COLOR_TAP(9)
    COLOR_TAP(10) COLOR_TAP(11) COLOR_TAP(12) COLOR_TAP(13) COLOR_TAP(14)
    COLOR_TAP(15) COLOR_TAP(16) COLOR_TAP(17) COLOR_TAP(18) COLOR_TAP(19)
    COLOR_TAP(20) COLOR_TAP(21) COLOR_TAP(22) COLOR_TAP(23) COLOR_TAP(24)
#endif
    lo_b = floor_shift(ivec4(lo), shift) + 32768;
    hi_b = floor_shift(ivec4(hi), shift) + 32768;

    best = 0xffffffffu;
    best_u = here.xy;
    best_r = ivec2(0);
#ifdef LABELS
    lab_t = texelFetch(lab_canvas, p, 0).r;
#endif
    // One call per neighbor with a constant j (constant indices, as in fidelity.frag).
    try_neighbor(0); try_neighbor(1); try_neighbor(2); try_neighbor(3); try_neighbor(4);
    try_neighbor(5); try_neighbor(6); try_neighbor(7); try_neighbor(8);
#ifdef LABELS
    if ((lab_t >> 24) != 0u) {
        ivec2 g = origin + p;
        if (period > 0) g &= period - 1;
        int pick = (hash2(g, level, walk_seed ^ LAB_SEED_SALT).x + 1024) & (SEED_COUNT - 1);
        ivec2 u = texelFetch(lab_seeds, ivec2(pick, int(lab_t & 15u)), 0).xy;
        u = border < 0 ? (u & wrap) : clamp(u, ivec2(border), ivec2(m - 1 - border));
        uint cost = uint(distance8(texelFetch(nbhd, u, 0), lo_b, hi_b)) * uint(psi)
                    + label_cost(lab_t, texelFetch(lab_exemplar, u, 0).r);
        if (AVOIDS(u)) cost = AVOIDED;
        if (cost < best) {
            best = cost;
            best_u = u;
            best_r = ivec2(0);
        }
    }
#endif
    int steps = walk;
#ifdef LABELS
    if ((lab_t >> 24) != 0u) steps = max(steps, LAB_WALK);  // labeled pixels' walk (labels.LABEL_WALK, off)
#endif
    if (steps > 0) {
        ivec2 g = origin + p;
        if (period > 0) g &= period - 1;
        int R = m >> 1;
        for (int t = 0; t < steps && R >= 2; ++t) {
            ivec2 H = hash2(g, level, walk_seed + uint(t) * 0x9E3779B9u);  // in [-1024, 1024)
            ivec2 off = floor_shift(ivec4(H * R, 0, 0), 10).xy;           // in [-R, R)
            ivec2 u = best_u + off;
            u = border < 0 ? (u & wrap) : clamp(u, ivec2(border), ivec2(m - 1 - border));
            uint cost = uint(distance8(texelFetch(nbhd, u, 0), lo_b, hi_b)) * uint(psi);
#ifdef LABELS
            cost += label_cost(lab_t, texelFetch(lab_exemplar, u, 0).r);
#endif
            if (AVOIDS(u)) cost = AVOIDED;
            if (cost < best) {
                best = cost;
                best_u = u;
            }
            R >>= 1;
        }
    }
    result = ivec4(best_u, best_r);
}
