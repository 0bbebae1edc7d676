// The choice between a flowing texture's two chains (engine/advect.py
// FlowFrames._frame), in three stages:
//   STAGE 0: take the new chain where most of the (2 VOTE + 1)^2 pixels around have come due;
//   STAGE 1: the chosen coordinates, and where a cut runs (a pixel whose left or upper
//            neighbour takes the other chain, the two chains differing at one of them);
//   STAGE 2: the seams: within SEAM px of a cut.
// Each stage reads the previous one's texture one margin larger.

uniform isampler2D a;         // STAGE 0: the new chain's turns; 1: take (R32I, the output's size); 2: cuts
uniform isampler2D c0;        // STAGE 1: the old chain's coordinates, the new one's
uniform isampler2D c1;
uniform int due;              // STAGE 0: a turn below this has come
uniform int margin;           // how much larger the input (STAGE 1: the chains) is on each side

layout(location = 0) out ivec4 result;
layout(location = 1) out int flag;

void main() {
    ivec2 P = ivec2(gl_FragCoord.xy);
#if STAGE == 0
    int votes = 0;
    for (int dy = -VOTE; dy <= VOTE; dy++) {
        for (int dx = -VOTE; dx <= VOTE; dx++) {
            votes += texelFetch(a, P + margin + ivec2(dx, dy), 0).x < due ? 1 : 0;
        }
    }
    flag = votes * 2 > (2 * VOTE + 1) * (2 * VOTE + 1) ? 1 : 0;
    result = ivec4(0);
#elif STAGE == 1
    ivec2 Q = P + margin;             // the chains are VOTE larger a side than the take
    int take = texelFetch(a, P, 0).x;
    ivec4 o = texelFetch(c0, Q, 0), n = texelFetch(c1, Q, 0);
    result = take != 0 ? n : o;
    bool differ = any(notEqual(o, n));
    int cut = 0;
    for (int i = 0; i < 2; i++) {
        ivec2 step = i == 0 ? ivec2(1, 0) : ivec2(0, 1);
        bool inside = i == 0 ? P.x > 0 : P.y > 0;  // the first column and row have no such neighbour
        if (inside && texelFetch(a, P - step, 0).x != take
                && (differ || any(notEqual(texelFetch(c0, Q - step, 0), texelFetch(c1, Q - step, 0))))) {
            cut = 1;
        }
    }
    flag = cut;
#else
    int any_cut = 0;
    for (int dy = -SEAM; dy <= SEAM; dy++) {
        for (int dx = -SEAM; dx <= SEAM; dx++) {
            any_cut |= texelFetch(a, P + margin + ivec2(dx, dy), 0).x;
        }
    }
    flag = any_cut;
    result = ivec4(0);
#endif
}
