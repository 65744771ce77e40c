#pragma once
// A rigid body as the scenario describes it, and as the bridges (systems/bullet_bridge.h) last left it.
// The physics engine owns the body; this component holds its shape and material, a copy of its pose and
// velocities written back after every step (what the dump, the hash, the renderer and the colliding springs
// and particles read), the engine's id, and the pushes that wait for the next step (impulses from events,
// springs and particles; a teleport flag for poses set from outside).
// Static bodies (mass 0) never move; springs and particles collide with every body by geometry of our own
// (systems/collision_system.h).

#include "engine/math.h"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace tumble {

/// Collision shapes (README, "Rigid bodies": `shape`).
enum class ShapeKind : std::uint8_t { Plane, Box, Sphere, Capsule, Cylinder, Convex, Mesh };

/// A triangle mesh from an OBJ file, in the body's frame: a convex hull's points or a static mesh.
struct ShapeMesh {
    std::string path;                                    ///< as the scenario names it
    std::vector<Vec3> vertices;                          ///< m
    std::vector<std::array<std::uint32_t, 3>> triangles; ///< counter-clockwise seen from outside
    std::vector<Vec3> faceNormals;                       ///< per triangle, unit, outward
    std::vector<int> faceLines;                          ///< per triangle, its line in the file
    Vec3 lo, hi;                                         ///< bounds, m
    Vec3 centre;                                         ///< convex: the file's point now at the origin
};

/// Shape, material, pose and velocities of a rigid body (3D, Bullet).
struct RigidBody {
    ShapeKind shape = ShapeKind::Box;
    Vec3 normal{0.0, 1.0, 0.0};      ///< plane: unit normal
    Vec3 halfExtents{0.5, 0.5, 0.5}; ///< box: m, in the body's frame
    double radius = 0.5;             ///< sphere, capsule, cylinder: m
    double height = 1.0; ///< capsule, cylinder: m, along the body's y (the capsule's straight part)
    std::shared_ptr<const ShapeMesh> mesh; ///< convex, mesh
    double mass = 0.0;                     ///< kg; 0 = static
    double friction = 0.6;
    double restitution = 0.0;
    bool canSleep = true; ///< Bullet may put it to sleep when it rests
    bool slab =
        false; ///< a 2D body's stand-in (systems/collision_system.h slabOf): what is inside leaves in-plane
    Vec3 color{0.62, 0.60, 0.56}; ///< RGB in [0, 1], for the renderer only

    // state, as the bridge last left it (the loader sets the start)
    Vec3 position;         ///< m, centre (plane: a point on it)
    Quat orientation;      ///< body frame to world
    Vec3 linearVelocity;   ///< m/s
    Vec3 angularVelocity;  ///< rad/s, world axes
    bool sleeping = false; ///< resting, not simulated until touched
    bool frozen = false;   ///< it blew up: kept where it was last finite, no longer simulated

    // bridge
    std::int32_t bodyId = -1; ///< the engine's body; -1 until the bridge has made it
    Vec3 impulse;             ///< N s at the centre of mass, applied and cleared at the next step
    Vec3 angularImpulse;      ///< N m s about the centre of mass, likewise
    bool teleported = false;  ///< pose or velocities set from outside: the bridge copies them in
    bool retuned = false;     ///< mass, material or sleep set from outside: the bridge gives them to Bullet

    bool dynamic() const { return mass > 0.0; }
    /// A point of the body's frame in world space.
    Vec3 toWorld(const Vec3& local) const { return position + rotate(orientation, local); }
    /// A world point in the body's frame.
    Vec3 toLocal(const Vec3& p) const { return rotate(conjugate(orientation), p - position); }
    /// The velocity of the body's material at world point p.
    Vec3 velocityAt(const Vec3& p) const { return linearVelocity + cross(angularVelocity, p - position); }
};

} // namespace tumble
