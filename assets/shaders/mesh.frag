#version 300 es
// One key light, soft ambient from the sky, two-sided (cloth shows both faces), and a darkening near the
// ground that stands in for contact shadows.
precision highp float;
in vec3 vNormal;
in vec3 vWorld;
uniform vec4 uColor;
uniform vec3 uLightDir;
uniform float uGrid;
uniform vec3 uEye;
out vec4 fragColor;
void main() {
    // the side that faces the camera is the lit one, whatever the winding (two-sided cloth)
    vec3 n = normalize(vNormal);
    if (dot(n, uEye - vWorld) < 0.0) {
        n = -n;
    }
    float diffuse = max(dot(n, -uLightDir), 0.0);
    float sky = 0.5 + 0.5 * n.y;
    vec3 base = uColor.rgb;
    if (uGrid > 0.0) {
        // a ground grid: one line every metre
        vec2 cell = abs(fract(vWorld.xz) - 0.5);
        float line = step(0.48, max(cell.x, cell.y));
        base = mix(base, base * 0.7, line);
    }
    float contact = mix(0.75, 1.0, clamp(vWorld.y * 4.0, 0.0, 1.0));
    vec3 lit = base * (0.35 * sky + 0.75 * diffuse) * (uGrid > 0.0 ? 1.0 : contact);
    fragColor = vec4(lit, uColor.a);
}
