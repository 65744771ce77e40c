// The implicit solver's linear algebra: the multigrid V-cycle is a symmetric positive preconditioner, and
// PCG solves cloth-like systems to the tolerance asked, in few iterations, with pinned rows held at zero.

#include "systems/linear_solver.h"
#include "systems/spring_builders.h"
#include "systems/spring_integrators.h"

#include "engine/random.h"

#include <gtest/gtest.h>

#include <cstring>

namespace tumble {
namespace {

/// The implicit Euler system of an n x n cloth pinned along its top row, as the integrator assembles it.
template <class S>
BlockMatrix<S> clothMatrix(int n, std::vector<std::uint8_t>& pinned) {
    ClothDef def;
    def.rows = def.cols = n;
    clothPinPreset("top-row", n, n, def.pins);
    SpringNetwork net = buildCloth(def);
    net.integrator = Integrator::ImplicitEuler;
    net.doublePrecisionSolve = std::is_same_v<S, double>;
    SpringWorkspace work;
    const Environment env{{0.0, -9.81, 0.0}, nullptr};
    for (int i = 0; i < 5; ++i) {
        stepNetwork(net, work, env, 1.0 / 60.0); // a sagging, non-trivial state
    }
    pinned = net.pinned;
    if constexpr (std::is_same_v<S, double>) {
        return work.precise.system;
    } else {
        return work.single.system;
    }
}

template <class S>
std::vector<Vec3T<S>> randomVector(std::size_t n, std::uint64_t seed,
                                   const std::vector<std::uint8_t>& pinned) {
    Rng rng(seed);
    std::vector<Vec3T<S>> v(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (!pinned[i]) {
            v[i] = {S(rng.uniform(-1, 1)), S(rng.uniform(-1, 1)), S(rng.uniform(-1, 1))};
        }
    }
    return v;
}

template <class S>
double dotv(const std::vector<Vec3T<S>>& a, const std::vector<Vec3T<S>>& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        s += double(dot(a[i], b[i]));
    }
    return s;
}

TEST(AggregationMultigrid, VCycleIsSymmetricAndPositive) {
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<double> a = clothMatrix<double>(20, pinned);
    AggregationMultigrid<double> mg;
    mg.update(a);
    EXPECT_GE(mg.levels(), 3u);
    const auto x = randomVector<double>(a.n, 1, pinned), y = randomVector<double>(a.n, 2, pinned);
    std::vector<Vec3T<double>> mx, my;
    mg.apply(x, mx);
    mg.apply(y, my);
    // <M x, y> = <x, M y>: CG needs a symmetric preconditioner
    EXPECT_NEAR(dotv(mx, y), dotv(x, my), 1e-10 * std::abs(dotv(mx, y)));
    EXPECT_GT(dotv(mx, x), 0.0);
}

TEST(AggregationMultigrid, TheColouredVCycleIsSymmetricAndPositiveAndSharesOutWithTheSameBits) {
    // 80 x 80 = 6400 rows: the fine level is smoothed colour by colour
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<double> a = clothMatrix<double>(80, pinned);
    AggregationMultigrid<double> mg;
    mg.update(a);
    ASSERT_GE(mg.colours(0), 2u) << "the fine level should be coloured";
    EXPECT_LE(mg.colours(0), 4u) << "blocks of a grid numbered row by row need few colours";
    const auto x = randomVector<double>(a.n, 1, pinned), y = randomVector<double>(a.n, 2, pinned);
    std::vector<Vec3T<double>> mx, my;
    mg.apply(x, mx);
    mg.apply(y, my);
    EXPECT_NEAR(dotv(mx, y), dotv(x, my), 1e-10 * std::abs(dotv(mx, y)));
    EXPECT_GT(dotv(mx, x), 0.0);
    for (int threads : {2, 3, 7}) {
        WorkerPool pool(threads);
        std::vector<Vec3T<double>> shared;
        mg.apply(x, shared, pool);
        ASSERT_EQ(shared.size(), mx.size());
        EXPECT_EQ(std::memcmp(shared.data(), mx.data(), mx.size() * sizeof(mx[0])), 0)
            << threads << " threads";
    }
}

template <class S>
void solvesCloth(int n, double tol, int maxIterations) {
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<S> a = clothMatrix<S>(n, pinned);
    AggregationMultigrid<S> mg;
    mg.update(a);
    const auto b = randomVector<S>(a.n, 7, pinned);
    std::vector<Vec3T<S>> x(a.n);
    PcgVectors<S> work;
    WorkerPool pool(2);
    const SolveStats stats = solvePcg(a, b, x, mg, pinned, tol, 500, work, pool);
    EXPECT_TRUE(stats.converged);
    EXPECT_LE(stats.iterations, maxIterations) << "multigrid keeps the count low";
    // check the residual independently
    std::vector<Vec3T<S>> ax;
    a.multiply(x, ax);
    double r2 = 0.0, b2 = 0.0;
    for (std::uint32_t i = 0; i < a.n; ++i) {
        const Vec3T<S> r = b[i] - ax[i];
        r2 += double(dot(r, r));
        b2 += double(dot(b[i], b[i]));
        if (pinned[i]) {
            EXPECT_EQ(x[i].x, S(0));
        }
    }
    EXPECT_LE(std::sqrt(r2 / b2), tol * 1.01);
}

TEST(Pcg, SolvesACurtainSystemInDouble) {
    solvesCloth<double>(35, 1e-10, 60); // from zero, to 1e-10, on a random right-hand side
}

TEST(Pcg, SolvesACurtainSystemInFloat) {
    solvesCloth<float>(35, 1e-4, 25);
}

TEST(Pcg, IterationsStayLowOnALargeCloth) {
    solvesCloth<float>(100, 1e-3, 25);
}

} // namespace
} // namespace tumble
