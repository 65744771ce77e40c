#pragma once
// Collisions of spring networks with static rigid bodies (mass 0), by geometry of our own: each shape has
// a signed distance and an outward normal; a mass closer than the network's thickness is pushed out to
// that distance, loses the velocity that points into the surface, and its sliding velocity is reduced by
// Coulomb friction (|dv_t| <= friction |dv_n|).
// Particles (with collide = true) bounce instead: restitution reverses part of the normal speed.
// System: reads RigidBody (static), writes SpringNetwork and ParticleEmitter x, v. Phase: fixed, after the
// springs.

#include "components/rigid_body.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// Signed distance from a static shape's surface to p (negative inside), and the outward normal there.
double signedDistance(const RigidBody& body, const Vec3& p, Vec3& normal);

/// Pushes every spring network's masses out of every static body.
void collideSprings(World& world, const StepContext& ctx);

/// Puts every colliding particle back on the surface of the static body it entered, its normal speed
/// reversed and scaled by restitution, its sliding speed reduced by friction.
void collideParticles(World& world, const StepContext& ctx);

/// Registers the `rigid_body` component (static bodies for now) and the collision system.
void registerCollisionSystem(Catalog& catalog);

} // namespace tumble
