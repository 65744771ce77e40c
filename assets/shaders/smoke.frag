#version 300 es
// Smoke as a volume: the ray from the eye through this pixel, clipped to the smoke's box and to the opaque
// scene in front (its depth, copied out before this pass), marched in steps of about a cell through the
// smoke density (a 3D texture, trilinear). Emission and absorption: each step of length ds with
// extinction sigma = opacity * density absorbs 1 - exp(-sigma ds) of what is behind it and adds that
// share of the smoke's colour, darker the deeper into the smoke it lies (a cheap stand-in for the light
// the smoke in front takes); the result is premultiplied, blended over the scene.
precision highp float;
precision highp sampler3D;
in vec3 vWorld;
uniform sampler3D uSmoke;
uniform highp sampler2D uDepth;
uniform mat4 uInverseViewProjection;
uniform vec2 uViewport;
uniform vec3 uEye;
uniform vec3 uBoxMin;
uniform vec3 uBoxSize;
uniform vec3 uGridMin;   // the whole grid's box, which the texture spans
uniform vec3 uGridSize;
uniform float uStep;     // m, the march's step
uniform float uOpacity;  // 1/m per unit of density
uniform vec3 uColor;
out vec4 fragColor;

void main() {
    vec3 toBack = vWorld - uEye;
    float far = length(toBack);
    vec3 dir = toBack / far;
    // where the ray enters the box (the slabs' latest entry), from the eye at the nearest
    vec3 inverse = 1.0 / dir;
    vec3 t0 = (uBoxMin - uEye) * inverse;
    vec3 t1 = (uBoxMin + uBoxSize - uEye) * inverse;
    vec3 tEnter = min(t0, t1);
    float near = max(max(max(tEnter.x, tEnter.y), tEnter.z), 0.0);
    // the opaque scene's depth here, as a distance along the ray
    float depth = texelFetch(uDepth, ivec2(gl_FragCoord.xy), 0).r;
    vec4 ndc = vec4(gl_FragCoord.xy / uViewport * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    vec4 scene = uInverseViewProjection * ndc;
    far = min(far, dot(scene.xyz / scene.w - uEye, dir));
    if (far <= near) {
        discard;
    }
    vec3 colour = vec3(0.0);
    float transmittance = 1.0;
    int steps = int(ceil((far - near) / uStep));
    float ds = (far - near) / float(steps);
    vec3 at = (uEye + dir * (near + 0.5 * ds) - uGridMin) / uGridSize;
    vec3 stride = dir * ds / uGridSize;
    for (int s = 0; s < steps && transmittance > 0.004; ++s) {
        float density = max(texture(uSmoke, at).r, 0.0);
        float absorbed = transmittance * (1.0 - exp(-uOpacity * density * ds));
        colour += absorbed * uColor * (0.55 + 0.45 * transmittance);
        transmittance -= absorbed;
        at += stride;
    }
    if (transmittance > 0.999) {
        discard;
    }
    fragColor = vec4(colour, 1.0 - transmittance);
}
