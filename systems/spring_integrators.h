#pragma once
// The five integrators of a spring network. With h the step, a(x, v) = F(x, v) / m:
//
// explicit_euler    x' = x + h v, v' = v + h a(x, v). First order. Unstable for any undamped spring
//                   (energy grows by a factor 1 + (omega h)^2 per step); one force evaluation.
// midpoint          a half step of explicit Euler, then the full step with the midpoint's slopes. Second
//                   order; still slowly gains energy on oscillators, stable while omega h < ~1 with damping;
//                   two force evaluations.
// rk4               classic fourth-order Runge-Kutta. Fourth order; stable while omega h < 2.8; loses a
//                   little energy; four force evaluations.
// symplectic_euler  v' = v + h a(x, v), then x' = x + h v'. First order, but symplectic: the energy of an
//                   undamped oscillator stays within O(omega h) of its start forever; stable while
//                   omega h < 2; one force evaluation. The cheapest integrator worth using.
// implicit_euler    backward Euler linearised once per step (Baraff & Witkin 1998):
//                   (M - h dF/dv - h^2 dF/dx) dv = h (F + h dF/dx v), v' = v + dv, x' = x + h v'.
//                   First order; unconditionally stable, at the price of numerical damping (energy is
//                   lost, more at larger h). Cost: assembling the sparse 3x3-block system (pattern built
//                   once) and a conjugate-gradient solve started from the best combination of the last
//                   steps' dv (warm start) and preconditioned by multigrid (linear_solver.h). Pinned masses
//                   are constraint-filtered.

#include "components/spring_network.h"
#include "engine/thread_choice.h"
#include "systems/block_sparse.h"
#include "systems/fem.h"
#include "systems/linear_solver.h"
#include "systems/spring_forces.h"

#include <array>
#include <vector>

namespace tumble {

/// One link's part of the implicit system in a step, taken by its two masses with opposite signs: the block
/// h kd u u^T + h^2 K = along u u^T + across I (K = k [(1 - t) u u^T + t I]: spring_forces.h), kept as u
/// and the two coefficients (5 doubles where the whole block is 9), and h F_a + h^2 K (v_b - v_a).
struct LinkTerms {
    Vec3 u;
    double along = 0.0, across = 0.0;
    Vec3 rhs;
    bool active = false; ///< false for coincident masses: no direction, nothing added

    Mat3 block() const {
        Mat3 b = Mat3::outer(u, along);
        b.m[0] += across;
        b.m[4] += across;
        b.m[8] += across;
        return b;
    }
};

/// The implicit solver's state in one precision: the system (fixed pattern), its preconditioner, and the
/// last velocity change (the next solve's warm start).
template <class S>
struct ImplicitSolver {
    BlockMatrix<S> system;                                ///< the links plus the diagonal
    std::vector<std::array<std::uint32_t, 2>> linkBlocks; ///< per link: its (a, b) and (b, a) blocks
    std::vector<LinkTerms> terms;                         ///< per link, this step's terms (see implicitEuler)
    std::vector<Mat3> sums;                               ///< the diagonal blocks, summed in double
    std::vector<std::uint32_t> pinnedBlocks;              ///< blocks to clear for pinned rows and columns
    AggregationMultigrid<S> multigrid;
    PcgVectors<S> pcg;
    std::vector<Vec3T<S>> rhs;
    std::vector<Vec3T<S>> dv; ///< last step's velocity change: the warm start
    std::vector<std::uint8_t> pinnedWhenBuilt;
};

/// Scratch of one network's integrator, kept between steps so that a step allocates nothing. Only the
/// implicit solvers' `dv` (warm starts) and the solutions their PcgVectors remember carry over from one step
/// to the next, and the choice of threads (which changes no bit).
struct SpringWorkspace {
    std::vector<Vec3> f;              ///< forces
    std::vector<Vec3> xs, v2, v3, v4; ///< stage positions and velocities (midpoint, rk4)
    std::vector<Vec3> a1, a2, a3, a4; ///< stage accelerations
    /// Each mass's links and triangles: the force loops and the implicit assembly gather per mass from them.
    ForceIncidence incidence;

    ImplicitSolver<float> single;   ///< implicit Euler, solver_precision = "float" (the default)
    ImplicitSolver<double> precise; ///< implicit Euler, solver_precision = "double"
    FemSolver fem;                  ///< an fem body's (kind Fem)
    SolveStats lastSolve;
    /// Whether this network's loops share out over the pool or stay on the thread that steps it
    /// (engine/thread_choice.h): speed only, never bits.
    ThreadChoice threadChoice;
};

/// Advances a network by one step of its integrator (an fem body: systems/fem.h).
void stepNetwork(SpringNetwork& net, SpringWorkspace& work, const Environment& env, double h);

} // namespace tumble
