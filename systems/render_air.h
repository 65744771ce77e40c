#pragma once
// The air grids drawn, for the renderer (systems/render_system.h): smoke as a volume, ray-marched through a
// 3D texture of its density (assets/shaders/smoke.*), and on request (`velocity_slice`) a slice of the
// velocity through the box's centre as arrows coloured by speed.

#include "engine/math.h"
#include "engine/world.h"

#include <array>
#include <string>
#include <vector>

namespace tumble {

/// A vertex of a line (or a particle's instance): position, colour, size.
struct FlatVertex {
    float x, y, z;
    float r, g, b, a;
    float size;
};

/// The GL objects of the smoke pass: its program and uniforms, the density texture (one, uploaded again
/// for each air grid drawn) and a copy of the scene's depth, which the march stops at.
struct SmokePass {
    unsigned program = 0;
    struct {
        int viewProjection = -1, inverseViewProjection = -1, viewport = -1, eye = -1, boxMin = -1,
            boxSize = -1, gridMin = -1, gridSize = -1, step = -1, opacity = -1, colour = -1, smoke = -1,
            depth = -1;
    } uniform;
    unsigned texture = 0;
    std::array<int, 3> textureCells{}; ///< the texture's size as last made
    int largestTexture = 0;            ///< the GL's largest 3D texture side
    unsigned depthFbo = 0, depthTexture = 0;
    int depthWidth = 0, depthHeight = 0;

    /// Compiles the program (throws with the GL log on failure) and makes the texture.
    void make(const std::string& vertexSource, const std::string& fragmentSource);
    /// Frees the GL objects (the context current).
    void release();
};

/// What the smoke pass needs of the frame being drawn.
struct SmokeFrame {
    std::array<float, 16> viewProjection; ///< column-major
    Vec3 eye;
    unsigned targetFbo;
    int width, height;
    unsigned cubeVao; ///< a cube from -1 to 1, its faces wound counter-clockwise seen from outside
    int cubeVertices;
};

/// Draws every air grid's smoke over the frame (its opaque things drawn first), blended.
void drawSmoke(World& world, SmokePass& pass, const SmokeFrame& frame);

/// Appends the lines of the velocity slices the air grids ask for (`velocity_slice`): arrows at most 32
/// a side, each as long as its spacing at the slice's top speed, coloured from blue (still) to red.
void appendVelocityArrows(World& world, std::vector<FlatVertex>& lines);

} // namespace tumble
