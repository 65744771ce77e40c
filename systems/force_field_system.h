#pragma once
// Force fields: the `force_field` component's loader and the system that updates each field once per
// fixed step (wind gusts). The forces a field exerts are in field_forces.h, shared by the systems that
// move bodies through fields.
// System: reads ForceField, Transform; writes ForceField::current, origin. Phase: fixed, first.
//
// - wind: air moving at `strength` (m/s), varied by gusts: |w| scales by 1 + gust g(t), g a smooth sum of
//   three sines whose phases come from the scene seed. A point mass feels coefficient (w - v); a cloth
//   triangle feels coefficient * area * ((w - v) . n) n, so a curtain billows.
// - drag: -strength.x v.
// - vortex: turning about `axis` through the field's position at omega = strength.x rad/s, within
//   `radius` (0 = everywhere): a mass feels the pull -m omega^2 r towards the axis, which keeps a body
//   circling at omega on its circle, plus coefficient (u - v), u = omega axis x r, the air's drag that
//   spins bodies up to omega. With coefficient 0 it is a central force and the radius of a circling body
//   is conserved.
// - point: an attractor pulling strength.x * m / d^2 (softened within 0.1 m), within `radius`.

#include "components/force_field.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <vector>

namespace tumble {

/// Updates every field's current wind and origin for this step.
void updateForceFields(World& world, const StepContext& ctx);

/// Registers the `force_field` component.
void registerForceFieldSystem(Catalog& catalog);

} // namespace tumble
