#version 300 es
// A round particle with a soft edge, blended over what is behind it.
precision mediump float;
in vec4 vColor;
in vec2 vCorner;
out vec4 fragColor;
void main() {
    float r = length(vCorner);
    if (r > 1.0) {
        discard;
    }
    fragColor = vec4(vColor.rgb, vColor.a * (1.0 - smoothstep(0.7, 1.0, r)));
}
