#include "systems/spring_integrators.h"

#include "engine/parallel.h"

#include "engine/profiler.h"

#include <optional>

namespace tumble {

namespace {

/// Accelerations of every free mass; zero for pinned ones.
void accelerations(const SpringNetwork& net, SpringWorkspace& w, const Environment& env,
                   const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::vector<Vec3>& a) {
    springForces(net, env, x, v, w.f, w.incidence);
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

/// A Runge-Kutta trial state a time h on from the start along the slope (v, a): xs = x + v h, vs = v0 + a h.
void trialState(const SpringNetwork& net, const std::vector<Vec3>& v, const std::vector<Vec3>& a, double h,
                std::vector<Vec3>& xs, std::vector<Vec3>& vs) {
    const std::size_t n = net.x.size();
    xs.resize(n);
    vs.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        xs[i] = net.x[i] + v[i] * h;
        vs[i] = net.v[i] + a[i] * h;
    }
}

void midpoint(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    const std::size_t n = net.x.size();
    accelerations(net, w, env, net.x, net.v, w.a1);
    trialState(net, net.v, w.a1, 0.5 * h, w.xs, w.v2);
    accelerations(net, w, env, w.xs, w.v2, w.a2);
    for (std::size_t i = 0; i < n; ++i) {
        net.x[i] += w.v2[i] * h;
        net.v[i] += w.a2[i] * h;
    }
}

void rk4(SpringNetwork& net, SpringWorkspace& w, const Environment& env, double h) {
    const std::size_t n = net.x.size();
    // stage k: slope (v_k, a_k) evaluated at (xs, v_k)
    accelerations(net, w, env, net.x, net.v, w.a1);
    trialState(net, net.v, w.a1, 0.5 * h, w.xs, w.v2);
    accelerations(net, w, env, w.xs, w.v2, w.a2);
    trialState(net, w.v2, w.a2, 0.5 * h, w.xs, w.v3);
    accelerations(net, w, env, w.xs, w.v3, w.a3);
    trialState(net, w.v3, w.a3, h, w.xs, w.v4);
    accelerations(net, w, env, w.xs, w.v4, w.a4);
    for (std::size_t i = 0; i < n; ++i) {
        net.x[i] += (net.v[i] + (w.v2[i] + w.v3[i]) * 2.0 + w.v4[i]) * (h / 6.0);
        net.v[i] += (w.a1[i] + (w.a2[i] + w.a3[i]) * 2.0 + w.a4[i]) * (h / 6.0);
    }
}

/// The block pattern of a network's system matrix, where each link's blocks are, and which blocks the
/// pinned masses clear.
template <class S>
void buildPattern(const SpringNetwork& net, ImplicitSolver<S>& w) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    pairs.reserve(net.links.size());
    for (const SpringLink& s : net.links) {
        pairs.emplace_back(std::min(s.a, s.b), std::max(s.a, s.b));
    }
    w.system = BlockMatrix<S>::fromPairs(static_cast<std::uint32_t>(net.x.size()), std::move(pairs));
    w.linkBlocks.resize(net.links.size());
    for (std::size_t k = 0; k < net.links.size(); ++k) {
        const SpringLink& s = net.links[k];
        w.linkBlocks[k] = {w.system.find(s.a, s.b), w.system.find(s.b, s.a)};
    }
    w.terms.resize(net.links.size());
    w.dv.assign(net.x.size(), Vec3T<S>{});
    w.pcg.remembered = 0; // solutions of another system
    w.multigrid = AggregationMultigrid<S>{};
}

/// Blocks of the pinned masses' rows and columns (their diagonal first in each row), rebuilt when pins
/// change.
template <class S>
void findPinnedBlocks(const SpringNetwork& net, ImplicitSolver<S>& w) {
    w.pinnedBlocks = w.system.fixedBlocks(net.pinned);
    w.pinnedWhenBuilt = net.pinned;
}

template <class S>
SolveStats implicitEuler(SpringNetwork& net, SpringWorkspace& work, ImplicitSolver<S>& w,
                         const Environment& env, double h) {
    const std::size_t n = net.x.size();
    if (w.system.n != n || w.linkBlocks.size() != net.links.size()) {
        buildPattern(net, w);
    }
    if (w.pinnedWhenBuilt != net.pinned) {
        findPinnedBlocks(net, w);
    }
    BlockMatrix<S>& a = w.system;
    std::optional<ProfileStage> stage(std::in_place, env.profiler, "springs.assemble");
    // the springs' forces are added below, with their Jacobians, from one length and direction each
    externalForces(net, env, net.x, net.v, work.f, work.incidence);

    // A = M + h c I + sum over springs of (h kd uu^T + h^2 K) in the +/- pattern, + the wind's damping on
    // cloth triangles (lumped); b = h (F + h dF/dx v), where dF/dx v adds K (v_b - v_a) to a and its negative
    // to b. The diagonal is summed in double (a mass can be small beside its springs' terms) and stored in S
    // at the end; off-diagonal blocks are cleared, then summed (two links may join the same pair).
    //
    // In two passes that share out over threads with the same bits: each link's terms, then each mass
    // gathers its links' terms in link order (exactly the additions, in the order, that a pass scattering
    // link after link into both masses makes), and clears and sums its row's off-diagonal blocks.
    WorkerPool& pool = poolOr(env.pool);
    std::vector<Vec3>& rhs = work.xs;     // double accumulation of the right-hand side
    std::vector<Mat3>& diagonal = w.sums; // double accumulation of the diagonal blocks
    diagonal.resize(n);
    rhs.resize(n);
    pool.forEach(net.links.size(), kLinkGrain, [&](std::size_t k) {
        const SpringLink& s = net.links[k];
        LinkTerms& t = w.terms[k];
        double len = 0.0, transverse = 0.0;
        t.active = springAxis(s, net.x[s.a], net.x[s.b], t.u, len, transverse);
        if (!t.active) {
            return;
        }
        const Vec3 dvel = net.v[s.b] - net.v[s.a];
        const double du = dot(dvel, t.u);
        const double stiffAlong = h * h * s.k * (1.0 - transverse);
        t.along = h * s.kd + stiffAlong;
        t.across = h * h * s.k * transverse;
        // h F_a = h (k (len - rest) + kd du) u, and h^2 K dvel = stiffAlong du u + across dvel
        t.rhs = t.u * (h * (s.k * (len - s.rest) + s.kd * du) + stiffAlong * du) + dvel * t.across;
    });
    pool.forEach(n, kMassGrain, [&](std::size_t i) {
        const double m = 1.0 / net.invMass[i];
        Mat3 d = Mat3::identity(m + h * massDamping(net, env, net.x[i]));
        Vec3 r = work.f[i] * h;
        const std::uint32_t* first = work.incidence.links.data() + work.incidence.linkStart[i];
        const std::uint32_t* last = work.incidence.links.data() + work.incidence.linkStart[i + 1];
        for (const std::uint32_t* it = first; it != last; ++it) {
            a.val[w.linkBlocks[*it / 2][*it % 2]] = Mat3T<S>{};
        }
        for (const std::uint32_t* it = first; it != last; ++it) {
            const std::uint32_t k = *it / 2, side = *it % 2;
            const LinkTerms& t = w.terms[k];
            if (!t.active) {
                continue;
            }
            if (side == 0) {
                r += t.rhs;
            } else {
                r -= t.rhs;
            }
            const Mat3 block = t.block();
            d += block;
            a.val[w.linkBlocks[k][side]] -= block.template cast<S>();
        }
        diagonal[i] = d;
        rhs[i] = r;
    });
    addWindDamping(net, env, h, work.incidence, diagonal);
    // constraint filtering: a pinned mass's row and column become the identity, its dv zero
    for (std::uint32_t b : w.pinnedBlocks) {
        a.val[b] = Mat3T<S>{};
    }
    w.rhs.resize(n);
    pool.forEach(n, kMassGrain, [&](std::size_t i) {
        if (net.pinned[i]) {
            a.val[a.diag[i]] = Mat3T<S>::identity();
            w.rhs[i] = Vec3T<S>{};
        } else {
            a.val[a.diag[i]] = diagonal[i].template cast<S>();
            w.rhs[i] = Vec3T<S>::from(rhs[i]);
        }
    });

    stage.emplace(env.profiler, "springs.solve");
    packSymmetric(a, pool);
    w.multigrid.update(a, pool);
    const SolveStats stats =
        solvePcg(a, w.rhs, w.dv, w.multigrid, net.pinned, net.cgTolerance, net.cgMaxIterations, w.pcg, pool);
    pool.forEach(n, kMassGrain, [&](std::size_t i) {
        if (!net.pinned[i]) {
            net.v[i] += w.dv[i].toVec3();
            net.x[i] += net.v[i] * h;
        }
    });
    return stats;
}

void stepSprings(SpringNetwork& net, SpringWorkspace& work, const Environment& env, double h);

} // namespace

void stepNetwork(SpringNetwork& net, SpringWorkspace& work, const Environment& env, double h) {
    if (net.kind == NetworkKind::Fem) {
        work.lastSolve = stepFem(net, work.fem, work.f, work.incidence, env, h);
    } else {
        stepSprings(net, work, env, h);
    }
    // pinned masses stay where they are
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (net.pinned[i]) {
            net.v[i] = Vec3{};
        }
    }
}

namespace {

void stepSprings(SpringNetwork& net, SpringWorkspace& work, const Environment& env, double h) {
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
        work.lastSolve = net.doublePrecisionSolve ? implicitEuler(net, work, work.precise, env, h)
                                                  : implicitEuler(net, work, work.single, env, h);
        break;
    }
}

} // namespace

} // namespace tumble
