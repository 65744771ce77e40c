#pragma once
// The mouse spring: how a person holds and throws things in `tumble view`, as events any run can replay.
//
// Events ([[event]], README "The viewer"; recorded like any input):
// - grab: value = [i] (a spring network's mass), [x, y, z] (a rigid body's point, body frame), [x, y] (a 2D
//   body's point) or nothing (a particle emitter); position = the target, world m.
// - drag: position = the new target. release: lets go.
// - set_integrator: value = k, a spring network's integrator from then on (0 explicit_euler, 1 midpoint,
//   2 rk4, 3 symplectic_euler, 4 implicit_euler).
//
// System `mouse_spring` (phase fixed, after the force fields, before what it pushes): a damped spring of
// natural frequency kOmega (rad/s) on the whole held thing, so that a light rope and a heavy crate follow
// the mouse alike. A spring network's mass i gets stiffness k = M omega^2 and damping c = 2 M omega (M the
// network's free mass), taken implicitly on that mass alone (backward Euler: stable at any step, however
// light the mass); a rigid body gets the force M omega^2 d - M omega v at the held point, as an impulse
// over the step (omega dt = 0.2 at 60 Hz, well inside the explicit limit). An emitter has no mass: it is
// moved to the target. Reads Grab, SpringNetwork, RigidBody, RigidBody2D; writes their velocities and
// impulses, an emitter's Transform and origin.

#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// Natural frequency of the mouse spring, rad/s (2 Hz).
inline constexpr double kGrabOmega = 2.0 * 3.14159265358979323846 * 2.0;

/// One step of every held thing's mouse spring.
void pullGrabs(World& world, const StepContext& ctx);

/// Registers the grab events.
void registerGrabSystem(Catalog& catalog);

} // namespace tumble
