#pragma once
// What the renderer needs of the step before the last one, to draw a frame that falls between two fixed
// steps: the positions of a spring network's masses, or a moving rigid body's pose, at the start of the last
// fixed step. Kept only while rendering; not simulation state (no codec, not in the hash or the dump).

#include "engine/math.h"

#include <vector>

namespace tumble {

/// A spring network's positions one fixed step back.
struct RenderHistory {
    std::vector<Vec3> previous; ///< m, one per mass, as they were before the last fixed step
};

/// A moving rigid body's pose one fixed step back (a 2D body's angle as a rotation about z).
struct PoseHistory {
    Vec3 position;
    Quat orientation;
};

} // namespace tumble
