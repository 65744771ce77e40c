#version 300 es
// One key light, which casts shadows with SHADOWS defined (a shadow map, percentage-closer filtered), ambient light from the sky
// above and the ground below (a hemisphere), two-sided (cloth shows both faces), and a darkening near the
// ground for contact. Compiled with GROUND defined, it draws a ground plane, which carries a grid; with
// WATER, water: see-through, reflecting the sky by Fresnel (programs of their own, not uniforms: a CPU
// rasteriser pays for both sides of a branch on a uniform). look.glsl (put in after the #version line)
// gives the colour spaces and the sky.
precision highp sampler2DShadow;
in vec3 vNormal;
in vec3 vWorld;
uniform vec4 uColor;         // in the space lighting is done in (linear with gamma: decoded before it is set)
uniform vec3 uLightDir;
uniform float uKey;          // the key light's strength
uniform vec3 uSkyLight;      // ambient from straight above (a surface facing up gets all of it)
uniform vec3 uGroundLight;   // ambient from straight below
uniform vec3 uEye;
out vec4 fragColor;

#ifdef SHADOWS
in vec3 vLight;
uniform sampler2DShadow uShadowMap;

// How much of the key light reaches this point: 1 lit, 0 in shadow; one filtered lookup (a 2 x 2
// percentage-closer comparison, bilinear: an edge a texel soft; four lookups half a texel apart softened it
// over three texels for 5 ms more of the curtain's frame on llvmpipe). No branches (a CPU rasteriser runs
// both sides): beside the map the lookup reads its clamped edge, which no caster reaches (the map spans the
// casters with a margin): lit; beyond the light box's far side (a ground far below the casters) the
// compared depth is 1 (clamped here too, not left to the driver), which every texel a caster covers is in
// front of.
float lightReaching() {
    return texture(uShadowMap, vec3(vLight.xy, min(vLight.z - 0.0005, 1.0)));
}
#else
float lightReaching() {
    return 1.0;
}
#endif

#ifdef GROUND
// How much of this pixel the grid's lines cover: lines 4 cm wide every metre along x and along z, each
// averaged over the pixel's footprint (fwidth: metres a pixel). A line thinner than a pixel is drawn a
// pixel wide and as much fainter, and as the footprint grows towards half a metre the lines fade into
// their average cover, so that far away they neither break into a moire nor vanish.
float gridCover(vec2 p) {
    const float halfWidth = 0.02;
    vec2 w = max(fwidth(p), vec2(1e-6));
    vec2 drawn = max(vec2(halfWidth), 0.5 * w);
    vec2 d = abs(fract(p + 0.5) - 0.5); // to the nearest line
    vec2 cover = clamp((drawn - d) / w + 0.5, 0.0, 1.0) * (halfWidth / drawn);
    cover = mix(cover, vec2(2.0 * halfWidth), smoothstep(0.15, 0.5, w));
    return cover.x + cover.y - cover.x * cover.y;
}
#endif

#ifdef WATER
// Water: the sky reflected by Schlick's Fresnel term (2% head on, all of it at grazing angles), the
// water's own colour (lit) covering uColor.a of what lies below when seen head on, and the sun's glint.
vec4 water(vec3 n, vec3 lit, float reaching) {
    vec3 v = normalize(uEye - vWorld);
    float fresnel = 0.02 + 0.98 * pow(1.0 - clamp(dot(n, v), 0.0, 1.0), 5.0);
    vec3 r = reflect(-v, n);
    float glint = uKey * reaching * pow(max(dot(r, -uLightDir), 0.0), 400.0);
    float body = (1.0 - fresnel) * uColor.a;
    float alpha = clamp(fresnel + body + glint, 0.0, 1.0);
    vec3 colour = fresnel * skyColour(r) + body * lit + vec3(glint);
    return vec4(encode(colour / max(alpha, 1e-3)), alpha);
}
#endif

#ifdef GROUND
// A ground plane: its normal, and so its light, is the same all over it. The CPU works out its colour lit
// by the key light (uGroundLit: the colour times ambient plus key times diffuse) and in shadow
// (uGroundShade: times ambient), and, for where no shadow reaches, the written colour as a quadratic in the
// grid's cover (uCover0 + g (uCover1 + g uCover2), through the written colours at g = 0, 1/2 and 1): that
// spares each pixel the sRGB curve, and with it most of a CPU rasteriser's time on the far floor.
uniform vec3 uGroundLit;
uniform vec3 uGroundShade;
uniform vec3 uCover0;
uniform vec3 uCover1;
uniform vec3 uCover2;

void main() {
    float g = gridCover(vWorld.xz);
#ifdef SHADOWS
    vec3 lit = mix(uGroundShade, uGroundLit, lightReaching()) * (1.0 - 0.3 * g);
    fragColor = vec4(encode(lit), uColor.a);
#else
    fragColor = vec4(uCover0 + g * (uCover1 + g * uCover2), uColor.a);
#endif
}
#else
void main() {
    // the side that faces the camera is the lit one, whatever the winding (two-sided cloth)
    vec3 n = normalize(vNormal);
    if (dot(n, uEye - vWorld) < 0.0) {
        n = -n;
    }
    float diffuse = max(dot(n, -uLightDir), 0.0);
    float reaching = lightReaching();
    vec3 base = uColor.rgb;
    float contact = mix(0.75, 1.0, clamp(vWorld.y * 4.0, 0.0, 1.0));
    vec3 ambient = mix(uGroundLight, uSkyLight, 0.5 + 0.5 * n.y);
    vec3 lit = base * (ambient + uKey * diffuse * reaching) * contact;
#ifdef WATER
    fragColor = water(n, lit, reaching);
#else
    fragColor = vec4(encode(lit), uColor.a);
#endif
}
#endif
