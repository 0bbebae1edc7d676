// One subpass of the fidelity stage: discrete texture optimization over whole
// patches (Kwatra et al. 2005, Han et al. 2006), on a quadrant-packed scratch
// buffer. Only the block of phase `active_phase` is rendered (pyramid.py
// _subpasses); each of its pixels p, with N(q) = E_l[S[q]] (8-bit colors), takes
//   among the candidates u: S[p] itself, then the predictions of its 8 neighbors
//     S[p + d] - h d (row-major), then FID_SEARCH random samples around the best
//     so far (radius m/4 halved each step, below 2 stops; offsets hashed from the
//     global position mod the period, the level, the seed and the subpass),
//   the first of least cost(u) = sum over d in [-R, R]^2, d != 0, of
//     ||N(p + d) - E_l[u + h d]||^2   (a u inside the avoid mask: never better).
// On a non-toroidal exemplar (border >= 0) predictions and samples are clamped
// to [border, m-1-border] and exemplar patches read clamped to [0, m-1]; on
// lattice levels (no_search = 1) only the predictions are tried.
// LABELS (engine/controls/labels.py): cost(u) also has label_cost(canvas mix at
// p, exemplar mix at u).
// DIRECTION (anisometric; engine/controls/direction.py): coordinates F in 1/256
// px and J = J_l(p): the patch of u reads the nearest texels of
// u + jmul(J, d, h), predictions are F[p + d] - jmul(J, d, h), random samples move
// the best by whole pixels, and candidates are kept inside (wrapped, or clamped
// to [256 border, 256 (m-1-border)]) in 1/256 px; tried, avoid and labels as
// without, at the candidate's nearest texel.
// UPRIGHT / TILTED (with DIRECTION; stages.fidelity_draws): a search subpass
// with a direction field is up to two draws into the same block, each
// discarding the other's pixels: UPRIGHT takes those where J_l(p) = I (where
// no field is painted), whose taps u + jmul(I, d, h) are the nearest texel of
// u plus h d exactly, so it reads the row taps (ROW_TAPS) of that texel
// (wrapped, or clamped into [0, m-1]: candidates are kept inside, so a no-op)
// at a fraction of the fetches; TILTED the others, drawn over their box only.
// The same results as one draw; one shader holding both ways was too large for
// llvmpipe's compiler (minutes for 7 x 7 patches).
// VOTE (FID_VOTE; SynthParams.fidelity_vote, Kwatra et al. 2005's voting step
// on coordinates): the odd passes of the stage rewrite each pixel p of the block
// with, among S[p] and then its 8 neighbors' predictions (row-major), the first
// that the most of the (2 R + 1)^2 predictions P(d) = S[p + d] - h d (P(0) = S[p],
// wrapped like them on a toroidal exemplar;
// DIRECTION: F[p + d] - jmul(J, d, h)) equal exactly. On a non-toroidal exemplar
// a prediction outside [border, m-1-border] (in 1/256 px with DIRECTION) neither
// votes nor is a candidate: clamped into the range, such predictions would agree
// by accident and stretch the exemplar's border rows. A candidate
// in the avoid mask is never taken, nor (LABELS) one with a higher label cost
// than S[p]'s. No colors are read: seams move to where the larger copy wins and
// stray pixels inside a copy go back to it, without pulling colors to a mean
// (a vote on the mean color grows flat areas: docs/benchmarks.md).
// Integer sums (at most 4 * 255^2 * 120 < 2^25), so the result is exact; skipping
// a candidate already tried and stopping a sum once it reaches the best cannot
// change it (costs only grow as taps are added, and ties keep the first). The
// sum runs row by row with constant bounds, checked once a row: on llvmpipe
// that is 25% faster than one loop over the taps checked at each.

uniform isampler2D src;       // current state, packed
uniform usampler2D colors;    // E_l as engine/fixed.py quantized_colors, FID_NCH 8-bit channels, m x m
uniform ivec2 dims;
uniform ivec2 qdims;
uniform int h;
uniform int m;
uniform int border;           // < 0: toroidal exemplar
uniform ivec2 origin;         // global level-l position of scratch pixel (0, 0)
uniform int level;
uniform int period;           // n_l, or 0
uniform uint search_seed;     // engine/fixed.py fidelity_seed
uniform int no_search;
uniform usampler2D avoid;     // AVOID: exemplar regions to avoid, m x m, 1 = avoid

const int R = FID_RADIUS;
const int SIDE = 2 * R + 1;
const int NT = SIDE * SIDE;
const int NCAND = 9 + FID_SEARCH;
const uint AVOIDED = 0xfffffffeu;

out ivec4 result;

#ifdef AVOID
#define AVOIDS(u) (texelFetch(avoid, u, 0).r != 0u)
#else
#define AVOIDS(u) false
#endif

ivec2 fetch_s(ivec2 p, ivec2 d) {
    return texelFetch(src, NEIGHBOR_TEXEL(p, d), 0).xy;
}

ivec2 exemplar_tap(ivec2 u) {
    return border < 0 ? (u & (m - 1)) : clamp(u, ivec2(0), ivec2(m - 1));
}

ivec2 keep_inside(ivec2 u) {
    return border < 0 ? (u & (m - 1)) : clamp(u, ivec2(border), ivec2(m - 1 - border));
}

#ifdef DIRECTION
ivec4 Jp;            // J_l(p)
ivec2 col0, col1;    // h J (1, 0) and h J (0, 1), Q12

ivec2 tap_of(ivec2 F, int dx, int dy) {
    return exemplar_tap(nearest_q8(F + floor_shift(ivec4(dx * col0 + dy * col1, 0, 0), 4).xy));
}

#ifdef UPRIGHT
// The texel whose row taps are F's where J = I (see UPRIGHT above).
ivec2 upright_texel(ivec2 F) {
    ivec2 n = nearest_q8(F);
    return border < 0 ? (n & (m - 1)) : clamp(n, ivec2(0), ivec2(m - 1));
}
#endif

ivec2 texel_of(ivec2 F) {
    return nearest_q8(F) & (m - 1);
}

ivec2 keep_c(ivec2 F) {
    return border < 0 ? (F & (256 * m - 1)) : clamp(F, ivec2(256 * border), ivec2(256 * (m - 1 - border)));
}

ivec2 raw_prediction(ivec2 p, ivec2 d) {
    return full_q8(texelFetch(src, NEIGHBOR_TEXEL(p, d), 0)) - jmul(Jp, d, h);
}

ivec2 step_of(ivec2 off) {
    return off * 256;
}
#else
ivec2 tap_of(ivec2 u, int dx, int dy) {
    return exemplar_tap(u + h * ivec2(dx, dy));
}

ivec2 texel_of(ivec2 u) {
    return u;
}

ivec2 keep_c(ivec2 u) {
    return keep_inside(u);
}

ivec2 raw_prediction(ivec2 p, ivec2 d) {
    return fetch_s(p, d) - h * d;
}

ivec2 step_of(ivec2 off) {
    return off;
}
#endif

ivec2 predict(ivec2 p, ivec2 d) {
    return keep_c(raw_prediction(p, d));
}

uint nb[NT];  // N(p + d), FID_NCH bytes packed (r in the low byte), row-major over the patch (the centre unused)

// Only the exemplar's channels are read and compared (FID_NCH, 1 to 4).
uint pack_color(uvec4 c) {
#if FID_NCH == 1
    return c.r;
#elif FID_NCH == 2
    return c.r | (c.g << 8);
#elif FID_NCH == 3
    return c.r | (c.g << 8) | (c.b << 16);
#else
    return c.r | (c.g << 8) | (c.b << 16) | (c.a << 24);
#endif
}

// ||a - c||^2 over the channels, a packed by pack_color.
uint color_distance(uint a, uvec4 c) {
#if FID_NCH == 1
    int e = int(a) - int(c.r);
    return uint(e * e);
#elif FID_NCH == 2
    ivec2 e = ivec2(a & 0xffu, a >> 8) - ivec2(c.rg);
    return uint(e.x * e.x + e.y * e.y);
#elif FID_NCH == 3
    ivec3 e = ivec3((uvec3(a) >> uvec3(0u, 8u, 16u)) & 0xffu) - ivec3(c.rgb);
    ivec3 sq = e * e;
    return uint(sq.x + sq.y + sq.z);
#else
    ivec4 e = ivec4((uvec4(a) >> uvec4(0u, 8u, 16u, 24u)) & 0xffu) - ivec4(c);
    ivec4 sq = e * e;
    return uint(sq.x + sq.y + sq.z + sq.w);
#endif
}

#ifdef ROW_TAPS
// Without a direction field a patch row's taps lie along an exemplar row, h
// apart: rowtaps (gpu.py LevelTextures.row_taps) holds at (x, y) the taps
// E_l[tap(x + h (i - R)), y], i = 0..2R, packed TAP_BYTES each (the channels,
// pack_color) TPU to a uint, so one fetch serves a row (or two or three for
// larger patches and colors). N(p + d) is packed the same way (nbrow).
#define FID_SIDE (2 * FID_RADIUS + 1)
#if FID_NCH >= 3
#define TAP_BYTES 4
#define TAP_MASK 0xffffffffu
#else
#define TAP_BYTES FID_NCH
#define TAP_MASK ((1u << (8 * FID_NCH)) - 1u)
#endif
#define TPU (4 / TAP_BYTES)
#define ROW_UINTS ((FID_SIDE + TPU - 1) / TPU)
#define ROW_TEXELS ((ROW_UINTS + 3) / 4)
uniform usampler2DArray rowtaps;
uint nbrow[FID_SIDE * ROW_UINTS];

// ||a - b||^2 over the channels of two packed taps.
uint tap_distance(uint a, uint b) {
#if FID_NCH == 1
    int e = int(a) - int(b);
    return uint(e * e);
#elif FID_NCH == 2
    ivec2 e = ivec2(a & 0xffu, a >> 8) - ivec2(b & 0xffu, b >> 8);
    return uint(e.x * e.x + e.y * e.y);
#elif FID_NCH == 3
    ivec3 e = ivec3((uvec3(a) >> uvec3(0u, 8u, 16u)) & 0xffu) - ivec3((uvec3(b) >> uvec3(0u, 8u, 16u)) & 0xffu);
    ivec3 sq = e * e;
    return uint(sq.x + sq.y + sq.z);
#else
    ivec4 e = ivec4((uvec4(a) >> uvec4(0u, 8u, 16u, 24u)) & 0xffu) - ivec4((uvec4(b) >> uvec4(0u, 8u, 16u, 24u)) & 0xffu);
    ivec4 sq = e * e;
    return uint(sq.x + sq.y + sq.z + sq.w);
#endif
}

// Tap i of the row (written out: constant indices); the centre adds 0.
#define ROW_TAP(i) { \
        uint a_ = (w[((i) / TPU) >> 2][((i) / TPU) & 3] >> (8 * TAP_BYTES * ((i) % TPU))) & TAP_MASK; \
        uint b_ = (nbrow[base + (i) / TPU] >> (8 * TAP_BYTES * ((i) % TPU))) & TAP_MASK; \
        cost += ((i) == R && dy == 0) ? 0u : tap_distance(a_, b_); \
    }

// The patch cost row by row, giving up once a row brings it to the best.
uint row_patch_cost(ivec2 u, uint limit) {
    uint cost = 0u;
    for (int dy = -R; dy <= R; ++dy) {
        int ty = border < 0 ? ((u.y + h * dy) & (m - 1)) : clamp(u.y + h * dy, 0, m - 1);
        uvec4 w[ROW_TEXELS];
        for (int k = 0; k < ROW_TEXELS; ++k) {
            w[k] = texelFetch(rowtaps, ivec3(u.x, ty, k), 0);
        }
        int base = (dy + R) * ROW_UINTS;
        ROW_TAP(0) ROW_TAP(1) ROW_TAP(2) ROW_TAP(3) ROW_TAP(4)
#if FID_SIDE > 5
        ROW_TAP(5) ROW_TAP(6)
#endif
#if FID_SIDE > 7
        ROW_TAP(7) ROW_TAP(8)
#endif
#if FID_SIDE > 9
        ROW_TAP(9) ROW_TAP(10)
#endif
        if (cost >= limit) return limit;  // cannot win: stop early
    }
    return cost;
}
#ifdef UPRIGHT
#define patch_cost(F, limit) row_patch_cost(upright_texel(F), limit)
#else
#define patch_cost(u, limit) row_patch_cost(u, limit)
#endif
#else
// The patch cost row by row, giving up once a row brings it to the best (the centre adds 0).
uint patch_cost(ivec2 u, uint limit) {
    uint cost = 0u;
    for (int dy = -R; dy <= R; ++dy) {
        for (int dx = -R; dx <= R; ++dx) {
            int t = (dy + R) * SIDE + dx + R;
            uint e = color_distance(nb[t], texelFetch(colors, tap_of(u, dx, dy), 0));
            cost += t == NT / 2 ? 0u : e;
        }
        if (cost >= limit) return limit;  // cannot win: stop early
    }
    return cost;
}
#endif

#ifdef FID_VOTE
// What the vote compares: coordinates (DIRECTION: in 1/256 px), or without a
// direction field a texel (x, y), both in [0, 2^15), as one int x | y << 16, so
// that a vote is one comparison. A clamped prediction (VKEY_NONE) matches no candidate.
#ifdef DIRECTION
#define VKEY ivec2
#define VKEY_OF(u) (u)
#define VKEY_NONE(t) ivec2(-1 - (t))
#define VKEY_VALID(k) ((k).x >= 0)
#define VKEY_COORD(k) (k)
#else
#define VKEY int
#define VKEY_OF(u) ((u).x | ((u).y << 16))
#define VKEY_NONE(t) (-1)
#define VKEY_VALID(k) ((k) >= 0)
#define VKEY_COORD(k) ivec2((k) & 0xffff, (k) >> 16)
#endif

void main() {
    // Only the block of the active phase is rendered (stages.subpass_draws).
    ivec2 X = ivec2(gl_FragCoord.xy);
    ivec4 here = texelFetch(src, X, 0);
    block_texel = X - boff - active_phase * bstride;
    ivec2 p = block_texel * SUB_S + active_phase;
#ifdef ATLAS
    reader = texelFetch(links, p, 0).x;
#endif
#ifdef DIRECTION
    Jp = texelFetch(dfield, p, 0);
    if (beyond_exemplar(Jp, h)) {  // grown past the exemplar's pixels: upsampling alone
        result = here;
        return;
    }
    ivec2 self = full_q8(here);
    if (border < 0) self = keep_c(self);  // wrapped like the predictions (a stored texel 0 may hold F < 0)
#else
    ivec2 self = here.xy;
#endif
    VKEY P[NT];
    for (int ty = 0; ty < SIDE; ++ty) {
        for (int tx = 0; tx < SIDE; ++tx) {
            int t = ty * SIDE + tx;
            ivec2 raw = raw_prediction(p, ivec2(tx - R, ty - R));
            ivec2 kept = keep_c(raw);
            // A prediction kept inside by clamping does not vote: clamped ones would agree by accident.
            P[t] = t == NT / 2 ? VKEY_OF(self) : (border < 0 || kept == raw ? VKEY_OF(kept) : VKEY_NONE(t));
        }
    }
#ifdef LABELS
    uint lab_t = texelFetch(lab_canvas, p, 0).r;
    uint lab_self = label_cost(lab_t, texelFetch(lab_exemplar, texel_of(self), 0).r);
#endif
    int most = -1;
    VKEY best = VKEY_OF(self);
    for (int j = -1; j < 9; ++j) {
        if (j == 4) continue;
        VKEY u = j < 0 ? VKEY_OF(self) : P[(j / 3 + R - 1) * SIDE + j % 3 + R - 1];
        if (!VKEY_VALID(u)) continue;  // clamped
        ivec2 ut = texel_of(VKEY_COORD(u));
        if (AVOIDS(ut)) continue;
#ifdef LABELS
        if (label_cost(lab_t, texelFetch(lab_exemplar, ut, 0).r) > lab_self) continue;
#endif
        int votes = 0;
        for (int ty = 0; ty < SIDE; ++ty) {  // rows of at most 11 unroll; a loop of NT would not
            for (int tx = 0; tx < SIDE; ++tx) {
                votes += P[ty * SIDE + tx] == u ? 1 : 0;
            }
        }
        if (votes > most) {
            most = votes;
            best = u;
        }
    }
#ifdef DIRECTION
    result = split_q8(VKEY_COORD(best), m);
#else
    result = ivec4(VKEY_COORD(best), 0, 0);
#endif
}
#else
ivec2 cand[NCAND + 1];  // cand[0]: S[p]; cand[j + 1]: candidate j (S[p] again where there is none)
uint best;               // the least cost so far, and its candidate
ivec2 best_u;
ivec2 pix;               // the pixel p
#ifdef LABELS
uint lab_t;
#endif

// Candidate j (j < 9: the prediction of neighbor j, row-major, 4 being p
// itself; j >= 9: random sample j - 9 around the best so far), kept when its
// cost is below the best. One already tried costs the same again: skipped.
void try_candidate(const int j) {
    ivec2 u;
    if (j < 9) {
        if (j == 4) {
            cand[j + 1] = cand[0];
            return;
        }
        u = predict(pix, ivec2(j % 3 - 1, j / 3 - 1));
    } else {
        int Rs = (m >> 2) >> (j - 9);
        if (no_search != 0 || Rs < 2) {  // (then no later sample is tried either)
            cand[j + 1] = cand[0];
            return;
        }
        ivec2 g = origin + pix;
        if (period > 0) g &= period - 1;
        ivec2 H = hash2(g, level, search_seed + uint(j - 9) * 0x9E3779B9u);  // in [-1024, 1024)
        u = keep_c(best_u + step_of(floor_shift(ivec4(H * Rs, 0, 0), 10).xy));  // offset in [-Rs, Rs)
    }
    cand[j + 1] = u;
    bool seen = false;
    for (int i = 0; i <= j; ++i) {
        seen = seen || cand[i] == u;
    }
    if (seen) return;  // the same cost again: it cannot be better
    ivec2 ut = texel_of(u);
    if (AVOIDS(ut)) return;
#ifdef LABELS
    uint lc = label_cost(lab_t, texelFetch(lab_exemplar, ut, 0).r);
    if (lc >= best) return;  // cannot win
    uint c = lc + patch_cost(u, best - lc);
#else
    uint c = patch_cost(u, best);
#endif
    if (c < best) {
        best = c;
        best_u = u;
    }
}

void main() {
    // Only the block of the active phase is rendered (stages.subpass_draws).
    ivec2 X = ivec2(gl_FragCoord.xy);
    ivec4 here = texelFetch(src, X, 0);
    block_texel = X - boff - active_phase * bstride;
    ivec2 p = block_texel * SUB_S + active_phase;
#ifdef ATLAS
    reader = texelFetch(links, p, 0).x;  // reads cross chart seams (common.glsl atlas_texel)
#endif
#ifdef DIRECTION
    Jp = texelFetch(dfield, p, 0);
#ifdef UPRIGHT
    if (Jp != ivec4(4096, 0, 0, 4096)) discard;  // TILTED's draw writes it
#elif defined(TILTED)
    if (Jp == ivec4(4096, 0, 0, 4096)) discard;  // UPRIGHT's draw writes it
#endif
#endif
#ifdef ROW_TAPS
    for (int k = 0; k < FID_SIDE * ROW_UINTS; ++k) {
        nbrow[k] = 0u;
    }
#endif
    for (int ty = 0; ty < SIDE; ++ty) {  // nested: a loop of NT would not unroll
        for (int tx = 0; tx < SIDE; ++tx) {
            int t = ty * SIDE + tx;
            ivec2 d = ivec2(tx - R, ty - R);
#ifdef ROW_TAPS
            int i = d.x + R;
            uint c = t == NT / 2 ? 0u : pack_color(texelFetch(colors, fetch_s(p, d), 0));
            nbrow[(d.y + R) * ROW_UINTS + i / TPU] |= c << (8 * TAP_BYTES * (i % TPU));
#else
            nb[t] = t == NT / 2 ? 0u : pack_color(texelFetch(colors, fetch_s(p, d), 0));
#endif
        }
    }
#ifdef DIRECTION
    if (beyond_exemplar(Jp, h)) {  // grown past the exemplar's pixels: upsampling alone (never upright)
        result = here;
        return;
    }
    col0 = h * Jp.xz;
    col1 = h * Jp.yw;
    best_u = full_q8(here);  // a coordinate in 1/256 px
#else
    best_u = here.xy;
#endif
    pix = p;
    ivec2 bt = texel_of(best_u);
#ifdef LABELS
    lab_t = texelFetch(lab_canvas, p, 0).r;
    best = (AVOIDS(bt)) ? AVOIDED
         : label_cost(lab_t, texelFetch(lab_exemplar, bt, 0).r) + patch_cost(best_u, 0xffffffffu);
#else
    best = (AVOIDS(bt)) ? AVOIDED : patch_cost(best_u, 0xffffffffu);
#endif
    cand[0] = best_u;
    // One call per candidate with a constant j: every index is then a constant
    // (in a loop, llvmpipe reads and writes such arrays lane by lane).
    try_candidate(0); try_candidate(1); try_candidate(2); try_candidate(3); try_candidate(4);
    try_candidate(5); try_candidate(6); try_candidate(7); try_candidate(8);
#if FID_SEARCH > 0
    try_candidate(9);
#endif
#if FID_SEARCH > 1
    try_candidate(10);
#endif
#if FID_SEARCH > 2
    try_candidate(11);
#endif
#if FID_SEARCH > 3
    try_candidate(12);
#endif
#if FID_SEARCH > 4
#error "fidelity.frag: write out the calls for FID_SEARCH > 4"
#endif
#ifdef DIRECTION
    result = split_q8(best_u, m);
#else
    result = ivec4(best_u, 0, 0);
#endif
}
#endif
