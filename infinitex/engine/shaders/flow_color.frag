// A draft frame's colors (engine/advect_gl.py GpuComposer.draft_colors; the editor
// plays them): each pixel's chosen coordinates, with their sub-pixel rest, sampled
// bilinearly in the map (8 bits a channel), wrapped on a toroidal exemplar, clamped
// otherwise, as engine/subpixel.py samples in floats.

uniform isampler2D coords;    // RGBA16I: texel x, y, remainders (1/256 px); SEAM larger a side
uniform sampler2D palette;    // the map, m x m, normalized 8 bits
uniform int m;
uniform int wrap;
uniform int channels;
uniform int margin;

layout(location = 0) out vec4 color;

ivec2 texel(ivec2 p) {
    return wrap != 0 ? (p & (m - 1)) : clamp(p, ivec2(0), ivec2(m - 1));
}

void main() {
    ivec4 c = texelFetch(coords, ivec2(gl_FragCoord.xy) + margin, 0);
    ivec2 pos = c.xy * 256 + c.zw;             // |pos| < 2^24: floor_shift is exact
    ivec2 i0 = floor_shift(ivec4(pos, 0, 0), 8).xy;
    vec2 f = vec2(pos - i0 * 256) / 256.0;
    ivec2 a = texel(i0), b = texel(i0 + 1);
    vec4 v = mix(mix(texelFetch(palette, ivec2(a.x, a.y), 0), texelFetch(palette, ivec2(b.x, a.y), 0), f.x),
                 mix(texelFetch(palette, ivec2(a.x, b.y), 0), texelFetch(palette, ivec2(b.x, b.y), 0), f.x), f.y);
    color = channels == 1 ? vec4(v.rrr, 1.0) : (channels == 2 ? vec4(v.rrr, 1.0) : v);
}
