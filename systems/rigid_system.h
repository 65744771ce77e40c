#pragma once
// Rigid bodies: the `rigid_body` (Bullet, 3D) and `rigid_body_2d` (Box2D, in the xy plane) components,
// [[joint]]s between them, their dump kinds "rigid" and "rigid2d", the events `impulse` and `set_velocity`
// on them, and the bridge systems, which run in the fixed phase after the springs' and particles'
// collisions (so the pushes those leave on bodies are applied in the same step):
//   rigid_in   both bridges: make and remove bodies and constraints, copy in what was pushed or set;
//   bullet     one Bullet step of dt;            box2d   one Box2D step of dt;
//   rigid_out  both bridges: copy poses and velocities back to the components.
// See systems/bullet_bridge.h and systems/box2d_bridge.h for the bridges themselves.

#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// Registers the rigid-body components, joints, codecs and events (the systems are in builtin.cpp's table).
void registerRigidSystem(Catalog& catalog);

/// The `rigid_in` system: both bridges' sync-in (systems/bullet_bridge.h, systems/box2d_bridge.h).
void syncRigidIn(World& world, const StepContext& ctx);
/// The `rigid_out` system: both bridges' sync-out.
void syncRigidOut(World& world, const StepContext& ctx);

} // namespace tumble
