#version 300 es
// The sky's colour over the screen: its texture (sky_texels.frag: the gradient worked out at the centre of
// every cell of 4 x 4 pixels, already written as sRGB with gamma), filtered bilinearly. A lookup a pixel,
// not the gradient's curve (on a CPU rasteriser the curve per pixel cost four times the rest of the pass).
precision highp float;
uniform sampler2D uSky;
uniform vec2 uPixelToUv; // 1 / the size in pixels of what the texture spans
out vec4 fragColor;
void main() {
    fragColor = vec4(texture(uSky, gl_FragCoord.xy * uPixelToUv).rgb, 1.0);
}
