#pragma once
// Resting contacts (components/spring_network.h) in an fem body's implicit Euler. The collision pass acts
// after the solve, so without them the solve moves a resting node with the body it belongs to as though
// nothing held it, and the pass puts it back: the layers above then settle by as much as the step lets them
// fall, which grows with h^2 K / m (an fem block's bottom layer was crushed flat at 1/60 s; its resting shape
// depended on the step). Each resting node's diagonal block gains c n n^T, c = kRestingStiffness times the
// block's mean diagonal: its speed into the surface changes by about a thousandth of what the forces would
// give it (the pass takes that out), and its speed away from it is held for that one step (the next step it
// is free, as the pass no longer finds it inside). The surface's impulse, -c (n . dv), is what friction then
// works with: the sliding speed loses at most friction times it over the mass, as in the pass. Only static
// bodies (a moving one would need the impulse handed to it) and only fem bodies (spring networks, cloth above
// all, have not been moved to it: their contact tests ran slower and some failed with it; a next step).

#include "components/spring_network.h"
#include "systems/block_sparse.h"

#include <algorithm>
#include <cstddef>
#include <vector>

namespace tumble {

constexpr double kRestingStiffness = 1e3;

/// c for a mass's diagonal block (its mean diagonal entry times kRestingStiffness).
inline double restingWeight(const Mat3& block) {
    return kRestingStiffness * (block.m[0] + block.m[4] + block.m[8]) / 3.0;
}

/// c n n^T.
inline Mat3 restingBlock(const Vec3& n, double c) {
    Mat3 b;
    const double u[3] = {n.x, n.y, n.z};
    for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
            b.m[std::size_t(3 * r + k)] = c * u[r] * u[k];
        }
    }
    return b;
}

/// After the solve, friction on each resting mass's step (dv, solved with weights[k] for contact k): its
/// sliding speed after the step slowed by at most friction times the surface's impulse over the mass.
template <class V>
void restingFriction(const SpringNetwork& net, const std::vector<double>& weights, std::vector<V>& dv) {
    for (std::size_t k = 0; k < net.resting.size(); ++k) {
        const RestingContact& c = net.resting[k];
        const std::uint32_t i = c.mass;
        if (net.pinned[i]) {
            continue;
        }
        const Vec3 step = dv[i].toVec3();
        const double impulse = -weights[k] * dot(c.normal, step);
        if (!(impulse > 0.0)) {
            continue; // the surface did not push
        }
        const Vec3 after = net.v[i] + step;
        const Vec3 sliding = after - c.normal * dot(after, c.normal);
        const double speed = length(sliding);
        const double slowdown = c.friction * impulse * net.invMass[i];
        if (speed > 0.0) {
            dv[i] = V::from(step - sliding * (std::min(speed, slowdown) / speed));
        }
    }
}

} // namespace tumble
