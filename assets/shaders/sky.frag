#version 300 es
// The sky's colour, as sky.vert worked it out at the grid's corners (already written as sRGB with gamma).
precision mediump float;
in vec3 vColour;
out vec4 fragColor;
void main() {
    fragColor = vec4(vColour, 1.0);
}
