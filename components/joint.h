#pragma once
// A joint between two rigid bodies of the same engine, or between a body and the world ([[joint]], README
// "Rigid bodies"). A joint is an entity of its own; the bridge makes the engine's constraint from it and
// removes that constraint when either body is gone.

#include "engine/entity.h"
#include "engine/math.h"

#include <cstdint>

namespace tumble {

/// hinge: rotation about one axis; point: a ball joint; fixed: welded; slider: translation along one axis;
/// spring: a damped spring between two points (rest length, stiffness, damping).
enum class JointKind : std::uint8_t { Hinge, Point, Fixed, Slider, Spring };

struct Joint {
    JointKind kind = JointKind::Point;
    Entity a;                 ///< a body
    Entity b;                 ///< another body, or null: the world
    bool twoD = false;        ///< between Box2D bodies
    Vec3 pivot;               ///< m, world, where the joint is at the start (spring: its end on a)
    Vec3 pivotB;              ///< spring: its end on b (or in the world), m
    Vec3 axis{0.0, 0.0, 1.0}; ///< hinge, slider: unit, world
    bool limited = false;     ///< hinge (rad) and slider (m) limits
    double lower = 0.0;
    double upper = 0.0;
    double stiffness = 0.0;         ///< spring: N/m
    double damping = 0.0;           ///< spring: N s/m
    double rest = 0.0;              ///< spring: m
    Vec3 localA, localB;            ///< spring (Bullet): its ends in a's frame and b's (the world's for none)
    std::int32_t constraintId = -1; ///< the bridge's; -1 until made
};

} // namespace tumble
