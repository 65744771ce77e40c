#pragma once
// Continuous collision detection that can be trusted: for a vertex and a triangle, or two edges, whose
// corners move linearly over a step, the earliest time at which they come within a given distance of each
// other. It never misses a contact; it may report one slightly early (by at most its tolerance), which is
// the safe side for a collision response.
//
// The method is inclusion-based (after Wang, Ferguson, Schneider, Jiang, Attene and Panozzo 2021, "A
// large-scale benchmark and an inclusion-based algorithm for continuous collision detection", the
// Tight-Inclusion method): the gap between the two primitives is written as a function F(t, u, v) of the
// time t in [0, 1] and the two surface parameters (the point on the triangle, or the points on the two
// edges). F is linear in each of t, u and v separately, so over a box of (t, u, v) each coordinate of F
// lies between its values at the box's eight corners. A box whose bounds exclude the cube [-d, d]^3 (d:
// the distance asked for, plus a bound on floating-point error) holds no contact; others are split, the
// earliest in time first, until a box is smaller than the tolerance (a contact at its start time) or none
// is left (no contact). There is no case analysis, so there is no special case to get wrong: coplanar
// motion, parallel edges, grazing contact, contact at t = 0 or t = 1, and any scale all go through the
// same test. This replaces the coplanarity cubic of Bridson et al. 2002, whose roots are lost to rounding
// when the motion is (nearly) coplanar.

#include "engine/math.h"

namespace tumble {

/// The answer of a continuous query.
struct CcdResult {
    bool hit = false; ///< the primitives come within the distance during [0, 1]
    double toi = 1.0; ///< the earliest such time (a lower bound within the tolerance), when hit
    bool capped =
        false; ///< the search hit its box cap and answered conservatively (hit at the earliest open box)
};

/// Vertex start[0] -> end[0] against the triangle start[1..3] -> end[1..3].
CcdResult vertexTriangleCcd(const Vec3 start[4], const Vec3 end[4], double distance);

/// Edge start[0]-start[1] -> end[0]-end[1] against edge start[2]-start[3] -> end[2]-end[3].
CcdResult edgeEdgeCcd(const Vec3 start[4], const Vec3 end[4], double distance);

} // namespace tumble
