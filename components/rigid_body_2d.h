#pragma once
// A rigid body of the 2D engine (Box2D), in the scene's xy plane: its shape and material, a copy of its
// pose and velocities written back after every step, the engine's id, and the pushes that wait for the
// next step. See components/rigid_body.h for the 3D twin.

#include "engine/math.h"

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace tumble {

/// 2D collision shapes (README, "Rigid bodies": `shape` of rigid_body_2d).
enum class Shape2DKind : std::uint8_t { Box, Circle, Polygon, Edge };

using Vec2 = std::array<double, 2>;

/// The depth of a 2D body in the 3D scene: a slab of this half depth about its entity's z, as it is drawn
/// and as springs and particles collide with it; an edge is a strip of kEdgeHalfWidth either side (less
/// than the 1 cm skin Box2D keeps round a polygon, so a box resting on an edge leaves room between them).
constexpr double kSlabHalfDepth = 0.25;  ///< m
constexpr double kEdgeHalfWidth = 0.005; ///< m

/// Shape, material, pose and velocities of a 2D rigid body.
struct RigidBody2D {
    Shape2DKind shape = Shape2DKind::Box;
    Vec2 halfExtents{0.5, 0.5}; ///< box: m
    double radius = 0.5;        ///< circle: m
    std::vector<Vec2> vertices; ///< polygon: m, body frame, convex, counter-clockwise
    Vec2 from{-1.0, 0.0};       ///< edge: m, body frame
    Vec2 to{1.0, 0.0};          ///< edge: m, body frame
    double mass = 0.0;          ///< kg; 0 = static
    double friction = 0.6;
    double restitution = 0.0;
    bool canSleep = true;
    Vec3 color{0.62, 0.60, 0.56}; ///< RGB in [0, 1], for the renderer only

    // state, as the bridge last left it
    Vec2 position{0.0, 0.0};      ///< m
    double angle = 0.0;           ///< rad, counter-clockwise about z
    Vec2 velocity{0.0, 0.0};      ///< m/s
    double angularVelocity = 0.0; ///< rad/s
    bool sleeping = false;

    // bridge
    std::int32_t bodyId = -1;
    Vec2 impulse{0.0, 0.0};      ///< N s at the centre, applied and cleared at the next step
    double angularImpulse = 0.0; ///< N m s, likewise
    bool teleported = false;
    bool retuned = false; ///< mass, material or sleep set from outside: the bridge gives them to Box2D

    bool dynamic() const { return mass > 0.0; }

    /// The centre of mass in the body's frame, which Box2D's velocities, impulses and turns are about: a
    /// polygon's centroid (its vertices are given about the body's position and need not be centred);
    /// every other shape is centred on the position.
    Vec2 localCentre() const {
        if (shape != Shape2DKind::Polygon) {
            return {0.0, 0.0};
        }
        double area = 0.0, cx = 0.0, cy = 0.0;
        for (std::size_t i = 0; i < vertices.size(); ++i) {
            const Vec2 &p = vertices[i], &q = vertices[(i + 1) % vertices.size()];
            const double cr = p[0] * q[1] - q[0] * p[1];
            area += 0.5 * cr;
            cx += (p[0] + q[0]) * cr / 6.0;
            cy += (p[1] + q[1]) * cr / 6.0;
        }
        return {cx / area, cy / area};
    }

    /// A point of the body's frame in the world's plane, and back.
    Vec2 toWorld(Vec2 local) const {
        const double c = std::cos(angle), s = std::sin(angle);
        return {position[0] + c * local[0] - s * local[1], position[1] + s * local[0] + c * local[1]};
    }
    Vec2 toLocal(Vec2 world) const {
        const double c = std::cos(angle), s = std::sin(angle);
        const double dx = world[0] - position[0], dy = world[1] - position[1];
        return {c * dx + s * dy, -s * dx + c * dy};
    }

    /// The velocity of the body's material at a point of the plane: v + omega x (p - centre of mass).
    Vec2 velocityAt(Vec2 world) const {
        const Vec2 c = toWorld(localCentre());
        return {velocity[0] - angularVelocity * (world[1] - c[1]),
                velocity[1] + angularVelocity * (world[0] - c[0])};
    }
};

} // namespace tumble
