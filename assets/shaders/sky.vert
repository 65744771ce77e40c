#version 300 es
// The sky: one triangle holding the whole screen, at the far plane (depth 1), drawn after the opaque scene
// with a depth test that lets it through only where nothing was drawn (sky.frag), or into the sky's texture
// (sky_texels.frag). One triangle and not a grid of small ones: with multisampling, llvmpipe works out each
// sample's coverage by itself wherever an edge crosses a 4 x 4 block, and a 16 x 64 grid of cells had an
// edge through most blocks of the screen (a fifth of the curtain's frame).
void main() {
    // (-1, -1), (3, -1), (-1, 3): the screen's square is inside, no edge crosses it
    vec2 ndc = vec2(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0);
    gl_Position = vec4(ndc, 1.0, 1.0);
}
