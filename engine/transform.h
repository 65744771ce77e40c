#pragma once
// Where an entity is placed in the world. Grids (cloth, soft bodies, water) are centred on it.

#include "engine/math.h"

namespace tumble {

/// World placement of an entity.
struct Transform {
    Vec3 position; ///< m
};

} // namespace tumble
