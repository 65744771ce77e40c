#pragma once
// A hold of the mouse (or of a scripted `grab` event) on one entity: a spring from a point of it to a
// target that the `drag` events move. One per entity; `release` removes it.

#include "engine/math.h"

#include <cstdint>

namespace tumble {

/// What is held and where it is pulled to.
struct Grab {
    std::uint32_t mass = 0; ///< spring network: the held mass
    Vec3 local;             ///< rigid body: the held point, in the body's frame (2D: x, y)
    Vec3 target;            ///< m, world: where the spring pulls the point to
    double heldMass = 0.0;  ///< kg: a network's free mass when it was grabbed (the spring scales with it)
};

} // namespace tumble
