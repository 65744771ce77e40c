#version 300 es
// Particles as camera-facing quads, one instance each: the four corners come from gl_VertexID and are
// spread along the camera's right and up vectors by the particle's size (m).
layout(location = 0) in vec3 aCentre;
layout(location = 1) in vec4 aColor;
layout(location = 2) in float aSize;
uniform mat4 uViewProjection;
uniform vec3 uRight;
uniform vec3 uUp;
out vec4 vColor;
out vec2 vCorner;
void main() {
    vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1)) * 2.0 - 1.0;
    vec3 world = aCentre + (uRight * corner.x + uUp * corner.y) * (0.5 * aSize);
    gl_Position = uViewProjection * vec4(world, 1.0);
    vColor = aColor;
    vCorner = corner;
}
