#pragma once
// Finite-element soft bodies: linear tetrahedra with corotational linear elasticity (Mueller and Gross
// 2004), lumped masses, Rayleigh damping, advanced by implicit or symplectic Euler.
//
// An fem body is a SpringNetwork of kind Fem whose masses are the mesh's nodes and which has no links:
// everything that works on masses (collisions with the ground and bodies, anchors, the mouse spring, the
// pin, unpin and impulse events, the renderer's surface, the hash and replays) works on it unchanged;
// only the internal forces differ, and they come from the elements (components/spring_network.h,
// FemElements).
//
// Per element, with g_a the gradient of corner a's shape function at rest (sum_a g_a = 0) and V its rest
// volume: the deformation gradient F = sum_a x_a g_a^T; its rotation R (below); the corotated strain
// e = sym(R^T F) - I; the stress s = lambda tr(e) I + 2 mu e; the force on corner a f_a = -V R s g_a. With R
// held fixed the force is linear in the positions, with the stiffness blocks
//   K_ab = V R [lambda g_a g_b^T + mu (g_a . g_b) I + mu g_b g_a^T] R^T      (df_a / dx_b = -K_ab),
// symmetric as a whole (K_ba = K_ab^T) and positive semidefinite, so implicit Euler's system
//   (M (1 + h alpha) + (h^2 + h beta) K) dv = h (f - (h + beta) K v - alpha M v)
// goes to the same block conjugate gradients and multigrid as the springs (linear_solver.h).
//
// The rotation: the polar rotation of F, found by Newton's method on the symmetry of R^T F (rotationOf),
// started from the element's rotation of the step before turned by its spin over the step (the skew part
// of dF/dt R^T: the positions moved by h v since), which leaves about 1e-4 rad to take out, one iteration.
// The first step (and an element whose F is not invertible, or where Newton does not settle) takes an SVD
// of F with the inversion handled as Irving, Teran and Fedkiw 2004 do: the sign of the smallest singular
// value's column is flipped so that R is a proper rotation. An inverted element then reads as compressed
// beyond flat along one axis and is pushed back out, never a NaN.

#include "components/spring_network.h"
#include "systems/fem_element.h"
#include "systems/linear_solver.h"
#include "systems/spring_forces.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace tumble {

/// Nodes and tetrahedra, before they become a body.
struct TetMesh {
    std::vector<Vec3> nodes;
    std::vector<std::array<std::uint32_t, 4>> tets;
    // where a mesh read from files came from, for messages: the .ele file, each element's line in it,
    // and the number the files give the first node (0 or 1)
    std::string file;
    std::vector<int> lines;
    std::uint32_t firstNode = 0;
};

/// The material of an fem body.
struct FemMaterial {
    double young = 1e5;             ///< Pa
    double poisson = 0.3;           ///< 0 <= poisson < 0.5 (the loader refuses <= -1 and >= 0.5)
    double density = 1000.0;        ///< kg/m^3
    double stiffnessDamping = 0.01; ///< s (Rayleigh beta)
    double massDamping = 0.0;       ///< 1/s (Rayleigh alpha)
};

/// A box of size[0] x size[1] x size[2] m centred on `centre`, cut into res[0] x res[1] x res[2] cells of
/// six tetrahedra each (every cube split along its diagonal the same way, so neighbours' faces match).
/// Node (i, j, k) is number i + (res[0] + 1) (j + (res[1] + 1) k).
TetMesh boxTets(const Vec3& centre, const std::array<double, 3>& size, const std::array<int, 3>& res);

/// The nodes of a box mesh on one face: "left" (min x), "right", "bottom" (min y), "top", "back" (min z),
/// "front"; false for another name.
bool boxFace(const std::string& face, const std::array<int, 3>& res, std::vector<std::uint32_t>& nodes);

/// A ball of `radius` centred on `centre`: the tetrahedra of a box mesh of `cells` cells across whose
/// centroids lie inside the sphere (its surface is stepped, as the cells' faces and diagonals make it).
TetMesh sphereTets(const Vec3& centre, double radius, int cells);

/// TetGen's .ele file and its .node beside it, the nodes moved by `offset`. Throws std::runtime_error
/// with file:line and what is wrong. At most maxNodes nodes and maxTets elements (checked from the counts
/// in the files' first lines, before anything is allocated).
TetMesh readTetGen(const std::filesystem::path& ele, const Vec3& offset, std::size_t maxNodes,
                   std::size_t maxTets);

/// The body: one mass per node (each element's mass rho V lumped equally onto its corners), the elements'
/// rest gradients and volumes, the boundary's triangles (outward, for the renderer) and the pins. Throws
/// std::invalid_argument naming the first element that is degenerate or inverted at rest, and its nodes.
SpringNetwork buildFem(const TetMesh& mesh, const FemMaterial& material,
                       const std::vector<std::uint32_t>& pins);

/// The solver's state of an fem body, kept between steps (the pattern and warm start of implicit Euler).
struct FemSolver {
    BlockMatrix<float> system;
    std::vector<std::uint32_t> mirror; ///< per block (i, j): the block (j, i)
    std::vector<Vec3> rhs;
    std::vector<Vec3T<float>> rhsFloat, dv; ///< dv: the last step's velocity change (the warm start)
    std::vector<std::uint32_t> pinnedBlocks;
    std::vector<std::uint8_t> pinnedWhenBuilt;
    std::vector<double> restingWeights;      ///< per resting contact, this step's c (resting_contacts.h)
    std::vector<Mat3T<float>> restingBlocks; ///< per resting contact, its node's block before it
    AggregationMultigrid<float> multigrid;
    PcgVectors<float> pcg;
    // what implicit Euler's assembly keeps of each element between its two passes
    std::vector<std::array<Vec3, 4>> forces;         ///< on each corner, with the stiffness's rate term
    std::vector<std::array<Vec3T<float>, 4>> turned; ///< sqrt(c V mu) R g_a, c = h^2 + h beta
    /// Compressed lists: the entries of i are items[start[i] .. start[i + 1]).
    struct Lists {
        std::vector<std::uint32_t> start, items;
    };
    /// per system block on or right of the diagonal: the element blocks (16 e + 4 a + b, the share of
    /// the slot of (t_b, t_a)) summed into it
    Lists blockSources;
    Lists nodeCorners; ///< per node: the element corners (4 e + a) at it
};

/// The elements' elastic and damping force on one node, at the network's state (for an anchor's body);
/// through the solver's lists of each node's corners where implicit Euler has made them.
Vec3 elementForceOn(const SpringNetwork& net, const FemSolver& solver, std::uint32_t node);

/// Elastic and damping forces of the elements added to f (f must hold the external forces). `since`: the
/// time since the rotations in rotationState were found (the step; 0 if not known).
void addElementForces(const SpringNetwork& net, const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                      std::vector<Vec3>& f, std::vector<Quat>& rotationState, double since);

/// One step of an fem body by its integrator (symplectic or implicit Euler).
SolveStats stepFem(SpringNetwork& net, FemSolver& solver, std::vector<Vec3>& f, ForceIncidence& incidence,
                   const Environment& env, double h);

} // namespace tumble
