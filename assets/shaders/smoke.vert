#version 300 es
// The box round an air grid's smoke (the cells where it is thick enough to see), drawn by its back faces
// (so that a camera inside the box still gets a fragment per pixel); the fragment shader marches the ray
// through the box.
layout(location = 0) in vec3 aPosition;
uniform mat4 uViewProjection;
uniform vec3 uBoxMin;
uniform vec3 uBoxSize;
out vec3 vWorld;
void main() {
    vWorld = uBoxMin + (aPosition * 0.5 + 0.5) * uBoxSize;
    gl_Position = uViewProjection * vec4(vWorld, 1.0);
}
