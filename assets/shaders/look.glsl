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
    // above 0.0031308 the curve 1.055 c^(1/2.4) - 0.055, as a sum of c's square, fourth and eighth roots
    // (fitted to it by weighted least squares: within 0.05 of a level of 255); three square roots cost a
    // CPU rasteriser less than pow's logarithm and exponential (the avalanche's frame 7% less on llvmpipe)
    c = clamp(c, 0.0, 1.0);
    vec3 r2 = sqrt(c);
    vec3 r4 = sqrt(r2);
    vec3 r8 = sqrt(r4);
    vec3 curve = 0.5545175 * r2 + 0.8999643 * r4 - 0.4887089 * r8 + 0.0344285;
    return mix(c * 12.92, curve, step(vec3(0.0031308), c));
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
