#pragma once
// The bridge to Box2D (2D rigid bodies in the scene's xy plane). A resource, Box2DWorld, owns the b2World;
// RigidBody2D and Joint components hold the ids. The same three steps as the Bullet bridge
// (systems/bullet_bridge.h), box2dSyncIn in the same stages under the same names (create world, remove dead
// joints, remove dead bodies, add bodies and apply pushes, add joints) with the same slot bookkeeping,
// box2dStep takes one b2World::Step of the scene's dt with the scene's velocity and position iterations,
// box2dSyncOut copies poses and velocities back. Box2D works in float (its only build).

#include "engine/scene.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <memory>

namespace tumble {

/// Box2D's world and everything in it (an opaque resource).
class Box2DWorld {
public:
    explicit Box2DWorld(const SceneDef& scene);
    ~Box2DWorld();
    Box2DWorld(const Box2DWorld&) = delete;
    Box2DWorld& operator=(const Box2DWorld&) = delete;

    struct Impl;
    Impl& impl() { return *m_impl; }

    /// Bodies and joints in Box2D now (for tests; the body the world's joints hang from is not counted).
    std::size_t bodyCount() const;
    std::size_t jointCount() const;

private:
    std::unique_ptr<Impl> m_impl;
};

void box2dSyncIn(World& world, const StepContext& ctx);
void box2dStep(World& world, const StepContext& ctx);
void box2dSyncOut(World& world, const StepContext& ctx);

/// Area of a 2D body's shape (m^2): what its mass is spread over.
double shapeArea2D(const struct RigidBody2D& body);

} // namespace tumble
