#pragma once
// Air on a grid in the scene (README, "Air"): the `air` component (a box of cubic cells advanced by
// stable fluids, systems/air_solver.h) and the `air_source` component that feeds one (smoke, heat and a
// velocity in a sphere or box about its entity). Each fixed step, grid by grid: the rigid bodies and the
// driving sources are voxelised into it (stage air.bodies), its advection, its sources feed it, then the
// rest of its step (systems/air_solver.h). System: reads SceneDef,
// Transform, AirSource and RigidBody; writes Air. Phase:
// fixed, after the water. Dump kind "air": `cells`, `smoke_total`, `smoke_centroid`, `divergence_max`,
// `kinetic_energy`, and with `dump_fields = true` the fields `u`, `v`, `w`, `smoke`, `heat`.

#include "components/air.h"
#include "components/rigid_body.h"
#include "engine/catalog.h"
#include "engine/step_context.h"
#include "engine/world.h"

namespace tumble {

/// One fixed step of every air grid (the order above).
void advanceAir(World& world, const StepContext& ctx);

/// Adds what a source at `at` gives its air over dt: smoke and heat to the cells whose centres are inside
/// its shape (the cell holding `at` when none is), and its velocity on the faces inside it (on the faces
/// of those cells when no face is inside).
void feedAir(Air& air, const AirSource& source, const Vec3& at, double dt);

/// A source that drives its air (`velocity` given), at its entity's position.
struct HeldSource {
    const AirSource* source;
    Vec3 at;
};

/// Marks the cells whose centres are inside a rigid body (all shapes but the open mesh; a plane fills what
/// is below it) as solid (kBodyCell), and holds each face between a solid cell and the air at its body's
/// velocity there: the air flows round a wall and a moving paddle pushes it. The cells of a driving source
/// (those feedAir feeds, when a cell's centre is inside; a body's where both are) are solid for the
/// projection too (kSourceCell), their faces held at the source's velocity, so that the projection keeps the
/// jet it blows (left free, it took a fan of 5 m/s down to 4); their smoke and heat stay (a body's cells hold
/// none). A source that would feed a pocket of air reaching no open side unevenly (against a closed room's
/// wall; filling a duct's closed end) is not held. A still source (velocity zero) is held still: a block the
/// air flows round.
void voxeliseSolids(Air& air, const std::vector<const RigidBody*>& bodies,
                    const std::vector<HeldSource>& sources);

/// Registers the `air` and `air_source` components and the dump kind "air".
void registerAirSystem(Catalog& catalog);

} // namespace tumble
