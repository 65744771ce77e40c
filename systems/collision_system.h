#pragma once
// Collisions of spring networks and particles with rigid bodies (3D, static or moving), by geometry of our
// own: each shape has a signed distance and an outward normal, in the body's frame; a mass closer than the
// network's thickness is pushed out to that distance, loses the velocity relative to the surface that
// points into it, and its sliding velocity is reduced by Coulomb friction (|dv_t| <= friction |dv_n|). A
// moving body takes the momentum the mass lost (an impulse left on RigidBody, applied by the Bullet bridge
// in the same step), so cloth weighs on a crate.
// Particles (with collide = true) bounce instead: restitution reverses part of the normal speed; they carry
// no mass and push nothing. Neither collides with 2D (Box2D) bodies.
// System: reads RigidBody, writes SpringNetwork and ParticleEmitter x, v and RigidBody impulses. Phase:
// fixed, after the springs and before the rigid bridges.

#include "components/rigid_body.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// Signed distance from a body's surface to world point p (negative inside), and the outward normal there.
/// Convex hulls and meshes: see the notes at their cases.
double signedDistance(const RigidBody& body, const Vec3& p, Vec3& normal);

/// The same for a point in the body's frame; the normal is in the body's frame too.
double localSignedDistance(const RigidBody& body, const Vec3& local, Vec3& normal);

/// Pushes every spring network's masses out of every static body.
void collideSprings(World& world, const StepContext& ctx);

/// Puts every colliding particle back on the surface of the static body it entered, its normal speed
/// reversed and scaled by restitution, its sliding speed reduced by friction.
void collideParticles(World& world, const StepContext& ctx);

/// The `collisions` system: the spring networks' masses, then the particles.
void collideWithBodies(World& world, const StepContext& ctx);

} // namespace tumble
