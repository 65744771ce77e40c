#pragma once
// The spring system: advances every spring network by one fixed step with its own integrator
// (spring_integrators.h), then checks it: a network whose state turns non-finite or faster than 10 km/s
// has blown up; it is frozen where it is, the run report names the entity, frame, integrator and a remedy,
// and the rest of the scene runs on.
// Reads: SceneDef (gravity), ForceField. Writes: SpringNetwork, SpringWorkspace, RunReport. Phase: fixed.
// It reads the clock to choose where a network's loops run (engine/thread_choice.h), never what they compute.
//
// It also registers the network builders' scenario keys: `springs` (masses and links given), `rope`,
// `cloth` and `softbody` (spring_builders.h), the dump and hash of a network, and the events impulse,
// set_velocity, pin and unpin.

#include "components/spring_network.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <cstddef>
#include <vector>

namespace tumble {

/// One fixed step of every spring network.
void integrateSprings(World& world, const StepContext& ctx);

/// A network step's work, to share the networks out over threads: its masses times what a mass costs a step
/// under its integrator, relative to symplectic Euler.
double networkWork(const SpringNetwork& net);

/// Which networks step alone, one after another, each with its loops shared over every thread, before the
/// rest step side by side, each on one thread. Stepping alone or not, a network's loops share out only while
/// its clock finds that faster than keeping them on the thread that steps it (SpringWorkspace::threadChoice,
/// engine/thread_choice.h: the clock decides where the work runs, never what it computes). Which thread runs
/// what changes no bit (each network touches only itself), only the time: side by side, a network with more
/// than an equal share of the work is left on one thread while the others idle. So the largest steps alone
/// while its work is more than an equal share of the work left (shared by the threads, or by the networks
/// left if they are fewer), then the next largest, and so on.
struct NetworkShares {
    std::vector<std::size_t> alone;    ///< largest first (ties: entity order)
    std::vector<std::size_t> together; ///< in entity order
};
NetworkShares shareOutNetworks(const std::vector<double>& work, int threads);

/// Registers the spring network components, their dump and hash and their events.
void registerSpringSystem(Catalog& catalog);

} // namespace tumble
