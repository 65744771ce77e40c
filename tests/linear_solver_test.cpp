// The implicit solver's linear algebra: the multigrid V-cycle is a symmetric positive preconditioner, and
// PCG solves cloth-like systems to the tolerance asked, in few iterations, with pinned rows held at zero.

#include "systems/linear_solver.h"
#include "systems/spring_builders.h"
#include "systems/spring_integrators.h"

#include "engine/random.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <stdexcept>

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

TEST(AggregationMultigrid, TheCurtainIsSweptByColourAndReadsNoValueLeftInTheOutput) {
    // 35 x 35 = 1225 rows: coloured in eight blocks of 154 rows. The sweep from zero does not clear z: a
    // V-cycle into a vector full of NaN (or of the last answer) must give the same bits as into an empty one
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<float> a = clothMatrix<float>(35, pinned);
    AggregationMultigrid<float> mg;
    mg.update(a);
    ASSERT_GE(mg.colours(0), 2u) << "the curtain's fine level should be coloured";
    const auto x = randomVector<float>(a.n, 3, pinned), y = randomVector<float>(a.n, 4, pinned);
    std::vector<Vec3T<float>> clean;
    mg.apply(x, clean);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int threads : {1, 2, 3, 7}) {
        WorkerPool pool(threads);
        std::vector<Vec3T<float>> dirty(a.n, Vec3T<float>{nan, nan, nan});
        mg.apply(x, dirty, pool);
        ASSERT_EQ(dirty.size(), clean.size());
        EXPECT_EQ(std::memcmp(dirty.data(), clean.data(), clean.size() * sizeof(clean[0])), 0)
            << threads << " threads, from NaN";
        std::vector<Vec3T<float>> reused;
        mg.apply(y, reused, pool);
        mg.apply(x, reused, pool); // over the answer for y
        EXPECT_EQ(std::memcmp(reused.data(), clean.data(), clean.size() * sizeof(clean[0])), 0)
            << threads << " threads, over another answer";
    }
    // and it is still a symmetric positive preconditioner
    std::vector<Vec3T<float>> my;
    mg.apply(y, my);
    EXPECT_NEAR(dotv(clean, y), dotv(x, my), 1e-5 * std::abs(dotv(clean, y)));
    EXPECT_GT(dotv(clean, x), 0.0);
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

// The first guess (PcgVectors): of the last three solutions, the combination nearest the answer in the
// A-norm. A solve given no iterations returns it; the reference is the 3 x 3 Galerkin system built here
// from the plain product and solved by Cramer's rule.
template <class S>
std::vector<Vec3T<S>> product(const BlockMatrix<S>& a, const std::vector<Vec3T<S>>& x) {
    std::vector<Vec3T<S>> y;
    a.multiply(x, y);
    return y;
}

double det3(const std::array<std::array<double, 3>, 3>& m) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/// (x - answer)^T A (x - answer), with A answer = b: x^T A x - 2 x^T b + (a constant left out).
double energyError(const BlockMatrix<double>& a, const std::vector<Vec3T<double>>& x,
                   const std::vector<Vec3T<double>>& b) {
    return dotv(x, product(a, x)) - 2.0 * dotv(x, b);
}

TEST(Pcg, StartsFromTheCombinationOfTheLastSolutionsNearestTheAnswer) {
    static_assert(kGuessHistory == 3, "the reference below combines three solutions");
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<double> a = clothMatrix<double>(12, pinned);
    AggregationMultigrid<double> mg;
    mg.update(a);
    PcgVectors<double> work;
    std::vector<Vec3T<double>> x(a.n);
    std::vector<std::vector<Vec3T<double>>> solutions;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        solvePcg(a, randomVector<double>(a.n, seed, pinned), x, mg, pinned, 1e-12, 200, work);
        solutions.push_back(x);
    }
    // a remembered solution not zero in a row pinned since (a release and a new pin): the guess is zero there
    const std::uint32_t pin = std::uint32_t(std::find(pinned.begin(), pinned.end(), 1) - pinned.begin());
    ASSERT_LT(pin, a.n);
    ASSERT_EQ(work.solutions[0].size(), a.n);
    work.solutions[0][pin] = solutions[1][pin] = {1.0, 2.0, 3.0}; // the second, to be remembered with x
    const std::vector<Vec3T<double>> b = randomVector<double>(a.n, 4, pinned);
    const std::vector<Vec3T<double>> warm = x;
    const SolveStats stats = solvePcg(a, b, x, mg, pinned, 1e-12, 0, work);
    EXPECT_EQ(stats.iterations, 0);

    // the sums leave out the pinned rows (the filtered matrix is the identity there: no mass of its own)
    std::vector<std::vector<Vec3T<double>>> free = solutions;
    for (std::vector<Vec3T<double>>& s : free) {
        s[pin] = {};
    }
    std::array<std::array<double, 3>, 3> g{};
    std::array<double, 3> c{};
    for (std::size_t i = 0; i < 3; ++i) {
        for (std::size_t j = 0; j < 3; ++j) {
            g[i][j] = dotv(free[i], product(a, free[j]));
        }
        c[i] = dotv(free[i], b);
    }
    const double d = det3(g);
    ASSERT_GT(std::abs(d), 1e-12 * g[0][0] * g[1][1] * g[2][2]) << "three independent solutions";
    std::vector<Vec3T<double>> expected(a.n);
    for (std::size_t k = 0; k < 3; ++k) {
        std::array<std::array<double, 3>, 3> gk = g;
        for (std::size_t i = 0; i < 3; ++i) {
            gk[i][k] = c[i];
        }
        const double y = det3(gk) / d;
        for (std::uint32_t i = 0; i < a.n; ++i) {
            expected[i] += pinned[i] ? Vec3T<double>{} : solutions[k][i] * y;
        }
    }
    double scale = 0.0;
    for (std::uint32_t i = 0; i < a.n; ++i) {
        scale = std::max(scale, std::sqrt(double(dot(expected[i], expected[i]))));
    }
    for (std::uint32_t i = 0; i < a.n; ++i) {
        ASSERT_NEAR(x[i].x, expected[i].x, 1e-9 * scale) << "row " << i;
        ASSERT_NEAR(x[i].y, expected[i].y, 1e-9 * scale) << "row " << i;
        ASSERT_NEAR(x[i].z, expected[i].z, 1e-9 * scale) << "row " << i;
    }
    // the residual it reports is that of the guess, and the guess is nearer the answer than the warm start
    const std::vector<Vec3T<double>> ax = product(a, x);
    double r2 = 0.0;
    for (std::uint32_t i = 0; i < a.n; ++i) {
        if (!pinned[i]) {
            const Vec3T<double> r = b[i] - ax[i];
            r2 += dot(r, r);
        }
    }
    EXPECT_NEAR(stats.relativeResidual, std::sqrt(r2 / dotv(b, b)), 1e-9 * stats.relativeResidual);
    EXPECT_LT(energyError(a, x, b), energyError(a, warm, b));
}

TEST(Pcg, AFirstGuessFromRepeatedSolutionsIsTheBestMultipleOfOne) {
    // a cloth at rest repeats its solution to rounding: the Galerkin system is then singular to rounding,
    // and the guess must be the best multiple of one of them (another 1e-8 apart gives weights of 1e8 and
    // takes in the direction of that difference, unrelated to the answer)
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<double> a = clothMatrix<double>(12, pinned);
    AggregationMultigrid<double> mg;
    mg.update(a);
    const std::vector<Vec3T<double>> v = randomVector<double>(a.n, 5, pinned);
    const std::vector<Vec3T<double>> w = randomVector<double>(a.n, 6, pinned);
    PcgVectors<double> work;
    work.solutions[0] = work.solutions[1] = v;
    for (std::uint32_t i = 0; i < a.n; ++i) {
        work.solutions[0][i] += w[i] * 1e-8;
    }
    work.remembered = 2;
    const std::vector<Vec3T<double>> b = randomVector<double>(a.n, 7, pinned);
    std::vector<Vec3T<double>> x = v;
    solvePcg(a, b, x, mg, pinned, 1e-12, 0, work);
    const double alpha = dotv(v, b) / dotv(v, product(a, v));
    for (std::uint32_t i = 0; i < a.n; ++i) {
        ASSERT_TRUE(std::isfinite(x[i].x) && std::isfinite(x[i].y) && std::isfinite(x[i].z)) << "row " << i;
        ASSERT_NEAR(x[i].x, alpha * v[i].x, 1e-6) << "row " << i;
        ASSERT_NEAR(x[i].y, alpha * v[i].y, 1e-6) << "row " << i;
        ASSERT_NEAR(x[i].z, alpha * v[i].z, 1e-6) << "row " << i;
    }
}

TEST(Pcg, AFirstGuessWithWeightsTooLargeForFloatStartsFromZero) {
    // a cloth at rest leaves a solution near float's smallest numbers; the next step's may be of order one
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<float> a = clothMatrix<float>(12, pinned);
    AggregationMultigrid<float> mg;
    mg.update(a);
    std::vector<Vec3T<float>> x = randomVector<float>(a.n, 8, pinned);
    for (Vec3T<float>& v : x) {
        v = v * 1e-43f; // subnormal: the weight is about 1e41
    }
    const std::vector<Vec3T<float>> b = randomVector<float>(a.n, 9, pinned);
    PcgVectors<float> work;
    const SolveStats stats = solvePcg(a, b, x, mg, pinned, 1e-6, 0, work);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        ASSERT_EQ(x[i].x, 0.0f) << "row " << i;
        ASSERT_EQ(x[i].y, 0.0f) << "row " << i;
        ASSERT_EQ(x[i].z, 0.0f) << "row " << i;
    }
    EXPECT_DOUBLE_EQ(stats.relativeResidual, 1.0);
    // and the solve from there converges as from zero
    const SolveStats solved = solvePcg(a, b, x, mg, pinned, 1e-4, 100, work);
    EXPECT_TRUE(solved.converged);
}

TEST(Pcg, AFirstGuessLeavesOutARememberedSolutionThatIsNotFinite) {
    std::vector<std::uint8_t> pinned;
    const BlockMatrix<float> a = clothMatrix<float>(12, pinned);
    AggregationMultigrid<float> mg;
    mg.update(a);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    PcgVectors<float> work;
    work.solutions[0].assign(a.n, Vec3T<float>{nan, nan, nan});
    work.remembered = 1;
    std::vector<Vec3T<float>> x = randomVector<float>(a.n, 10, pinned);
    const std::vector<Vec3T<float>> b = randomVector<float>(a.n, 11, pinned);
    const SolveStats stats = solvePcg(a, b, x, mg, pinned, 1e-4, 100, work);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        ASSERT_TRUE(std::isfinite(x[i].x) && std::isfinite(x[i].y) && std::isfinite(x[i].z)) << "row " << i;
    }
    EXPECT_TRUE(stats.converged);
}

// The pattern from pairs against a set built from them: both orientations, the diagonal, each row sorted
// and unique, the diagonal's index right; an index past the matrix refused.
TEST(BlockMatrix, APatternFromPairsHoldsBothOrientationsAndTheDiagonalOnceEach) {
    Rng rng(7);
    const std::uint32_t n = 300;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    std::set<std::pair<std::uint32_t, std::uint32_t>> expected;
    for (std::uint32_t i = 0; i < n; ++i) {
        expected.emplace(i, i);
    }
    for (int k = 0; k < 4000; ++k) {
        // few distinct columns per row, so that repeats and both orientations both occur
        const auto i = std::uint32_t(rng.uniform(0.0, double(n))) % n;
        const auto j = (i + std::uint32_t(rng.uniform(0.0, 6.0)) % 6 + n - 3) % n;
        pairs.emplace_back(i, j);
        expected.emplace(i, j);
        expected.emplace(j, i);
    }
    const BlockMatrix<float> a = BlockMatrix<float>::fromPairs(n, pairs);
    ASSERT_EQ(a.n, n);
    ASSERT_EQ(a.col.size(), expected.size());
    ASSERT_EQ(a.val.size(), expected.size());
    ASSERT_EQ(a.rowStart.size(), std::size_t(n) + 1);
    ASSERT_EQ(a.rowStart[0], 0u);
    ASSERT_EQ(a.rowStart[n], a.col.size());
    auto it = expected.begin();
    for (std::uint32_t i = 0; i < n; ++i) {
        ASSERT_LE(a.rowStart[i], a.rowStart[std::size_t(i) + 1]);
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[std::size_t(i) + 1]; ++b, ++it) {
            ASSERT_NE(it, expected.end());
            EXPECT_EQ(std::make_pair(i, a.col[b]), *it);
        }
        EXPECT_EQ(a.col[a.diag[i]], i);
        EXPECT_EQ(a.find(i, i), a.diag[i]);
    }
    EXPECT_EQ(it, expected.end());
    // no pairs: the diagonal alone; no rows: nothing
    const BlockMatrix<float> d = BlockMatrix<float>::fromPairs(5, {});
    EXPECT_EQ(d.col, (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
    EXPECT_EQ(d.diag, (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
    EXPECT_EQ(d.rowStart, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5}));
    const BlockMatrix<float> e = BlockMatrix<float>::fromPairs(0, {});
    EXPECT_TRUE(e.col.empty());
    EXPECT_EQ(e.rowStart, (std::vector<std::uint32_t>{0}));
    EXPECT_THROW(BlockMatrix<float>::fromPairs(n, {{0, n}}), std::out_of_range);
    EXPECT_THROW(BlockMatrix<float>::fromPairs(n, {{n + 5, 1}}), std::out_of_range);
}

} // namespace
} // namespace tumble
