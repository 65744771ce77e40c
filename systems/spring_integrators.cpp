#include "systems/spring_integrators.h"

namespace tumble {

namespace {

/// Accelerations of every free mass; zero for pinned ones.
void accelerations(const SpringNetwork& net, SpringWorkspace& w, const Environment& env,
                   const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::vector<Vec3>& a) {
    springForces(net, env, x, v, w.f);
    a.resize(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
        a[i] = net.pinned[i] ? Vec3{} : w.f[i] * net.invMass[i];
    }
}

void explicitEuler(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    accelerations(net, w, env, net.x, net.v, w.a1);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        net.x[i] += net.v[i] * h;
        net.v[i] += w.a1[i] * h;
    }
}

void symplecticEuler(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    accelerations(net, w, env, net.x, net.v, w.a1);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        net.v[i] += w.a1[i] * h;
        net.x[i] += net.v[i] * h;
    }
}

void midpoint(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    const std::size_t n = net.x.size();
    w.xs.resize(n);
    w.v2.resize(n);
    accelerations(net, w, env, net.x, net.v, w.a1);
    for (std::size_t i = 0; i < n; ++i) {
        w.xs[i] = net.x[i] + net.v[i] * (0.5 * h);
        w.v2[i] = net.v[i] + w.a1[i] * (0.5 * h);
    }
    accelerations(net, w, env, w.xs, w.v2, w.a2);
    for (std::size_t i = 0; i < n; ++i) {
        net.x[i] += w.v2[i] * h;
        net.v[i] += w.a2[i] * h;
    }
}

void rk4(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    const std::size_t n = net.x.size();
    w.xs.resize(n);
    w.v2.resize(n);
    w.v3.resize(n);
    w.v4.resize(n);
    // stage k: slope (v_k, a_k) evaluated at (xs, v_k)
    accelerations(net, w, env, net.x, net.v, w.a1);
    for (std::size_t i = 0; i < n; ++i) {
        w.xs[i] = net.x[i] + net.v[i] * (0.5 * h);
        w.v2[i] = net.v[i] + w.a1[i] * (0.5 * h);
    }
    accelerations(net, w, env, w.xs, w.v2, w.a2);
    for (std::size_t i = 0; i < n; ++i) {
        w.xs[i] = net.x[i] + w.v2[i] * (0.5 * h);
        w.v3[i] = net.v[i] + w.a2[i] * (0.5 * h);
    }
    accelerations(net, w, env, w.xs, w.v3, w.a3);
    for (std::size_t i = 0; i < n; ++i) {
        w.xs[i] = net.x[i] + w.v3[i] * h;
        w.v4[i] = net.v[i] + w.a3[i] * h;
    }
    accelerations(net, w, env, w.xs, w.v4, w.a4);
    for (std::size_t i = 0; i < n; ++i) {
        net.x[i] += (net.v[i] + (w.v2[i] + w.v3[i]) * 2.0 + w.v4[i]) * (h / 6.0);
        net.v[i] += (w.a1[i] + (w.a2[i] + w.a3[i]) * 2.0 + w.a4[i]) * (h / 6.0);
    }
}

/// The block pattern of a network's system matrix, and where each link's blocks are.
void buildPattern(const SpringNetwork& net, SpringWorkspace& w) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    pairs.reserve(net.links.size());
    for (const SpringLink& s : net.links) {
        pairs.emplace_back(std::min(s.a, s.b), std::max(s.a, s.b));
    }
    w.system = BlockMatrix::fromPairs(static_cast<std::uint32_t>(net.x.size()), std::move(pairs));
    w.linkBlocks.resize(net.links.size());
    for (std::size_t k = 0; k < net.links.size(); ++k) {
        const SpringLink& s = net.links[k];
        w.linkBlocks[k] = {w.system.find(s.a, s.b), w.system.find(s.b, s.a)};
    }
    w.dv.assign(net.x.size(), Vec3{});
}

void implicitEuler(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    const std::size_t n = net.x.size();
    if (w.system.n != n || w.linkBlocks.size() != net.links.size()) {
        buildPattern(net, w);
    }
    BlockMatrix& a = w.system;
    a.setZero();
    springForces(net, env, net.x, net.v, w.f);

    // A = M + h c I + sum over springs of (h kd uu^T + h^2 K) in the +/- pattern;
    // b = h (F + h dF/dx v), where dF/dx v adds K (v_b - v_a) to a and its negative to b
    w.rhs.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double m = 1.0 / net.invMass[i];
        a.val[a.diag[i]] = Mat3::identity(m + h * massDamping(net, env, net.x[i]));
        w.rhs[i] = w.f[i] * h;
    }
    for (std::size_t k = 0; k < net.links.size(); ++k) {
        const SpringLink& s = net.links[k];
        Mat3 stiff;
        Vec3 u;
        if (!springStiffness(s, net.x[s.a], net.x[s.b], stiff, u)) {
            continue;
        }
        const Vec3 kdv = stiff * (net.v[s.b] - net.v[s.a]);
        w.rhs[s.a] += kdv * (h * h);
        w.rhs[s.b] -= kdv * (h * h);
        Mat3 block = Mat3::outer(u, h * s.kd);
        for (std::size_t e = 0; e < 9; ++e) {
            block.m[e] += h * h * stiff.m[e];
        }
        a.val[a.diag[s.a]] += block;
        a.val[a.diag[s.b]] += block;
        a.val[w.linkBlocks[k][0]] -= block;
        a.val[w.linkBlocks[k][1]] -= block;
    }
    // constraint filtering: a pinned mass's row and column become the identity, its dv zero
    for (std::uint32_t i = 0; i < n; ++i) {
        if (!net.pinned[i]) {
            continue;
        }
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[std::size_t(i) + 1]; ++b) {
            const std::uint32_t j = a.col[b];
            a.val[b] = j == i ? Mat3::identity() : Mat3{};
            if (j != i) {
                a.val[a.find(j, i)] = Mat3{};
            }
        }
        w.rhs[i] = Vec3{};
    }

    w.multigrid.update(a);
    w.lastSolve =
        solvePcg(a, w.rhs, w.dv, w.multigrid, net.pinned, net.cgTolerance, net.cgMaxIterations, w.pcg);
    for (std::size_t i = 0; i < n; ++i) {
        if (net.pinned[i]) {
            continue;
        }
        net.v[i] += w.dv[i];
        net.x[i] += net.v[i] * h;
    }
}

} // namespace

void stepNetwork(SpringNetwork& net, SpringWorkspace& work, const Environment& env, double h) {
    switch (net.integrator) {
    case Integrator::ExplicitEuler:
        explicitEuler(net, work, env, h);
        break;
    case Integrator::Midpoint:
        midpoint(net, work, env, h);
        break;
    case Integrator::Rk4:
        rk4(net, work, env, h);
        break;
    case Integrator::SymplecticEuler:
        symplecticEuler(net, work, env, h);
        break;
    case Integrator::ImplicitEuler:
        implicitEuler(net, work, env, h);
        break;
    }
    // pinned masses stay where they are
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (net.pinned[i]) {
            net.v[i] = Vec3{};
        }
    }
}

} // namespace tumble
