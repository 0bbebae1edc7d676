// Copy texels unchanged (a corrected block of a scratch buffer back into the
// buffer it was computed from).

uniform isampler2D src;

out ivec4 result;

void main() {
    result = texelFetch(src, ivec2(gl_FragCoord.xy), 0);
}
