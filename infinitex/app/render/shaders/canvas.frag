// Draw one pyramid level's synthesized coordinates onto the canvas.
//
// Screen pixel q (origin at the canvas' top-left, y down) shows finest-level
// canvas position tl_i + tl_f + (q + 0.5) / zoom. At level l = L - k that is
// the continuous level position base + frac, with the integer part kept
// exact for far-away origins. Texels outside [vlo, vhi) are left to the
// coarser level drawn before (progressive refinement).
//
// Compiled per draw kind (canvas.py): MODE (0 color, 1 coords, 2 patches,
// 3 level, 4 relief, 5 lit), MAG (0 texel fetch, 1 synthesis magnification
// from the stack, 2 from the hi-res exemplar), ALPHA (draw on a checkerboard)
// and SHAPE_KIND (lit: 0 normal map, 1 height); DIRECTION (a direction field:
// coordinates carry 1/256 px remainders, drawn bilinearly, and magnification
// extrapolates through each texel's Jacobian J, engine/controls/direction.py). llvmpipe runs the branches
// of a uniform condition anyway: one program for all cost 9x for exact texels.

uniform isampler2D coords;    // level buffer: texel of position g is (g - anchor) & cmask
uniform ivec2 anchor;
uniform ivec2 cmask;
uniform ivec2 vlo;
uniform ivec2 vhi;
uniform ivec2 tl_i;
uniform vec2 tl_f;
uniform float zoom;
uniform vec4 geom;            // screen px -> finest-level canvas px: (a, b, c, d) = [[a, b], [c, d]];
                              // (1/zoom, 0, 0, 1/zoom), or a lattice's map to the rectified canvas
uniform int k;                // L - l: one level texel is 2^k finest pixels
uniform int m;                // exemplar size
uniform int layer;            // stack layer (= level)
uniform int mag_layer;        // stack layer sampled by magnification (the view's level: a coarse
                              // level standing in during refinement still shows sharp texture)
uniform sampler2DArray stack; // uint8 Gaussian stack, RGBA
uniform sampler2D hires;      // high-resolution exemplar (mipmapped)
uniform sampler2DArray shape; // "lit": the normal map (encoded, rgb) or height (r) stack, half floats
uniform vec3 light;           // unit vector towards the light (x right, y up, z out of the surface)
uniform float relief;         // height: finest-level pixels of relief for the full [0, 1] range; normals: tilt gain
uniform int toroidal;
uniform float relief_strength;

out vec4 color;
#ifdef FEATHER
uniform vec4 feather;         // a quick look's patch (x0, y0, x1, y1, level texels): drawn over the level,
uniform float feather_w;      // its opacity rising over feather_w texels from its edges (no hard seam)
#endif

ivec2 S(ivec2 g) {
    g = clamp(g, vlo, vhi - 1);
    return texelFetch(coords, (g - anchor) & cmask, 0).xy;
}

#ifdef DIRECTION
uniform isampler2D jfield;    // J of this level over [jorigin, jorigin + jdims), Q12
uniform ivec2 jorigin;
uniform ivec2 jdims;

// The coordinate with its sub-pixel remainder.
vec2 Sf(ivec2 g) {
    g = clamp(g, vlo, vhi - 1);
    ivec4 v = texelFetch(coords, (g - anchor) & cmask, 0);
    return vec2(v.xy) + vec2(v.zw) / 256.0;
}

mat2 Jm(ivec2 g) {
    ivec4 j = texelFetch(jfield, clamp(g - jorigin, ivec2(0), jdims - 1), 0);
    return mat2(float(j.x), float(j.z), float(j.y), float(j.w)) / 4096.0;  // columns J e_x, J e_y
}
#endif

vec4 fetch(ivec2 u) {
    return texelFetch(stack, ivec3(u, layer), 0);
}

float luma(vec4 c) {
    return dot(c.rgb, vec3(0.2126, 0.7152, 0.0722));
}

vec3 hue(uint h) {
    h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;
    vec3 c = vec3(float(h & 255u), float((h >> 8) & 255u), float((h >> 16) & 255u)) / 255.0;
    return 0.35 + 0.65 * c;
}

bool coherent(ivec2 g, ivec2 e) {
    int h = 1 << k;
    ivec2 d = S(g + e) - S(g) - h * e;
    if (toroidal != 0) d = d & (m - 1);
    return d == ivec2(0);
}

// LH05 section 5: extrapolate each of the 4 nearest texels' coordinates to
// this point, sample there, blend bilinearly. A corner's position is first
// pulled towards the corners that nearly agree with it (at most one texel
// apart: a 1 px shear from fine-level jitter), so two such patches warp into
// each other instead of showing two copies 1 px apart (the comb or zipper
// lines along edges at 800%); engine/material.py shear_pull does the same.
// source: 0 the stack, 1 the hi-res exemplar, 2 the lit preview's shape map.
vec4 magnified_from(ivec2 base, vec2 frac, int source) {
    vec2 F = frac - 0.5;
    vec2 fb = floor(F);
    vec2 t = F - fb;
    float h = float(1 << k);
    vec2 P[4];
    float W[4];
    for (int c = 0; c < 4; c++) {
        ivec2 o = ivec2(c & 1, c >> 1);
#ifdef DIRECTION
        ivec2 gc = base + ivec2(fb) + o;
        P[c] = Sf(gc) + 0.5 + h * (Jm(gc) * (t - vec2(o)));
#else
        P[c] = vec2(S(base + ivec2(fb) + o)) + 0.5 + h * (t - vec2(o));
#endif
        W[c] = (o.x == 0 ? 1.0 - t.x : t.x) * (o.y == 0 ? 1.0 - t.y : t.y);
    }
    vec4 acc = vec4(0.0);
    vec2 ddx = vec2(geom.x, geom.z) / float(m);   // uv derivatives per screen pixel
    vec2 ddy = vec2(geom.y, geom.w) / float(m);
    for (int c = 0; c < 4; c++) {
        vec2 pull = vec2(0.0);
        for (int o = 0; o < 4; o++) {
            vec2 d = P[o] - P[c];
            if (toroidal != 0) d -= float(m) * floor(d / float(m) + 0.5);
            if (o != c && max(abs(d.x), abs(d.y)) <= h) pull += W[o] * d;
        }
        vec2 uv = (P[c] + pull) / float(m);
        vec4 s;
        if (source == 1) s = textureGrad(hires, uv, ddx, ddy);
        else if (source == 2) s = texture(shape, vec3(uv, float(mag_layer)));
        else s = texture(stack, vec3(uv, float(mag_layer)));
        acc += W[c] * s;
    }
    return acc;
}

vec4 magnified(ivec2 base, vec2 frac) {
    return magnified_from(base, frac, MAG == 2 ? 1 : 0);
}

// The shape map at level position frac: magnified, or the texel's value.
vec4 shape_at(ivec2 base, vec2 frac, bool mag) {
    if (mag) return magnified_from(base, frac, 2);
    return texelFetch(shape, ivec3(S(base + ivec2(floor(frac))), layer), 0);
}

void main() {
    vec2 q = gl_FragCoord.xy;
    vec2 P = tl_f + vec2(geom.x * q.x + geom.y * q.y, geom.z * q.x + geom.w * q.y);  // finest level, relative to tl_i
    int s = 1 << k;
    ivec2 base = tl_i >> k;                          // floor division (sign-extending shift)
    vec2 frac = (vec2(tl_i - (base << k)) + P) / float(s);
    ivec2 g = base + ivec2(floor(frac));
    if (any(lessThan(g, vlo)) || any(greaterThanEqual(g, vhi))) discard;
    ivec2 u = S(g);
    vec4 c;
#if MODE == 1
    c = vec4((vec2(u) + 0.5) / float(m), 0.25, 1.0);
#elif MODE == 4
    float hx = luma(fetch(S(g + ivec2(1, 0)))) - luma(fetch(S(g - ivec2(1, 0))));
    float hy = luma(fetch(S(g + ivec2(0, 1)))) - luma(fetch(S(g - ivec2(0, 1))));
    float st = relief_strength / float(s);
    vec3 n = normalize(vec3(-hx * st, -hy * st, 1.0));
    float shade = 0.2 + 0.8 * max(dot(n, normalize(vec3(-0.6, -0.6, 0.55))), 0.0);
    c = vec4(vec3(shade), 1.0);
#elif MAG == 0 && defined(DIRECTION)
    c = texture(stack, vec3((Sf(g) + 0.5) / float(m), float(layer)));
#elif MAG == 0
    c = fetch(u);
#else
    c = magnified(base, frac);
#endif
#if MODE == 5
    // Lit material: the normal map (or the height map's slopes) shaded by a
    // directional light, the base color on top. Surface frame: x right, y up.
    bool mag = MAG != 0;
    vec3 n;
#if SHAPE_KIND == 0
    vec3 e = shape_at(base, frac, mag).rgb * 2.0 - 1.0;
    n = normalize(vec3(e.xy * relief, max(e.z, 1e-3)));
#else
    float d = mag ? 0.5 : 1.0;  // texels between the samples
    float hx = shape_at(base, frac + vec2(d, 0.0), mag).r - shape_at(base, frac - vec2(d, 0.0), mag).r;
    float hy = shape_at(base, frac + vec2(0.0, d), mag).r - shape_at(base, frac - vec2(0.0, d), mag).r;
    float gr = relief / (2.0 * d * float(s));  // height per finest pixel
    n = normalize(vec3(-hx * gr, hy * gr, 1.0));  // rows go down, y goes up
#endif
    // Lambert, scaled so a flat surface keeps its base color at any light
    // height: slopes facing the light brighten, the others darken to the ambient.
    float diffuse = max(dot(n, light), 0.0) / max(light.z, 0.2);
    c.rgb = min(c.rgb * (0.25 + 0.75 * diffuse), vec3(1.0));
#endif
#if ALPHA && (MODE == 0 || MODE == 3 || MODE == 5)
    ivec2 chk = ivec2(q) / 8;
    float bg = ((chk.x + chk.y) & 1) == 0 ? 0.8 : 0.6;
    c = vec4(mix(vec3(bg), c.rgb, c.a), 1.0);
#endif
#if MODE == 2
    ivec2 off = (u - g * s) & (m - 1);
    c.rgb = mix(c.rgb, hue(uint(off.x) * 7919u + uint(off.y) * 104729u), 0.45);
    float texel_px = zoom * float(s);
    vec2 f = fract(frac);
    bool right = (1.0 - f.x) * texel_px <= 1.0;
    bool below = (1.0 - f.y) * texel_px <= 1.0;
    if ((right && !coherent(g, ivec2(1, 0))) || (below && !coherent(g, ivec2(0, 1))))
        c.rgb = vec3(0.05);
#endif
#ifdef FEATHER
    vec2 gp = vec2(base) + frac;  // continuous level position
    vec2 edge = min(gp - feather.xy, feather.zw - gp);
    color = vec4(c.rgb, clamp(min(edge.x, edge.y) / feather_w, 0.0, 1.0));
#else
    color = vec4(c.rgb, 1.0);
#endif
}
