#version 300 es
// The sky: a grid of 16 x 64 cells over the whole screen at the far plane (depth 1), drawn after the opaque
// scene with a depth test that lets it through only where nothing was drawn. Its colour (look.glsl's
// gradient along the ray from the eye, put in after the #version line) is worked out at the grid's
// corners and interpolated: a sky pixel costs a write, not the gradient's curve (on a CPU rasteriser the
// curve per pixel cost four times the rest of the pass).
uniform mat4 uInverseViewProjection;
uniform vec3 uEye;
out vec3 vColour;
const int kColumns = 16;
const int kRows = 64;
void main() {
    // six corners a cell, two triangles: (0, 0) (1, 0) (1, 1) and (0, 0) (1, 1) (0, 1)
    int cell = gl_VertexID / 6, corner = gl_VertexID % 6;
    int dx = corner == 1 || corner == 2 || corner == 4 ? 1 : 0;
    int dy = corner == 2 || corner == 4 || corner == 5 ? 1 : 0;
    vec2 at = vec2(float(cell % kColumns + dx) / float(kColumns), float(cell / kColumns + dy) / float(kRows));
    vec2 ndc = at * 2.0 - 1.0;
    vec4 far = uInverseViewProjection * vec4(ndc, 1.0, 1.0);
    vColour = encode(skyColour(normalize(far.xyz / far.w - uEye)));
    gl_Position = vec4(ndc, 1.0, 1.0);
}
