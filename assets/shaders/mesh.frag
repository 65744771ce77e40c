#version 300 es
// One key light, which casts shadows (a shadow map, percentage-closer filtered), soft ambient from the
// sky, two-sided (cloth shows both faces), and a darkening near the ground for contact.
precision highp float;
precision highp sampler2DShadow;
in vec3 vNormal;
in vec3 vWorld;
uniform vec4 uColor;
uniform vec3 uLightDir;
uniform float uGrid;
uniform vec3 uEye;
uniform sampler2DShadow uShadowMap;
uniform mat4 uLightViewProjection;
uniform float uShadows;     // 1: the shadow map holds this frame's casters
uniform float uShadowTexel; // 1 / the shadow map's size
out vec4 fragColor;

// How much of the key light reaches this point: 1 lit, 0 in shadow; nine filtered lookups (each itself a
// 2 x 2 comparison) around it soften the edge over about three texels. Beside the map: lit.
float lightReaching() {
    if (uShadows <= 0.0) {
        return 1.0;
    }
    vec4 p = uLightViewProjection * vec4(vWorld, 1.0);
    vec3 q = p.xyz / p.w * 0.5 + 0.5;
    if (q.x <= 0.0 || q.x >= 1.0 || q.y <= 0.0 || q.y >= 1.0) {
        return 1.0;
    }
    // beyond the light box's far side (a ground far below the casters) the compared depth is clamped to 1,
    // which every texel a caster covers is in front of: shadowed where a caster is, lit elsewhere
    // four filtered lookups half a texel either way: each compares 2 x 2 texels, together 3 x 3
    float z = q.z - 0.0005;
    vec2 d = vec2(0.5 * uShadowTexel);
    return 0.25 * (texture(uShadowMap, vec3(q.xy + vec2(-d.x, -d.y), z)) +
                   texture(uShadowMap, vec3(q.xy + vec2(d.x, -d.y), z)) +
                   texture(uShadowMap, vec3(q.xy + vec2(-d.x, d.y), z)) +
                   texture(uShadowMap, vec3(q.xy + vec2(d.x, d.y), z)));
}

void main() {
    // the side that faces the camera is the lit one, whatever the winding (two-sided cloth)
    vec3 n = normalize(vNormal);
    if (dot(n, uEye - vWorld) < 0.0) {
        n = -n;
    }
    float diffuse = max(dot(n, -uLightDir), 0.0);
    if (diffuse > 0.0) {
        diffuse *= lightReaching();
    }
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
