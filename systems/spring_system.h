#pragma once
// The spring system: advances every SpringNetwork by one fixed step.
// Reads: SceneDef (resource: gravity). Writes: SpringNetwork x, v. Phase: fixed.
//
// Forces: gravity, Hooke springs F = -k (|L| - R) L/|L| with damping kd along the spring on the relative
// velocity, and global drag -drag v.
// Integrator: symplectic (semi-implicit) Euler, v += dt F/m, then x += dt v. First order, but it conserves
// a nearby energy, so an undamped spring oscillates with bounded energy error instead of gaining energy as
// explicit Euler does; stable while dt < 2/omega for the stiffest spring. The other integrators of the
// scenario format arrive with the mass-spring work.

#include "components/spring_network.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// One fixed step of every spring network.
void integrateSprings(World& world, const StepContext& ctx);

/// Registers the `springs` component, its dump and hash, its events and the system.
void registerSpringSystem(Catalog& catalog);

} // namespace tumble
