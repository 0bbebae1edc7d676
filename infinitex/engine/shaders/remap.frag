// Copy texels between two level buffers with different sizes or wrap masks
// (a buffer that grows keeps what it held); WIDEN: into a four-component one.

uniform isampler2D src;
uniform ivec2 src_anchor;
uniform ivec2 src_mask;
uniform ivec2 region_g0;      // global position of the first written texel
uniform ivec2 region_t0;      // its texel in the destination
uniform ivec2 dest_mask;

out ivec4 result;

void main() {
    ivec2 T = ivec2(gl_FragCoord.xy);
    ivec2 g = region_g0 + ((T - region_t0) & dest_mask);
    result = texelFetch(src, (g - src_anchor) & src_mask, 0);
#ifdef WIDEN
    result.zw = ivec2(0);  // two components to four: a remainder of 0 (a 2-component fetch gives w = 1)
#endif
}
