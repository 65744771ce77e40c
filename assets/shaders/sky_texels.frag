#version 300 es
// The sky's texture: each texel the gradient (look.glsl's skyColour, put in after the #version line, and
// encoded) along the ray from the eye through the centre of the screen's cell of pixels it stands for.
uniform mat4 uInverseViewProjection;
uniform vec3 uEye;
uniform vec2 uTexelToNdc; // a texel's size in normalised device coordinates
out vec4 fragColor;
void main() {
    vec2 ndc = gl_FragCoord.xy * uTexelToNdc - 1.0;
    vec4 far = uInverseViewProjection * vec4(ndc, 1.0, 1.0);
    fragColor = vec4(encode(skyColour(normalize(far.xyz / far.w - uEye))), 1.0);
}
