#pragma once
// Resting contacts (components/spring_network.h) in an fem body's implicit Euler. The collision pass acts
// after the solve, so without them the solve moves a resting node with the body it belongs to as though
// nothing held it, and the pass puts it back: the layers above then settle by as much as the step lets them
// fall, which grows with h^2 K / m (an fem block's bottom layer was crushed flat at 1/60 s; its resting shape
// depended on the step). Each resting node's diagonal block gains c n n^T, c = kRestingStiffness times the
// block's mean diagonal: its speed into the surface changes by about a thousandth of what the forces would
// give it (the pass takes that out). A contact that held its node from leaving the surface (the solve's n .
// dv > 0: the surface pulled) lets go and the system is solved again without it, so that a body rolls and
// lifts off freely. The surface's impulse, -c (n . dv), is what friction then works with: the sliding speed
// loses at most friction times it over the mass, as in the pass. Only static bodies (a moving one would need
// the impulse handed to it) and only fem bodies (spring networks, cloth above all, have not been moved to it:
// their contact tests ran slower and some failed with it; a next step).

#include "components/spring_network.h"
#include "systems/block_sparse.h"

#include <algorithm>
#include <cstddef>
#include <vector>

namespace tumble {

constexpr double kRestingStiffness = 1e3;

/// Adds each resting contact's c n n^T to its node's diagonal block of `a` (c into weights[k]), keeping
/// each block it changes as it was in `saved` (at the node's first contact: a node's contacts are next to
/// each other, as the collision pass records them mass by mass).
void holdResting(const SpringNetwork& net, BlockMatrix<float>& a, std::vector<double>& weights,
                 std::vector<Mat3T<float>>& saved);

/// After a solve (dv): a contact whose surface pulled its node (the node was leaving it: -c (n . dv) < 0)
/// lets go, its weight zero and its node's block as it was with the node's other contacts only. True if
/// any let go: the caller solves again, so that a body can roll or lift off (held for that step, a rolling
/// ball's rear nodes braked it to a stop on a step's edge).
bool releasePulling(const SpringNetwork& net, BlockMatrix<float>& a, const std::vector<Vec3T<float>>& dv,
                    std::vector<double>& weights, const std::vector<Mat3T<float>>& saved);

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
