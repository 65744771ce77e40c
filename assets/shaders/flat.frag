#version 300 es
// Points are drawn round, with soft edges; lines are plain.
precision mediump float;
in vec4 vColor;
uniform bool uRound;
out vec4 fragColor;
void main() {
    float alpha = vColor.a;
    if (uRound) {
        vec2 d = gl_PointCoord - vec2(0.5);
        float r = length(d) * 2.0;
        if (r > 1.0) {
            discard;
        }
        alpha *= 1.0 - smoothstep(0.7, 1.0, r);
    }
    fragColor = vec4(vColor.rgb, alpha);
}
