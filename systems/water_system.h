#pragma once
// Height-field water (the grid method of the lecture material): the discrete 2D wave equation
//   u_tt = c^2 (u_xx + u_zz) - damping u_t
// on the nodes of a regular grid, by symplectic Euler (v += dt (c^2 Lap(u) - damping v); u += dt v), with
// the five-point Laplacian. Stable while c dt sqrt(1/dx^2 + 1/dz^2) <= 1 (the CFL limit); a scene whose dt
// breaks it takes as many wave steps per fixed step as it needs, and says so once.
// Borders: `reflect` (the surface's slope is zero there: waves bounce back) or `absorb` (a first-order
// one-way condition, u_t = -c u_n, after Engquist & Majda: waves leave with little reflection).
// Disturbances: the `disturb` event (position, radius, amount: a smooth raised or lowered bump) and a wave
// maker (one edge driven up and down). Rigid bodies, both ways: a body floats on the ambient surface (the
// waves no body made, a second height field), cut into vertical columns with its shape's exact extent, each
// lifted by the weight of the water it displaces (buoyancy and the righting torque), the response to its
// own motion implicit in the waterline's stiffness (stable at any density ratio); the surface's slope carries
// it; the water it pushes aside leaves the nodes under it and raises the rest (the volume kept), making its
// waves. 2D bodies float as the slabs they are drawn as (systems/collision_system.h slabOf). Spring
// networks (cloth, ropes, soft bodies, fem bodies) float mass by mass, each the cube of its share of the
// network's volume, with the same lift, heave, slope, drag and displacement, and the resistance of the
// cube's face (a force on each mass through the next step). Particles that collide are
// drops it takes in: they die where they fall in, and their volume rings the surface. System: reads
// Transform; writes Water, the impulses on RigidBody and RigidBody2D, SpringNetwork's water force and
// ParticleEmitter deaths. Phase: fixed, after the rigid bridges.

#include "components/water.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// One fixed step of every water surface, with the bodies in it.
void stepWater(World& world, const StepContext& ctx);

/// Registers the `water` component, its dump kind "water" and the `disturb` event.
void registerWaterSystem(Catalog& catalog);

} // namespace tumble
