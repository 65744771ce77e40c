#pragma once
// The forces on a spring network and their Jacobians.
//
// Spring between masses a and b, with d = x_b - x_a, l = |d|, u = d / l:
//   F_a = k (l - R) u + kd ((v_b - v_a) . u) u,   F_b = -F_a
//   dF_a/dx_a = -K,  K = k [ u u^T + max(0, 1 - R/l) (I - u u^T) ]
//   dF_a/dv_a = -kd u u^T
// The max(0, .) drops the transverse term of a compressed spring, whose true value is negative and would
// make the system matrix indefinite (Choi & Ko 2002); it only changes the Newton direction, not the force.
// Gravity m g, global drag -drag v, and the force fields (force_field_system.h) are added per mass; wind on
// cloth acts through its triangles' normals. An air grid (systems/air_solver.h) acts as wind does, with
// its velocity where the mass (or the triangle's centroid) is, on what is inside its box. External forces are
// taken explicitly by implicit Euler, except their linear damping, which joins the system matrix.

#include "components/air.h"
#include "components/force_field.h"
#include "components/spring_network.h"
#include "systems/block_sparse.h"

#include <cstddef>
#include <emmintrin.h>
#include <vector>

namespace tumble {
class Profiler;
class WorkerPool;
} // namespace tumble

namespace tumble {

/// Items per chunk of the per-mass, per-link and per-triangle loops (the force loops and implicit Euler's
/// assembly): fixed, so the chunks do not depend on the thread count, and small enough that a cloth the
/// size of the curtain (1225 masses, 7002 links, 2312 triangles) shares out evenly over two threads: in
/// chunks of 512 masses (two of 512 and one of 201) one thread did 713 while the other waited. None of
/// these loops is a sum, so the chunks change no bit.
constexpr std::size_t kMassGrain = 128, kLinkGrain = 512, kTriangleGrain = 256;

/// What acts on a network besides its springs.
struct Environment {
    Vec3 gravity;                                    ///< m/s^2
    const std::vector<ForceField>* fields = nullptr; ///< the scene's force fields, or none
    Profiler* profiler = nullptr;                    ///< for the integrators' stages; null when untimed
    WorkerPool* pool = nullptr; ///< threads for the per-mass and per-link loops; null: one thread
    const std::vector<const Air*>* air = nullptr; ///< the scene's air grids, or none
};

/// Each mass's links and cloth triangles, in order, and room for one evaluation's per-link and per-triangle
/// forces. The force loops compute per link and per triangle, then each mass gathers its own in link and
/// triangle order: exactly the additions a scatter in that order makes, so any thread count gives the
/// same bits.
struct ForceIncidence {
    std::vector<std::uint32_t> linkStart, links;         ///< per mass: link * 2 + side (side 1: the link's b)
    std::vector<std::uint32_t> triangleStart, triangles; ///< per mass: the triangles it is a corner of
    std::vector<Vec3> perLink, perTriangle;              ///< scratch: the force of each, this evaluation
    std::vector<Mat3> perTriangleBlock;                  ///< scratch: each triangle's wind damping block
    std::vector<std::uint8_t> linkActive, triangleActive; ///< scratch: whether it adds anything

    /// Builds the lists for the network's masses, links and triangles if they changed in number.
    void update(const SpringNetwork& net);
};

/// Gravity, drag and force fields on every mass (f is overwritten).
void externalForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                    const std::vector<Vec3>& v, std::vector<Vec3>& f, ForceIncidence& incidence);

/// Net force on every mass for positions x and velocities v (pinned masses get whatever acts on them).
void springForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                  const std::vector<Vec3>& v, std::vector<Vec3>& f, ForceIncidence& incidence);
/// The same, with lists made for this call (for a caller that evaluates forces once).
void springForces(const SpringNetwork& net, const Environment& env, const std::vector<Vec3>& x,
                  const std::vector<Vec3>& v, std::vector<Vec3>& f);

/// A spring's unit direction u from a to b, its length, and the fraction t = max(0, 1 - rest / len) of its
/// stiffness that acts across it: K = k [(1 - t) u u^T + t I] (see the header comment). Returns false for
/// coincident masses (no direction). Inline, and its max without a branch: whether a spring is stretched
/// changes from spring to spring, and a branch on the division's result, mispredicted, held up the loops
/// over links.
inline bool springAxis(const SpringLink& s, const Vec3& xa, const Vec3& xb, Vec3& u, double& len,
                       double& transverse) {
    const Vec3 d = xb - xa;
    len = length(d);
    if (len <= 1e-12) {
        return false;
    }
    u = d * (1.0 / len);
    // maxsd(x, 0) is x > 0 ? x : +0: std::max(0.0, x) to the bit (-0 and NaN give +0)
    transverse = _mm_cvtsd_f64(_mm_max_sd(_mm_set_sd(1.0 - s.rest / len), _mm_setzero_pd()));
    return true;
}

/// The stiffness block K of a spring (see the header comment), its unit direction from a to b and its length.
/// Returns false for coincident masses (no direction).
bool springStiffness(const SpringLink& s, const Vec3& xa, const Vec3& xb, Mat3& k, Vec3& u, double& len);

/// Adds -h dF/dv of the wind on cloth triangles to the diagonal blocks, lumped onto the corners: a
/// triangle's force on each corner is c A/3 ((w - vbar) . n) n with vbar the mean of its corners'
/// velocities, so its exact Jacobian couples every pair of corners by c A/9 n n^T. Lumped, each corner
/// takes the row sum, c A/3 n n^T, alone: the difference is positive semidefinite, so the lumped system
/// damps at least as much (stable), keeps the springs' pattern, and measured fewer CG iterations than the
/// exact coupling (15.5 against 17.6 on the 100 x 100 curtain).
void addWindDamping(const SpringNetwork& net, const Environment& env, double h, ForceIncidence& incidence,
                    std::vector<Mat3>& diagonal);

/// Linear damping on each mass from drag and fields, N s/m (dF/dv = -c I).
double massDamping(const SpringNetwork& net, const Environment& env, const Vec3& x);

} // namespace tumble
