// The look the lit programs share, put in after each one's #version line: the colour spaces and the sky.
// With GAMMA defined, colours (given as sRGB values and decoded before they are set: uniforms, not worth a
// curve per fragment) are lit in linear light and encoded back to sRGB when written (the sRGB curve);
// without, they are lit as given and written as they come out. (A define, not a uniform: a CPU rasteriser
// pays for both sides of a branch on a uniform.)
precision highp float;
uniform vec3 uZenith;  // the sky straight up, linear with GAMMA
uniform vec3 uHorizon; // at the horizon
uniform vec3 uNadir;   // below the horizon (what a surface facing down reflects)

vec3 encode(vec3 c) {
#ifdef GAMMA
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
#else
    return c;
#endif
}

// The sky seen along the unit direction d: the zenith's colour overhead, paling to the horizon's, and
// below the horizon darkening quickly to the nadir's.
vec3 skyColour(vec3 d) {
    if (d.y >= 0.0) {
        return mix(uHorizon, uZenith, sqrt(d.y));
    }
    return mix(uHorizon, uNadir, min(-8.0 * d.y, 1.0));
}
