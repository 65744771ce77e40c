#pragma once
// The spring system: advances every spring network by one fixed step with its own integrator
// (spring_integrators.h), then checks it: a network whose state turns non-finite or faster than 10 km/s
// has blown up; it is frozen where it is, the run report names the entity, frame, integrator and a remedy,
// and the rest of the scene runs on.
// Reads: SceneDef (gravity), ForceField. Writes: SpringNetwork, SpringWorkspace, RunReport. Phase: fixed.
//
// It also registers the network builders' scenario keys: `springs` (masses and links given), `rope`,
// `cloth` and `softbody` (spring_builders.h), the dump and hash of a network, and the events impulse,
// set_velocity, pin and unpin.

#include "components/spring_network.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// One fixed step of every spring network.
void integrateSprings(World& world, const StepContext& ctx);

/// Registers the spring network components, their dump and hash and their events.
void registerSpringSystem(Catalog& catalog);

} // namespace tumble
