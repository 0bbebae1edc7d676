// The model view's fragment shader (render/model_view.py): the lit texture, or (mode 1)
// the texture coordinates for picking; MAGNIFY: the synthesis magnified per pixel.
uniform sampler2D tex;
uniform vec3 light;      // towards the light, world space
uniform vec3 eye_dir;    // towards the eye, world space
uniform int mode;        // 0 lit texture, 1 texture coordinates (picking)
uniform int marks;       // mark the chart borders (seams)
uniform sampler2D seams; // 1 where a texel is a chart border texel
uniform int has_overlay; // a heat map over the atlas (painted randomness), blended in
uniform sampler2D overlay;
// Synthesis magnification (LH05 5, LH06 6): the atlas's coordinates (texel x,
// y, remainder x, y in 1/256 px; off the charts, the texels across the seam),
// J per texel (Q12) and the exemplar (its hi-res copy when there is one).
uniform isampler2D coords;
uniform isampler2D jac;
uniform sampler2D exemplar;
uniform int n;           // atlas texels a side
uniform float m;         // exemplar pixels a side (the coordinates' unit)
uniform int toroidal;
in vec3 v_normal;
in vec2 v_uv;
out vec4 color;

#ifdef MAGNIFY
vec3 magnified(vec2 p, vec2 px, vec2 py) {
    // p: atlas texel space (row 0 at the top); px, py: its derivatives per screen pixel
    vec2 fb = floor(p);
    vec2 t = p - fb;
    vec2 P[4];
    float W[4];
    mat2 J0 = mat2(1.0);
    for (int c = 0; c < 4; c++) {
        ivec2 o = ivec2(c & 1, c >> 1);
        ivec2 g = clamp(ivec2(fb) + o, ivec2(0), ivec2(n - 1));
        ivec4 S = texelFetch(coords, g, 0);
        vec4 j = vec4(texelFetch(jac, g, 0)) / 4096.0;
        mat2 J = mat2(j.x, j.z, j.y, j.w);  // columns: J (1, 0), J (0, 1)
        if (c == 0) J0 = J;
        P[c] = vec2(S.xy) + vec2(S.zw) / 256.0 + 0.5 + J * (t - vec2(o));
        W[c] = (o.x == 0 ? 1.0 - t.x : t.x) * (o.y == 0 ? 1.0 - t.y : t.y);
    }
    vec2 dx = J0 * px / m, dy = J0 * py / m;
    vec3 acc = vec3(0.0);
    for (int c = 0; c < 4; c++) {
        vec2 pull = vec2(0.0);  // patches a texel apart warp into each other (canvas.frag)
        for (int o = 0; o < 4; o++) {
            vec2 d = P[o] - P[c];
            if (toroidal != 0) d -= m * floor(d / m + 0.5);
            if (o != c && max(abs(d.x), abs(d.y)) <= 1.0) pull += W[o] * d;
        }
        acc += W[c] * textureGrad(exemplar, (P[c] + pull) / m, dx, dy).rgb;
    }
    return acc;
}
#endif

void main() {
    if (mode == 1) {
        color = vec4(v_uv, 1.0, 1.0);
        return;
    }
    vec3 n3 = normalize(v_normal);
    if (!gl_FrontFacing) n3 = -n3;
    vec2 uv = vec2(v_uv.x, 1.0 - v_uv.y);
    // Magnified where a texel covers more than a screen pixel (zoomed in); farther
    // out the texture's mipmaps show the same at a fraction of the cost.
    vec3 c;
#ifdef MAGNIFY
    // (A program of its own: llvmpipe runs a branch's body even when a uniform
    // turns it off everywhere, which cost the plain view two thirds of its frame rate.)
    vec2 p = uv * float(n) - 0.5;
    vec2 px = dFdx(p), py = dFdy(p);
    if (max(length(px), length(py)) < 1.0) {
        c = magnified(p, px, py);
    } else {
        c = texture(tex, uv).rgb;
    }
#else
    c = texture(tex, uv).rgb;
#endif
    float diff = max(dot(n3, normalize(light)), 0.0);
    vec3 h = normalize(normalize(light) + normalize(eye_dir));
    float spec = pow(max(dot(n3, h), 0.0), 40.0) * 0.12;
    vec3 lit = c * (0.28 + 0.8 * diff) + spec;
    if (has_overlay != 0) {
        vec4 o = texture(overlay, uv);
        lit = mix(lit, o.rgb, o.a);
    }
    if (marks != 0 && texture(seams, uv).r > 0.5) lit = mix(lit, vec3(1.0, 0.15, 0.1), 0.75);
    color = vec4(lit, 1.0);
}
