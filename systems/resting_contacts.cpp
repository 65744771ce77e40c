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

/// Node i's block: as saved, plus c n n^T of each of its contacts still held.
void rebuildBlock(const SpringNetwork& net, BlockMatrix<float>& a, std::uint32_t i,
                  const std::vector<double>& weights, const Mat3T<float>& saved) {
    Mat3 sum = widened(saved);
    for (std::size_t k = 0; k < net.resting.size(); ++k) {
        if (net.resting[k].mass == i && weights[k] > 0.0) {
            sum += restingBlock(net.resting[k].normal, weights[k]);
        }
    }
    a.val[a.diag[i]] = sum.cast<float>();
}

} // namespace

void holdResting(const SpringNetwork& net, BlockMatrix<float>& a, std::vector<double>& weights,
                 std::vector<Mat3T<float>>& saved) {
    const std::size_t n = a.n;
    weights.assign(net.resting.size(), 0.0);
    saved.assign(net.resting.size(), Mat3T<float>{});
    for (std::size_t k = 0; k < net.resting.size(); ++k) {
        const std::uint32_t i = net.resting[k].mass;
        if (i < n && !net.pinned[i]) {
            saved[k] = a.val[a.diag[i]];
            for (std::size_t e = 0; e < k; ++e) { // a node's first contact saved its block untouched
                if (net.resting[e].mass == i) {
                    saved[k] = saved[e];
                    break;
                }
            }
            weights[k] = kRestingStiffness * (double(saved[k].m[0]) + saved[k].m[4] + saved[k].m[8]) / 3.0;
        }
    }
    for (std::size_t k = 0; k < net.resting.size(); ++k) {
        if (weights[k] > 0.0) {
            rebuildBlock(net, a, net.resting[k].mass, weights, saved[k]);
        }
    }
}

bool releasePulling(const SpringNetwork& net, BlockMatrix<float>& a, const std::vector<Vec3T<float>>& dv,
                    std::vector<double>& weights, const std::vector<Mat3T<float>>& saved) {
    bool released = false;
    for (std::size_t k = 0; k < net.resting.size(); ++k) {
        const RestingContact& c = net.resting[k];
        if (weights[k] > 0.0 && dot(c.normal, dv[c.mass].toVec3()) > 0.0) {
            weights[k] = 0.0;
            released = true;
        }
    }
    if (released) {
        for (std::size_t k = 0; k < net.resting.size(); ++k) {
            if (net.resting[k].mass < a.n && !net.pinned[net.resting[k].mass]) {
                rebuildBlock(net, a, net.resting[k].mass, weights, saved[k]);
            }
        }
    }
    return released;
}

} // namespace tumble
