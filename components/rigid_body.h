#pragma once
// A rigid body as the scenario describes it. Static bodies (mass 0) are colliders that spring networks and
// particles collide with by geometry of our own; dynamic bodies are simulated by the rigid-body bridges.

#include "engine/math.h"

#include <cstdint>

namespace tumble {

/// Collision shapes (CONTRACT.md `shape`).
enum class ShapeKind : std::uint8_t { Plane, Box, Sphere, Capsule, Cylinder };

/// Shape, material and mass of a rigid body; placed at its entity's transform.
struct RigidBody {
    ShapeKind shape = ShapeKind::Box;
    Vec3 normal{0.0, 1.0, 0.0};      ///< plane: unit normal
    Vec3 halfExtents{0.5, 0.5, 0.5}; ///< box: m, axis-aligned
    double radius = 0.5;             ///< sphere, capsule, cylinder: m
    double height = 1.0;             ///< capsule, cylinder: m, along y (the capsule's straight part)
    double mass = 0.0;               ///< kg; 0 = static
    double friction = 0.6;
    double restitution = 0.0;
    Vec3 position; ///< m, centre (plane: a point on it)
    Vec3 color{0.62, 0.60, 0.56}; ///< RGB in [0, 1], for the renderer only
};

} // namespace tumble
