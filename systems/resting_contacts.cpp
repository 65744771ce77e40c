#include "systems/resting_contacts.h"

namespace tumble {

namespace {

/// c n n^T.
Mat3 restingBlock(const Vec3& n, double c) {
    Mat3 b;
    const double u[3] = {n.x, n.y, n.z};
    for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
            b.m[std::size_t(3 * r + k)] = c * u[r] * u[k];
        }
    }
    return b;
}

Mat3 widened(const Mat3T<float>& block) {
    Mat3 sum;
    for (std::size_t e = 0; e < 9; ++e) {
        sum.m[e] = double(block.m[e]);
    }
    return sum;
}

/// The contacts of one node are next to each other in net.resting (the collision pass goes mass by mass):
/// calls fn(first, end) for each node's run of them.
template <class F>
void eachNode(const SpringNetwork& net, F&& fn) {
    for (std::size_t first = 0; first < net.resting.size();) {
        std::size_t end = first + 1;
        while (end < net.resting.size() && net.resting[end].mass == net.resting[first].mass) {
            ++end;
        }
        fn(first, end);
        first = end;
    }
}

/// A node's block: as saved, plus c n n^T of each of its contacts [first, end) still held.
void rebuildBlock(const SpringNetwork& net, BlockMatrix<float>& a, std::size_t first, std::size_t end,
                  const std::vector<double>& weights, const Mat3T<float>& saved) {
    Mat3 sum = widened(saved);
    for (std::size_t k = first; k < end; ++k) {
        if (weights[k] > 0.0) {
            sum += restingBlock(net.resting[k].normal, weights[k]);
        }
    }
    a.val[a.diag[net.resting[first].mass]] = sum.cast<float>();
}

} // namespace

void holdResting(const SpringNetwork& net, BlockMatrix<float>& a, std::vector<double>& weights,
                 std::vector<Mat3T<float>>& saved) {
    weights.assign(net.resting.size(), 0.0);
    saved.assign(net.resting.size(), Mat3T<float>{});
    eachNode(net, [&](std::size_t first, std::size_t end) {
        const std::uint32_t i = net.resting[first].mass;
        if (i >= a.n || net.pinned[i]) {
            return;
        }
        saved[first] = a.val[a.diag[i]]; // each weight from the block before any contact
        const double weight =
            kRestingStiffness * (double(saved[first].m[0]) + saved[first].m[4] + saved[first].m[8]) / 3.0;
        for (std::size_t k = first; k < end; ++k) {
            weights[k] = weight;
        }
        rebuildBlock(net, a, first, end, weights, saved[first]);
    });
}

bool releasePulling(const SpringNetwork& net, BlockMatrix<float>& a, const std::vector<Vec3T<float>>& dv,
                    std::vector<double>& weights, const std::vector<Mat3T<float>>& saved) {
    bool released = false;
    eachNode(net, [&](std::size_t first, std::size_t end) {
        bool let = false;
        for (std::size_t k = first; k < end; ++k) {
            const RestingContact& c = net.resting[k];
            if (weights[k] > 0.0 && dot(c.normal, dv[c.mass].toVec3()) > 0.0) {
                weights[k] = 0.0;
                let = true;
            }
        }
        if (let) {
            rebuildBlock(net, a, first, end, weights, saved[first]);
            released = true;
        }
    });
    return released;
}

} // namespace tumble
