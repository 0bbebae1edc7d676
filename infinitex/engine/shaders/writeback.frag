// Copy the exact part of a corrected scratch region into a level's
// persistent buffer, whose texel of global position g is (g - anchor) & mask;
// placed features are imposed again (correction may have moved their pixels).

uniform isampler2D src;       // quadrant-packed scratch
uniform ivec2 qdims;
uniform ivec2 src_origin;     // global position of scratch pixel (0, 0)
uniform ivec2 region_g0;      // global position of the first written texel
uniform ivec2 region_t0;      // its texel in the destination
uniform ivec2 dest_mask;
uniform int h;
uniform int m;
uniform int period;

out ivec4 result;

void main() {
    ivec2 T = ivec2(gl_FragCoord.xy);
    ivec2 g = region_g0 + ((T - region_t0) & dest_mask);
    ivec4 v = texelFetch(src, packed_texel(g - src_origin, qdims), 0);
#if defined(ATLAS)
    result = apply_features_atlas(g, v, h, m, texelFetch(links, g - src_origin, 0).x);  // the texel's chart
#elif defined(DIRECTION)
    bool hit = false;
    ivec2 s = apply_features_hit(g, v.xy, h, m, period, hit);
    result = ivec4(s, hit ? ivec2(0) : v.zw);  // a feature sets a whole texel
#else
    result = ivec4(apply_features(g, v.xy, h, m, period), 0, 0);  // features hold through correction
#endif
}
