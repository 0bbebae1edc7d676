// One chain of a flowing texture over a window (engine/advect.py
// FlowFrames._chain and renewal_turns): where the static texture T showed each
// pixel's content, its coordinate with the sub-pixel rest as a remainder, and
// the chain's turn: the value of the blob its content lies in.
//
//   e = d - born_frac,  q0 = p - born_px + floor((e + 128) / 256),  rest = e + 128 mod 256 - 128
//   q = q0 + R where the map moves at q0 (R: the chain's key offset), else q0
//   S = T[q] + rest (nearest texel and remainder; wrapped or clamped to the exemplar)

uniform isampler2D path;      // the chain's trajectories over the window plus one, RG32I
uniform isampler2D still;     // T where no key offset applies: coordinates and remainders, RGBA16I
uniform isampler2D still_units;   // their units (exemplar element, patch), RG32I
uniform ivec2 still_origin;   // canvas pixel of their texel (0, 0)
uniform isampler2D moved;     // T where the key offset applies (the same as still if R = 0)
uniform isampler2D moved_units;
uniform ivec2 moved_origin;
uniform isampler2D vmap;      // the velocity map with its border (flow_step.frag), for where it moves
uniform ivec2 map_xy;
uniform ivec2 map_wh;
uniform int has_offset;       // R != 0
uniform ivec2 offset;         // R, px
uniform ivec2 origin;         // canvas pixel of the window's texel (0, 0)
uniform ivec2 born_px;        // V0 t_j = 256 born_px + born_frac
uniform ivec2 born_frac;
uniform int period;           // a toroidal tile's size, 0: none
uniform int m;                // exemplar size
uniform int wrap;             // the exemplar tiles
uniform uint seed;            // renewal_turns' s
uniform int blob;             // BLOB
uniform int nudge;            // UNIT_NUDGE
uniform int want_turns;       // 0: the old chain, whose turns have passed (turn = 0)

layout(location = 0) out ivec4 coords;
layout(location = 1) out int turn;

uint chained(uint h, uint a) {
    return lowbias32(h ^ a);
}

bool moving_at(ivec2 q) {
    ivec2 t = (period > 0 ? (q & (period - 1)) : q) - map_xy;
    if (t.x < 0 || t.y < 0 || t.x >= map_wh.x || t.y >= map_wh.y) {
        return false;
    }
    return any(notEqual(texelFetch(vmap, t + 2, 0).xy, ivec2(0)));
}

const int BLUE_NOISE[256] = int[256](
    16, 159, 220, 57, 150, 91, 135, 105, 12, 224, 112, 27, 218, 10, 246, 44,
    232, 133, 26, 117, 248, 2, 192, 215, 58, 180, 146, 203, 95, 59, 151, 85,
    110, 67, 181, 198, 76, 168, 39, 126, 83, 252, 41, 72, 233, 169, 123, 200,
    172, 40, 236, 98, 47, 142, 231, 178, 17, 157, 119, 3, 138, 29, 241, 14,
    222, 147, 8, 161, 210, 25, 92, 66, 204, 99, 219, 176, 196, 107, 77, 54,
    93, 121, 74, 253, 130, 111, 244, 148, 33, 239, 60, 86, 46, 211, 153, 185,
    22, 213, 191, 30, 61, 183, 5, 193, 124, 162, 24, 134, 237, 7, 131, 245,
    170, 50, 101, 165, 141, 82, 221, 51, 75, 216, 104, 189, 164, 97, 37, 68,
    145, 223, 1, 205, 230, 19, 154, 115, 177, 9, 254, 43, 70, 226, 206, 109,
    250, 79, 129, 55, 114, 94, 249, 31, 207, 90, 152, 120, 15, 140, 179, 13,
    42, 197, 158, 242, 35, 173, 195, 65, 136, 228, 53, 199, 240, 87, 56, 118,
    149, 28, 88, 184, 69, 144, 6, 102, 167, 23, 81, 175, 36, 160, 217, 188,
    235, 106, 209, 11, 127, 238, 212, 45, 247, 128, 214, 108, 132, 20, 100, 71,
    171, 49, 137, 225, 52, 84, 155, 116, 73, 187, 0, 62, 251, 194, 227, 4,
    125, 255, 21, 166, 113, 182, 18, 201, 34, 139, 234, 156, 80, 38, 143, 63,
    186, 78, 96, 202, 32, 229, 64, 243, 163, 89, 48, 190, 122, 174, 103, 208);  // engine/advect.py BLUE_NOISE

void main() {
    ivec2 P = ivec2(gl_FragCoord.xy);
    ivec2 e = texelFetch(path, P, 0).xy - born_frac;
    ivec2 k = floor_shift(ivec4(e + 128, 0, 0), 8).xy;
    ivec2 rest = e - k * 256;
    ivec2 q = origin + P - born_px + k;
    bool apart = has_offset != 0 && moving_at(q);
    if (apart) {
        q += offset;
    }
    if (period > 0) {
        q &= period - 1;
    }
    ivec4 t = apart ? texelFetch(moved, q - moved_origin, 0) : texelFetch(still, q - still_origin, 0);
    ivec2 unit = apart ? texelFetch(moved_units, q - moved_origin, 0).xy : texelFetch(still_units, q - still_origin, 0).xy;
    ivec2 F = t.xy * 256 + t.zw + rest;
    ivec2 u = floor_shift(ivec4(F + 128, 0, 0), 8).xy;
    coords = ivec4(wrap != 0 ? (u & (m - 1)) : clamp(u, ivec2(0), ivec2(m - 1)), F - u * 256);

    if (want_turns == 0) {
        turn = 0;
        return;
    }
    // The blob (renewal_turns): the nearest of one jittered point per blob x blob px
    // to the position nudged by the unit's hash.
    uint hu = chained(chained(lowbias32(seed), uint(unit.x)), uint(unit.y));
    uint n = uint(2 * nudge + 1);
    ivec2 pp = q + ivec2(int(hu % n), int((hu >> 8) % n)) - nudge;
    ivec2 c = (pp - (pp & (blob - 1))) / blob;  // floor(pp / blob), exact near +-2^31 too
    int best = 0x7fffffff;
    uint value = 0u;
    uint gseed = seed ^ 0x5BD1E995u;
    uint phase = lowbias32(gseed);
    int ox = int(phase & 15u), oy = int((phase >> 4) & 15u);  // where the chain's table starts
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            ivec2 gc = c + ivec2(dx, dy);
            ivec2 hc = period > 0 ? (gc & (period / blob - 1)) : gc;
            uint g = chained(chained(lowbias32(gseed), uint(hc.x)), uint(hc.y));
            ivec2 s = gc * blob + ivec2(int(g % uint(blob)), int((g >> 8) % uint(blob)));
            ivec2 dd = pp - s;
            int dist = dd.x * dd.x + dd.y * dd.y;
            if (dist < best) {
                best = dist;
                // Stratified turns (renewal_turns): the cell's blue-noise rank, a hash below it.
                value = (uint(BLUE_NOISE[((hc.y + oy) & 15) * 16 + ((hc.x + ox) & 15)]) << 8) | (g >> 24);
            }
        }
    }
    turn = int(value);
}
