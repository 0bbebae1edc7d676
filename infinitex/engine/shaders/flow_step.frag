// One frame more of every trajectory of a window (engine/advect.py
// FlowFrames.trajectory; the sampling is Flow.sample, engine/controls/flow.py):
// d' = d - V(p + d), all in 1/256 px, exact integers. V is the uniform velocity
// plus the map's, bilinear between its texels; the map sits in a border of 2
// zero texels, so a corner outside it reads 0. With a period n the canvas and
// the map repeat every n px (each corner wraps on its own).

uniform isampler2D path;     // d over the window (RG32I)
uniform isampler2D vmap;     // the velocity map, (w + 4) x (h + 4), RG32I
uniform ivec2 origin;        // canvas pixel of the window's texel (0, 0)
uniform ivec2 map_xy;        // canvas pixel of the map's texel (0, 0)
uniform ivec2 map_wh;
uniform ivec2 velocity;      // the uniform part
uniform int period;          // a toroidal tile's size (a power of two), 0: none
uniform int has_map;

out ivec2 result;

// The bordered map's column (or row) of canvas pixel i along one axis.
int bordered(int i, int lo, int n) {
    if (period > 0) {
        return clamp((i & (period - 1)) - lo + 2, 1, n + 2);
    }
    return i < lo - 2 ? 0 : i > lo + n ? n + 2 : i - lo + 2;
}

void main() {
    ivec2 T = ivec2(gl_FragCoord.xy);
    ivec2 d = texelFetch(path, T, 0).xy;
    ivec2 v = velocity;
    if (has_map != 0) {
        ivec2 p = origin + T;
        ivec2 i = p + floor_shift(ivec4(d, 0, 0), 8).xy;   // the position's texel, p + d >> 8
        ivec2 f = d & 255;
        ivec2 g = 256 - f;
        int x0 = bordered(i.x, map_xy.x, map_wh.x), x1 = bordered(i.x + 1, map_xy.x, map_wh.x);
        int y0 = bordered(i.y, map_xy.y, map_wh.y), y1 = bordered(i.y + 1, map_xy.y, map_wh.y);
        ivec2 s = texelFetch(vmap, ivec2(x0, y0), 0).xy * (g.x * g.y)
                + texelFetch(vmap, ivec2(x1, y0), 0).xy * (f.x * g.y)
                + texelFetch(vmap, ivec2(x0, y1), 0).xy * (g.x * f.y)
                + texelFetch(vmap, ivec2(x1, y1), 0).xy * (f.x * f.y);
        v += floor_shift(ivec4(s, 0, 0), 16).xy;
    }
    result = d - v;
}
