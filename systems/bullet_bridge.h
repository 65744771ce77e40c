#pragma once
// The bridge to Bullet (3D rigid bodies). A resource, BulletWorld, owns Bullet's btDiscreteDynamicsWorld
// and every body, shape and constraint in it; RigidBody and Joint components hold the ids. Each fixed step:
//   bulletSyncIn   in stages named as the Box2D bridge's: create the world (on the first step with a body),
//                  remove dead joints, remove dead bodies, add bodies and apply pushes (poses set from
//                  outside, the impulses events, springs and particles left on the components), add joints;
//                  the slots that map ids to Bullet's objects are systems/bridge_slots.h's, shared;
//   bulletStep     advances Bullet by exactly one internal step of the scene's dt;
//   bulletSyncOut  copies poses and velocities back into RigidBody and Transform.
//
// Bullet is linked in its single-precision build. Debian ships both; on the 1000-box stack of
// tests/bench/rigid_bench.cpp the double build took 10.5 ms a step against 7.0-8.2 ms for single (raw
// Bullet, same machine, same run), and single is the build Bullet is made and tested for. Poses cross the
// bridge as floats into Bullet and come back exactly as doubles; at the scale of these scenes (within
// 100 m of the origin) a float resolves 10 um.
// Bodies are made in entity order, so a scene gives Bullet the same insertion order, and the same bits,
// every run.

#include "engine/scene.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <memory>

namespace tumble {

/// Bullet's world and everything in it (an opaque resource).
class BulletWorld {
public:
    explicit BulletWorld(const SceneDef& scene);
    ~BulletWorld();
    BulletWorld(const BulletWorld&) = delete;
    BulletWorld& operator=(const BulletWorld&) = delete;

    struct Impl;
    Impl& impl() { return *m_impl; }

    /// Bodies and constraints in Bullet now (for tests).
    std::size_t bodyCount() const;
    std::size_t constraintCount() const;

private:
    std::unique_ptr<Impl> m_impl;
};

/// Sets Bullet's process-wide rules for touching materials to Tumble's: friction the geometric mean,
/// restitution the larger (as Box2D and our own collisions have them). Every BulletWorld sets them.
void setBulletMaterialRules();

void bulletSyncIn(World& world, const StepContext& ctx);
void bulletStep(World& world, const StepContext& ctx);
void bulletSyncOut(World& world, const StepContext& ctx);

} // namespace tumble
