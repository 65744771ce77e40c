#pragma once
// The elements of an fem body (systems/fem.h gives the model): each element's rotation and its forces on
// its corners, two elements at a time on SSE2 registers (engine/lanes.h) with the bits of one at a time.
// The common case, an element whose rotation one Newton iteration settles from last step's turned by its
// spin, runs in the lanes; an element that needs more (its first step, an inverted or nearly flat element,
// a fast turn) has its rotation found by rotationOf alone, and then goes on in its lane.

#include "components/spring_network.h"
#include "engine/math.h"
#include "systems/block_sparse.h"

#include <array>
#include <cstddef>
#include <vector>

namespace tumble {

/// An element's rotation before its first step (not a rotation: the first step finds it by an SVD).
inline constexpr Quat kNoRotation{0.0, 0.0, 0.0, 0.0};

/// Where elementForces writes, element e's at [e - first]: its forces on its corners, and (if turned is
/// not null) its rest gradients turned and scaled, sqrt(weight V mu) R g_a (what implicit Euler's blocks
/// are built from: systems/fem.cpp, addElementBlock). If `searched` is not null, it counts the elements
/// whose rotation one Newton iteration did not settle (rotationOf found it).
struct ElementOutput {
    std::array<Vec3, 4>* force = nullptr;
    std::array<Vec3T<float>, 4>* turned = nullptr;
    double weight = 0.0;
    std::size_t* searched = nullptr;
};

/// Elements [first, end) at positions x and velocities v: each one's rotation, found from rotation[e -
/// first] (and written there), and its forces on its corners, elastic at x plus `damping` times the
/// stiffness's rate term at v (beta for the damping force; h + beta for implicit Euler's right-hand side,
/// which holds -(h + beta) K v). `since` is the time since the rotations were found (the step, as x moved
/// by h v since; 0 where not known): each element's spin at v times it is the turn its search starts from.
void elementForces(const FemElements& fem, const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                   std::size_t first, std::size_t end, Quat* rotation, double damping, double since,
                   const ElementOutput& out);

/// The polar rotation of f started from q turned by `turn` (axis times angle, in the world's frame: the
/// turn expected since q was found); q is updated to it. Newton's method on the symmetry of R^T F, or an
/// SVD where Newton is not safe (systems/fem.h).
Mat3 rotationOf(const Mat3& f, Quat& q, bool fromScratch, const Vec3& turn = {});

} // namespace tumble
