#version 300 es
// Lit meshes: position and normal per vertex, one model matrix per draw, and for instanced draws (the
// masses of a spring network) an offset and a scale per instance. With SHADOWS defined, each point's place in
// the key light's shadow map too (interpolated: linear, the light's projection being orthographic).
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aInstance; // per instance: offset (xyz) and scale (w); (0, 0, 0, 1) when not instanced
uniform mat4 uViewProjection;
uniform mat4 uModel;
#ifdef SHADOWS
uniform mat4 uLightViewProjection;
out vec3 vLight; // where the point falls in the key light's shadow map: its texture coordinates and depth
#endif
out vec3 vNormal;
out vec3 vWorld;
void main() {
    vec4 world = uModel * vec4(aPosition * aInstance.w + aInstance.xyz, 1.0);
    vWorld = world.xyz;
    vNormal = mat3(uModel) * aNormal;
    gl_Position = uViewProjection * world;
#ifdef SHADOWS
    vLight = (uLightViewProjection * world).xyz * 0.5 + 0.5; // orthographic: w is 1
#endif
}
