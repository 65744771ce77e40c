#pragma once
// Stable fluids (Stam 1999) on the air's staggered grid (components/air.h), one fixed step:
//   1. advection: every face's velocity is taken from where the flow brought it, the point found by
//      following the face's velocity back over the step, sampled trilinearly (semi-Lagrangian:
//      unconditionally stable; first order, so it smooths); with `advection = "maccormack"`, the result
//      carried back along the same velocity and half the difference from the start taken off where that
//      stays within the values the first sample mixed, else the first sample's value (second order where
//      the field is smooth; twice the cost). The cells' smoke and heat are carried by finite volumes, so that
//      the totals change only through open sides (and by sources, dissipation and bodies taking cells): each
//      face passes its flow's share of the cell upwind of it (first-order upwind), in as many substeps as
//      keep every cell's flows within one cell a substep; with "maccormack", Lax-Wendroff's fluxes limited by
//      flux-corrected transport (Zalesak 1979: no new extremum). A flow of more than 64 cells a step takes
//      the semi-Lagrangian step for them too (not conserving);
//   2. smoke's dissipation, implicit: s / (1 + dt d);
//   3. forces: buoyancy along gravity, (smoke_weight s - heat_lift (T - mean T)) per unit of gravity's
//      direction (a uniformly warm atmosphere feels none: Boussinesq, after Fedkiw, Stam and Jensen 2001),
//      and vorticity confinement, eps dx (N x omega) with N the unit gradient of |omega|;
//   4. viscosity, explicit, in as many substeps as nu dt / dx^2 <= 1/6 needs;
//   5. projection: with q = p dt / rho, the discrete Poisson problem -dx^2 Lap q = -dx^2 div u (closed
//      sides: no flow through them, Neumann; open sides: q = 0 outside, Dirichlet), solved by conjugate
//      gradients preconditioned with a multigrid V-cycle (cells merged 2 x 2 x 2, Jacobi smoothing
//      weighted by a Chebyshev polynomial's roots, symmetric), from the guess 2 q_n - q_n-1 carried on
//      from the last two steps, until every cell's divergence is under `tolerance`; then u -= grad q.
// Every loop runs over z-slabs of fixed size on the worker pool and every sum adds per-slab partials in
// slab order, so any thread count gives the same bits.

#include "components/air.h"
#include "engine/parallel.h"

namespace tumble {

/// Makes the fields (zero) and the solver's levels for the air's grid.
void initAir(Air& air);

/// A cell whose faces carry more than this in or out (m/s, summed over its faces), or a face speed that is
/// not finite: the grid has blown up.
constexpr double kMostAirSpeed = 1e4;

/// One step of dt (the steps above). `gravity` gives buoyancy its direction (straight down when zero).
/// False, having done nothing, when the grid has blown up (kMostAirSpeed).
bool stepAir(Air& air, const Vec3& gravity, double dt, WorkerPool& pool);
/// stepAir in two parts, for the sources to feed between them: step 1 (advection), then steps 2 to 5. A
/// source fed before the advection was carried off by it: a jet faster than its nozzle's size a step left
/// nothing behind. advectAir is false, having done nothing, when the grid has blown up.
bool advectAir(Air& air, double dt, WorkerPool& pool);
void finishAirStep(Air& air, const Vec3& gravity, double dt, WorkerPool& pool);

/// The explicit viscosity's substeps a step of dt takes (kMostViscositySubsteps + 1 when it would take
/// more than those: the load refuses such a grid).
constexpr int kMostViscositySubsteps = 1000;
int airViscositySubsteps(const Air& air, double dt);

/// The projection alone (step 5): the velocity made divergence-free to within the tolerance.
void projectAir(Air& air, WorkerPool& pool);

/// The largest divergence of a cell (1/s), from the faces as they are.
double airDivergenceMax(const Air& air, WorkerPool& pool);

/// Whether a world point is inside the air's box.
bool airContains(const Air& air, const Vec3& point);

/// The velocity at a world point (each component trilinear between its faces; clamped to the box).
Vec3 airVelocityAt(const Air& air, const Vec3& point);

/// Summaries for the dump: smoke's total (density times m^3), its centroid (world, m; the box's centre
/// when there is none), the kinetic energy (J, air of 1.2 kg/m^3).
double airSmokeTotal(const Air& air);
Vec3 airSmokeCentroid(const Air& air);
double airKineticEnergy(const Air& air);

} // namespace tumble
