#pragma once
// Collisions of spring networks and particles with rigid bodies (3D, static or moving), by geometry of our
// own: each shape has a signed distance and an outward normal, in the body's frame; a mass closer than the
// network's thickness is pushed out to that distance, loses the velocity relative to the surface that
// points into it, and its sliding velocity is reduced by Coulomb friction (|dv_t| <= friction |dv_n|). A
// moving body takes the momentum the mass lost (an impulse left on RigidBody, applied by the Bullet bridge
// in the same step), so cloth weighs on a crate.
// Particles (with collide = true) bounce instead: restitution reverses part of the normal speed; they carry
// no mass and push nothing. 2D (Box2D) bodies take part as the slabs they are drawn as
// (components/rigid_body_2d.h: a box, a cylinder along z, a prism, a thin strip for an edge, about their
// entity's z), after the 3D bodies; what a mass pushes on one reaches it in its plane, and about z.
// System: reads RigidBody, RigidBody2D and Transform, writes SpringNetwork and ParticleEmitter x, v and the
// bodies' impulses. Phase: fixed, after the springs and before the rigid bridges.

#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"
#include "systems/bvh.h"

namespace tumble {

/// Signed distance from a body's surface to world point p (negative inside), and the outward normal there.
/// Convex hulls and meshes: see the notes at their cases.
double signedDistance(const RigidBody& body, const Vec3& p, Vec3& normal);

/// The same for a point in the body's frame; the normal is in the body's frame too.
double localSignedDistance(const RigidBody& body, const Vec3& local, Vec3& normal);

/// A body's box in the world; false for what has no bounds to speak of: a plane, and a static mesh (a
/// point below a terrain is inside it, however far below).
bool worldBox(const RigidBody& body, Aabb& box);

/// A 2D body as the 3D shape it is drawn as (components/rigid_body_2d.h): a slab about z (its entity's z),
/// in the body's pose advanced by its velocity over dt, and moving as it does; a circle is a cylinder along
/// z, a polygon a prism, an edge a thin box about its middle (moving as the body's point there). The
/// water floats 2D bodies as these too.
RigidBody slabOf(const RigidBody2D& body, double z, double dt);

/// Pushes every spring network's masses out of every static body.
void collideSprings(World& world, const StepContext& ctx);

/// Puts every colliding particle back on the surface of the static body it entered, its normal speed
/// reversed and scaled by restitution, its sliding speed reduced by friction.
void collideParticles(World& world, const StepContext& ctx);

/// The `collisions` system: the spring networks' masses, then the particles.
void collideWithBodies(World& world, const StepContext& ctx);

/// The `collisions_2d` system, after the rigid bridges: puts every mass and particle that Box2D's step left
/// inside a 2D body (its position correction moves bodies a millimetre without a velocity) back outside
/// it where it now is, without touching velocities; so none ends a step inside one.
void settleOutside2DBodies(World& world, const StepContext& ctx);

} // namespace tumble
