#version 300 es
// Springs as lines and masses and particles as points: a colour and a size per vertex.
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec4 aColor;
layout(location = 2) in float aSize;
uniform mat4 uViewProjection;
uniform float uPixelsPerMetre;
out vec4 vColor;
void main() {
    gl_Position = uViewProjection * vec4(aPosition, 1.0);
    vColor = aColor;
    // size in metres, seen from the camera: pixels = size * focal / depth
    gl_PointSize = max(1.0, aSize * uPixelsPerMetre / max(gl_Position.w, 1e-3));
}
