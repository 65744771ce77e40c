#pragma once
// Particle systems (Reeves 1983): emitters give birth to particles, which move under gravity, drag and
// the force fields, and die when their lifetime is over.
//
// emitters (phase fixed, after the force fields): births of the step, from the rate and any pending burst.
//   Reads Transform; writes ParticleEmitter. Rate births are counted, not accumulated: after n steps of dt
//   at rate r an emitter has born floor(r n dt) particles (a count within a relative 1e-9 of a whole number
//   counts as that number), so fractional births carry over exactly and 100 per second gives 200 in two
//   seconds of simulated time; set_rate carries the owed fraction into the new rate. When the
//   pool is full (max_particles), a birth is dropped, not swapped for an older particle; `dropped` counts
//   them, and the dump shows it.
// particles (phase fixed, after the emitters): ages every particle, removes the dead (the survivors past
//   the new end fill their holes, in order), and advances the rest by symplectic Euler, v += dt (g +
//   fields) with drag applied as its exact decay e^(-drag dt), then x += dt v: first order, one
//   evaluation, stable for any drag. The fields are taken
//   explicitly: a wind or vortex coefficient above 2/dt makes particles overshoot. Particles move a whole
//   step at a time, so one faster than a collider's thickness per step can pass through it. Reads SceneDef
//   (gravity), ForceField; writes ParticleEmitter. Collisions with static colliders are the collision
//   system's (collision_system.h).
//
// The update of gravity, drag, ageing and deaths runs over the packed float arrays four particles at a
// time (SSE2, which every x86-64 CPU has, so the results are the same everywhere); the rare groups that
// hold a dead particle are noted during that pass and compacted afterwards.

#include "components/particles.h"
#include "engine/catalog.h"
#include "engine/parallel.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// Births of the step for every emitter.
void emitParticles(World& world, const StepContext& ctx);

/// Ageing, deaths and motion of every emitter's particles.
void updateParticles(World& world, const StepContext& ctx);

/// Gives birth to up to n particles (fewer when the pool fills; the rest are counted as dropped), in chunks
/// over the pool's threads: each birth's draws are keyed by the emitter and the birth's number.
/// dt is the step's, which turns each particle's lifetime into the number of updates it lives through.
void spawnParticles(ParticleEmitter& emitter, std::uint64_t n, double dt, WorkerPool& threads = serialPool());

/// Sizes every array of a pool for `capacity` particles, once, at load: the update never allocates.
void reserveParticles(ParticlePool& pool, std::uint32_t capacity);

/// Ages the pool by one step (p.clock), removes the particles whose lifetime is over, and advances the
/// survivors under gravity and drag (acceleration g - drag v). Returns how many died. The vectorised kernel,
/// in chunks shared by the pool's threads; then the holes the dead leave below the new end are filled, in
/// index order, by the survivors past it, also in chunks: the same bits at any thread count.
std::uint32_t advanceParticles(ParticlePool& pool, const Vec3& gravity, float drag, float dt,
                               WorkerPool& threads = serialPool());

/// Registers the `emitter` component, its dump, hash and events.
void registerParticleSystem(Catalog& catalog);

} // namespace tumble
