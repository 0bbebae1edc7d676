// Upsample + jitter (LH05 3.1-3.2) of one padded region of level l into a
// quadrant-packed scratch buffer:
//   S_l[p] = (S_{l-1}[q] + floor(h (D - 1/2)) + J_l(p)) mod m,  D = p - 2q,
//   J_l(p) = floor(h H(p, l, seed) r_l M_l(p) + 1/2),
// q the parent texel: floor(p/2) as in LH05 (D in {0, 1}), or per axis at random
// the nearest other one (D in {-1, 2}; common.glsl parent_step): the same
// coordinate inside a coherent patch, a side taken at random at a seam.
// M_l(p) the product of the randomness fields over the exemplar (read at the
// upsampled coordinate, min-mipmapped) and over the canvas (engine/controls/fields.py);
// the effective r_l M_l(p) is clamped to 1. Fields are 1/32768ths (neutral 32768).
// Level 0 starts from the exemplar centre m/2 (the upsampled S_{-1} = 0).
// With a period n_l (toroidal output), jitter and child offsets use p mod n_l.
// On lattice levels (near-regular exemplars) J is quantized to whole cells.
// DIRECTION (anisometric, LH06 5; engine/controls/direction.py): in 1/256 px,
//   F_l[p] = F_{l-1}[q] + child_offset_q8(J_l(p), D, h) + jitter_q8(J_l(p), Jit_l(p)),
// the child offset floor(J_l(p) h (2D - 1) / 32), less 128 at h = 1 (with J = I
// exactly the integer rule); the jitter is scaled with the texture by a power of
// two (common.glsl jitter_q8: grown s times, about s times less in exemplar
// pixels, as much in its own texels; a turn leaves it as it is), and none (each
// child from its own parent, q = floor(p/2)) where the level is grown past the exemplar's pixels
// (common.glsl beyond_exemplar: magnification adds no detail); the randomness over the exemplar is read at the
// nearest texel of the upsampled coordinate; a placed feature sets a whole texel.
// ATLAS (a mesh's texture atlas, LH06 6): the parent texel q is read
// through the parent level's indirection map for the pixel's chart (common.glsl).

uniform isampler2D parent;      // level l-1, persistent buffer (toroidal addressing)
uniform ivec2 parent_anchor;    // texel = (g - anchor) & mask
uniform ivec2 parent_mask;
uniform int has_parent;
uniform ivec2 origin;           // global level-l position of scratch pixel (0, 0)
uniform ivec2 qdims;            // quadrant size: scratch size / s
uniform int h;
uniform int m;
uniform int level;
uniform uint seed;
uniform int rq;                 // r_l in 1024ths
uniform int period;             // n_l (a power of two), or 0 for the infinite canvas
uniform int has_efield;         // randomness over the exemplar
uniform usampler2D efield;      // R_E,l: (m >> eshift)^2, uint16
uniform int eshift;             // L - l
uniform int has_cfield;         // randomness over the canvas
uniform usampler2D cfield;      // R_S,l over this scratch region (row-major local pixels), uint16
uniform ivec2 lattice_shift;    // lattice level (LH05 4.5): log2 of the cell (cx, cy); else (-1, -1)
uniform int dithered;           // the parent chosen at random per axis (common.glsl parent_step)
#ifdef ATLAS
uniform isampler2D plinks;      // the parent level's indirection map over region.parents()
uniform ivec2 plink_origin;     // its level-(l-1) position of texel (0, 0)

ivec2 parent_texel(ivec2 gp) {
    ivec4 L = texelFetch(plinks, gp - plink_origin, 0);
    return (reader >= 0 && L.x != reader && L.y == reader) ? L.zw : gp;
}
#else
ivec2 parent_texel(ivec2 gp) {
    return gp;
}
#endif

out ivec4 result;

void main() {
    ivec2 X = ivec2(gl_FragCoord.xy) - boff;
    ivec2 phase = X / bstride;
    ivec2 inblock = X - phase * bstride;
    if (any(greaterThanEqual(inblock, qdims))) {  // between blocks (stages.block_layout)
        result = ivec4(0);
        return;
    }
    ivec2 local = inblock * SUB_S + phase;
    ivec2 g = origin + local;
    ivec2 gm = period > 0 ? (g & (period - 1)) : g;
#ifdef ATLAS
    reader = texelFetch(links, local, 0).x;
#endif
    ivec2 u;
#ifdef DIRECTION
    ivec2 F;
    if (has_parent != 0) {
        ivec4 Jp = texelFetch(dfield, local, 0);
        // grown past the exemplar: magnified alone, each texel's children from it
        ivec2 e = beyond_exemplar(Jp, h) ? ivec2(0) : parent_step(gm, level, seed, dithered);
        ivec2 t = (parent_texel((g - (g & 1)) / 2 + e) - parent_anchor) & parent_mask;
        ivec2 v = h * (2 * ((gm & 1) - 2 * e) - 1);
        ivec2 off = floor_shift(ivec4(Jp.x * v.x + Jp.y * v.y, Jp.z * v.x + Jp.w * v.y, 0, 0), 5).xy - (h == 1 ? 128 : 0);
        F = full_q8(texelFetch(parent, t, 0)) + off;
    } else {
        F = ivec2(m / 2 * 256);
    }
    u = split_q8(F, m).xy;
#else
    if (has_parent != 0) {
        ivec2 e = parent_step(gm, level, seed, dithered);  // q = floor(g / 2) + e, D = (g mod 2) - 2 e
        ivec2 t = (parent_texel((g - (g & 1)) / 2 + e) - parent_anchor) & parent_mask;  // exact division
        u = texelFetch(parent, t, 0).xy + ((gm & 1) - 2 * e) * h - ((h + 1) >> 1);
    } else {
        u = ivec2(m / 2);
    }
#endif
    int r = rq;
    if (has_efield != 0 || has_cfield != 0) {
        uint E = has_efield != 0 ? texelFetch(efield, (u & (m - 1)) >> eshift, 0).r : 32768u;
        uint C = has_cfield != 0 ? texelFetch(cfield, local, 0).r : 32768u;
        r = modulated_rq(rq, E, C);
    }
    ivec2 H = hash2(gm, level, seed);
    ivec2 J = ((h * H * r + (1 << 19) + SHIFT_BIAS) >> 20) - (SHIFT_BIAS >> 20);
    if (lattice_shift.x >= 0) {  // whole cells: J' = c floor(J / c + 1/2)
        ivec2 half_cell = (ivec2(1) << lattice_shift) >> 1;
        J = (((J + half_cell + SHIFT_BIAS) >> lattice_shift) - (ivec2(SHIFT_BIAS) >> lattice_shift)) << lattice_shift;
    }
#ifdef DIRECTION
    ivec4 Jh = texelFetch(dfield, local, 0);
    ivec2 Fj = F + (beyond_exemplar(Jh, h) ? ivec2(0) : jitter_q8(Jh, J));  // scaled with the texture
#endif
#if defined(ATLAS)
    result = apply_features_atlas(g, split_q8(Fj, m), h, m, reader);
#elif defined(DIRECTION)
    ivec4 q = split_q8(Fj, m);
    bool hit = false;
    ivec2 s = apply_features_hit(g, q.xy, h, m, period, hit);
    result = ivec4(s, hit ? ivec2(0) : q.zw);
#else
    result = ivec4(apply_features(g, (u + J) & (m - 1), h, m, period), 0, 0);
#endif
}
