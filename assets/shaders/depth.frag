#version 300 es
// The shadow map's pass: depth only (mesh.vert places the vertices as seen from the light).
precision mediump float;
void main() {
}
