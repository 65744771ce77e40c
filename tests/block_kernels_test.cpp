// The solver's row kernels: each against a plain double-precision computation written here, and the SSE2
// and AVX2 versions against each other, bit for bit, on rows of every length (none, one, odd and even
// numbers of blocks, the diagonal first, last or between), and through a whole preconditioned solve.

#include "systems/block_kernels.h"
#include "systems/linear_solver.h"

#include "engine/random.h"
#include "engine/simd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <utility>
#include <vector>

namespace tumble {
namespace {

/// A random symmetric matrix: row i couples to a random set of others (0 to 9 each, a few rows none), every
/// block symmetric, the diagonal blocks dominant.
BlockMatrix<float> randomMatrix(std::uint32_t n, std::uint64_t seed) {
    Rng rng(seed);
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    for (std::uint32_t i = 0; i < n; ++i) {
        const int links = i % 11 == 0 ? 0 : int(rng.uniform(0.0, 5.0));
        for (int k = 0; k < links; ++k) {
            const auto j = std::uint32_t(rng.uniform(0.0, double(n)));
            if (j != i && j < n) {
                pairs.emplace_back(std::min(i, j), std::max(i, j));
            }
        }
    }
    BlockMatrix<float> a = BlockMatrix<float>::fromPairs(n, pairs);
    auto symmetricBlock = [&](double scale) {
        Mat3T<float> m;
        for (int r = 0; r < 3; ++r) {
            for (int c = r; c < 3; ++c) {
                const auto v = float(scale * rng.uniform(-1.0, 1.0));
                m.m[std::size_t(3 * r + c)] = v;
                m.m[std::size_t(3 * c + r)] = v;
            }
        }
        return m;
    };
    for (std::uint32_t i = 0; i < n; ++i) {
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[i + 1]; ++b) {
            const std::uint32_t j = a.col[b];
            if (j < i) {
                a.val[b] = a.val[a.find(j, i)]; // (i, j) = (j, i), already drawn
            } else if (j > i) {
                a.val[b] = symmetricBlock(1.0);
            } else {
                a.val[b] = symmetricBlock(0.5);
                for (int d = 0; d < 3; ++d) {
                    a.val[b].m[std::size_t(4 * d)] += 40.0f;
                }
            }
        }
    }
    return a;
}

std::vector<Vec3T<float>> randomVector(std::uint32_t n, std::uint64_t seed) {
    Rng rng(seed);
    std::vector<Vec3T<float>> v(n);
    for (auto& e : v) {
        e = {float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1))};
    }
    return v;
}

/// A block times a vector in double, entry by entry (row r of the block times v).
Vec3 times(const Mat3T<float>& m, const Vec3T<float>& v) {
    const double x[3] = {v.x, v.y, v.z};
    double r[3] = {0, 0, 0};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r[i] += double(m.m[std::size_t(3 * i + j)]) * x[j];
        }
    }
    return {r[0], r[1], r[2]};
}

void expectClose(const Vec3T<float>& got, const Vec3& want, double scale, const std::string& what) {
    EXPECT_NEAR(got.x, want.x, 1e-5 * scale) << what;
    EXPECT_NEAR(got.y, want.y, 1e-5 * scale) << what;
    EXPECT_NEAR(got.z, want.z, 1e-5 * scale) << what;
    EXPECT_EQ(got.pad, 0.0f) << what << ": the fourth lane must stay clear";
}

/// Runs fn under both instruction sets and compares the vectors it returns bit for bit.
void expectSameBits(const std::function<std::vector<Vec3T<float>>()>& fn, const char* what) {
    if (!avx2Available()) {
        GTEST_SKIP() << "this processor has no AVX2";
    }
    const Simd before = activeSimd();
    forceSimd(Simd::Sse2);
    const std::vector<Vec3T<float>> sse2 = fn();
    forceSimd(Simd::Avx2);
    const std::vector<Vec3T<float>> avx2 = fn();
    forceSimd(before);
    ASSERT_EQ(sse2.size(), avx2.size());
    EXPECT_EQ(std::memcmp(sse2.data(), avx2.data(), sse2.size() * sizeof(sse2[0])), 0) << what;
}

constexpr std::uint32_t kRows = 333;

/// The inverses of a matrix's diagonal blocks (the sweeps' dinv).
std::vector<Mat3T<float>> diagonalInverses(const BlockMatrix<float>& a) {
    std::vector<Mat3T<float>> dinv(a.n);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        dinv[i] = a.val[a.diag[i]].inverse();
    }
    return dinv;
}

/// The reference Gauss-Seidel update of row i, in double: x_i = D_i^-1 (b_i - sum_{j != i} A_ij x_j).
void gaussSeidelRow(const BlockMatrix<float>& a, const std::vector<Mat3T<float>>& dinv,
                    const std::vector<Vec3T<float>>& b, std::vector<Vec3>& x, std::uint32_t i) {
    Vec3 s{b[i].x, b[i].y, b[i].z};
    for (std::uint32_t bl = a.rowStart[i]; bl < a.rowStart[i + 1]; ++bl) {
        if (a.col[bl] != i) {
            const Vec3& xj = x[a.col[bl]];
            s -= times(a.val[bl], {float(xj.x), float(xj.y), float(xj.z)});
        }
    }
    x[i] = times(dinv[i], {float(s.x), float(s.y), float(s.z)});
}

TEST(BlockKernels, ProductMatchesAPlainSumInDouble) {
    const BlockMatrix<float> a = randomMatrix(kRows, 1);
    const auto x = randomVector(kRows, 2);
    std::vector<Vec3T<float>> y(kRows);
    kernels::multiplyRows(a, x.data(), y.data(), 0, kRows);
    for (std::uint32_t i = 0; i < kRows; ++i) {
        Vec3 want;
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[i + 1]; ++b) {
            want += times(a.val[b], x[a.col[b]]);
        }
        expectClose(y[i], want, 40.0, "row " + std::to_string(i));
    }
}

TEST(BlockKernels, SweepsAreGaussSeidelInDouble) {
    const BlockMatrix<float> a = randomMatrix(kRows, 3);
    const auto b = randomVector(kRows, 4);
    const std::vector<Mat3T<float>> dinv = diagonalInverses(a);
    // the reference: x_i = D_i^-1 (b_i - sum_{j != i} A_ij x_j), row after row, in double
    auto reference = [&](std::vector<Vec3> x, bool forward) {
        for (std::uint32_t k = 0; k < kRows; ++k) {
            gaussSeidelRow(a, dinv, b, x, forward ? k : kRows - 1 - k);
        }
        return x;
    };
    std::vector<Vec3T<float>> x(kRows);
    kernels::forwardRowsFromZero(a, dinv.data(), b.data(), x.data(), 0, kRows);
    const std::vector<Vec3> forward = reference(std::vector<Vec3>(kRows), true);
    for (std::uint32_t i = 0; i < kRows; ++i) {
        expectClose(x[i], forward[i], 1.0, "forward row " + std::to_string(i));
    }
    // the residual after the forward sweep, against b - A x summed here
    std::vector<Vec3T<float>> r(kRows);
    kernels::residualAfterForward(a, x.data(), r.data(), 0, kRows);
    for (std::uint32_t i = 0; i < kRows; ++i) {
        Vec3 want{b[i].x, b[i].y, b[i].z};
        for (std::uint32_t bl = a.rowStart[i]; bl < a.rowStart[i + 1]; ++bl) {
            want -= times(a.val[bl], x[a.col[bl]]);
        }
        expectClose(r[i], want, 40.0, "residual row " + std::to_string(i));
    }
    // then backward from where the forward sweep left x
    std::vector<Vec3> start(kRows);
    for (std::uint32_t i = 0; i < kRows; ++i) {
        start[i] = x[i].toVec3();
    }
    kernels::smoothRows(a, dinv.data(), b.data(), x.data(), 0, kRows, false);
    const std::vector<Vec3> backward = reference(start, false);
    for (std::uint32_t i = 0; i < kRows; ++i) {
        expectClose(x[i], backward[i], 1.0, "backward row " + std::to_string(i));
    }
}

/// The sweep order (kernels::SweepOrder) of visiting the rows in the order `visit`, built here from its
/// definition: row i's off-diagonal blocks of rows visited before it, then those visited after it.
kernels::SweepOrder sweepOrder(const BlockMatrix<float>& a, const std::vector<std::uint32_t>& visit) {
    std::vector<std::uint32_t> position(a.n);
    for (std::uint32_t k = 0; k < a.n; ++k) {
        position[visit[k]] = k;
    }
    kernels::SweepOrder order;
    order.split.resize(a.n);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        for (bool before : {true, false}) {
            if (!before) {
                order.split[i] = std::uint32_t(order.items.size());
            }
            for (std::uint32_t bl = a.rowStart[i]; bl < a.rowStart[i + 1]; ++bl) {
                if (a.col[bl] != i && (position[a.col[bl]] < position[i]) == before) {
                    order.items.push_back(bl);
                }
            }
        }
    }
    return order;
}

TEST(BlockKernels, ASweepFromZeroInAnyOrderIsGaussSeidelInThatOrder) {
    // the order a coloured level is swept in: here a random one, row by row
    const BlockMatrix<float> a = randomMatrix(kRows, 11);
    const auto b = randomVector(kRows, 12);
    const std::vector<Mat3T<float>> dinv = diagonalInverses(a);
    std::vector<std::uint32_t> visit(kRows);
    for (std::uint32_t k = 0; k < kRows; ++k) {
        visit[k] = k;
    }
    Rng rng(13);
    for (std::uint32_t k = kRows - 1; k > 0; --k) {
        std::swap(visit[k], visit[std::uint32_t(rng.uniform(0.0, double(k) + 0.999))]);
    }
    const kernels::SweepOrder order = sweepOrder(a, visit);
    // the reference: Gauss-Seidel from zero in the visiting order, every block of the row, in double
    std::vector<Vec3> want(kRows);
    for (std::uint32_t i : visit) {
        gaussSeidelRow(a, dinv, b, want, i);
    }
    auto sweep = [&] {
        std::vector<Vec3T<float>> x(kRows, Vec3T<float>{1e6f, 1e6f, 1e6f}); // not read before written
        for (std::uint32_t i : visit) {
            kernels::forwardRowsFromZero(a, dinv.data(), b.data(), x.data(), i, i + 1, &order);
        }
        std::vector<Vec3T<float>> r(kRows);
        kernels::residualAfterForward(a, x.data(), r.data(), 0, kRows, &order);
        x.insert(x.end(), r.begin(), r.end());
        return x;
    };
    const std::vector<Vec3T<float>> got = sweep();
    for (std::uint32_t i = 0; i < kRows; ++i) {
        expectClose(got[i], want[i], 1.0, "row " + std::to_string(i));
        Vec3 residual{b[i].x, b[i].y, b[i].z};
        for (std::uint32_t bl = a.rowStart[i]; bl < a.rowStart[i + 1]; ++bl) {
            residual -= times(a.val[bl], got[a.col[bl]]);
        }
        expectClose(got[kRows + i], residual, 40.0, "residual row " + std::to_string(i));
    }
    expectSameBits(sweep, "a sweep in another order and its residual");
}

/// Two random matrices side by side on the diagonal: rows [0, first) couple only among themselves, and so
/// do the rows after them.
BlockMatrix<float> twoMatrices(std::uint32_t first, std::uint32_t second, std::uint64_t seed) {
    const BlockMatrix<float> parts[2] = {randomMatrix(first, seed), randomMatrix(second, seed + 1)};
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    for (std::uint32_t p = 0; p < 2; ++p) {
        for (std::uint32_t i = 0; i < parts[p].n; ++i) {
            for (std::uint32_t b = parts[p].rowStart[i]; b < parts[p].rowStart[i + 1]; ++b) {
                if (parts[p].col[b] > i) {
                    pairs.emplace_back(i + p * first, parts[p].col[b] + p * first);
                }
            }
        }
    }
    BlockMatrix<float> a = BlockMatrix<float>::fromPairs(first + second, pairs);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        const std::uint32_t p = i < first ? 0 : 1, offset = p * first;
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[i + 1]; ++b) {
            a.val[b] = parts[p].val[parts[p].find(i - offset, a.col[b] - offset)];
        }
    }
    return a;
}

TEST(BlockKernels, TwoRangesSweptInTurnGiveTheBitsOfOneSweptAfterTheOther) {
    // two ranges that read none of each other's rows (as two blocks of one colour), the second longer
    const std::uint32_t first = 150, n = 350;
    const BlockMatrix<float> a = twoMatrices(first, n - first, 21);
    const auto b = randomVector(n, 22);
    const std::vector<Mat3T<float>> dinv = diagonalInverses(a);
    std::vector<std::uint32_t> visit(n);
    for (std::uint32_t k = 0; k < n; ++k) {
        visit[k] = k;
    }
    const kernels::SweepOrder order = sweepOrder(a, visit);
    // the reference: Gauss-Seidel from zero in double, row after row (the two ranges are independent)
    std::vector<Vec3> want(n);
    for (std::uint32_t i = 0; i < n; ++i) {
        gaussSeidelRow(a, dinv, b, want, i);
    }
    const Vec3T<float> unread{1e6f, 1e6f, 1e6f}; // x is not cleared: no row may be read before it is written
    for (Simd simd : {Simd::Sse2, Simd::Avx2}) {
        if (simd == Simd::Avx2 && !avx2Available()) {
            continue;
        }
        const Simd before = activeSimd();
        forceSimd(simd);
        for (const kernels::SweepOrder* listed : {static_cast<const kernels::SweepOrder*>(nullptr), &order}) {
            const std::string what = std::string(simd == Simd::Avx2 ? "AVX2" : "SSE2") +
                                     (listed ? ", rows as listed" : ", rows in order");
            std::vector<Vec3T<float>> alone(n, unread);
            kernels::forwardRowsFromZero(a, dinv.data(), b.data(), alone.data(), 0, first, listed);
            kernels::forwardRowsFromZero(a, dinv.data(), b.data(), alone.data(), first, n, listed);
            for (std::uint32_t i = 0; i < n; ++i) {
                expectClose(alone[i], want[i], 1.0, what + ", row " + std::to_string(i));
            }
            // either range first, and one range with an empty one
            const kernels::RowRange one{0, first}, other{first, n}, none{n, n};
            for (auto [p, q] : {std::pair{one, other}, std::pair{other, one}}) {
                std::vector<Vec3T<float>> x(n, unread);
                kernels::forwardRowPairFromZero(a, dinv.data(), b.data(), x.data(), p, q, listed);
                EXPECT_EQ(std::memcmp(x.data(), alone.data(), n * sizeof(x[0])), 0) << what;
            }
            std::vector<Vec3T<float>> x(n, unread);
            kernels::forwardRowPairFromZero(a, dinv.data(), b.data(), x.data(), one, none, listed);
            kernels::forwardRowPairFromZero(a, dinv.data(), b.data(), x.data(), none, other, listed);
            EXPECT_EQ(std::memcmp(x.data(), alone.data(), n * sizeof(x[0])), 0) << what << ", one at a time";
        }
        forceSimd(before);
    }
}

/// What the bit-for-bit tests run over every row of a matrix: its product with x0, the forward sweep from
/// zero with its residual, and a forward then a backward sweep from x0.
enum class KernelRun { Product, ForwardAndResidual, Sweeps };
constexpr KernelRun kKernelRuns[] = {KernelRun::Product, KernelRun::ForwardAndResidual, KernelRun::Sweeps};
constexpr const char* kKernelRunNames[] = {"product", "forward sweep and residual", "sweeps"};

std::vector<Vec3T<float>> runKernel(KernelRun run, const BlockMatrix<float>& m,
                                    const std::vector<Mat3T<float>>& dinv,
                                    const std::vector<Vec3T<float>>& x0, const std::vector<Vec3T<float>>& b) {
    const std::uint32_t n = m.n;
    std::vector<Vec3T<float>> x(n), r(n);
    switch (run) {
    case KernelRun::Product:
        kernels::multiplyRows(m, x0.data(), x.data(), 0, n);
        break;
    case KernelRun::ForwardAndResidual:
        kernels::forwardRowsFromZero(m, dinv.data(), b.data(), x.data(), 0, n);
        kernels::residualAfterForward(m, x.data(), r.data(), 0, n);
        x.insert(x.end(), r.begin(), r.end());
        break;
    case KernelRun::Sweeps:
        x = x0;
        kernels::smoothRows(m, dinv.data(), b.data(), x.data(), 0, n, true);
        kernels::smoothRows(m, dinv.data(), b.data(), x.data(), 0, n, false);
        break;
    }
    return x;
}

TEST(BlockKernels, Sse2AndAvx2GiveTheSameBits) {
    const BlockMatrix<float> a = randomMatrix(kRows, 5);
    const auto x0 = randomVector(kRows, 6), b = randomVector(kRows, 7);
    const std::vector<Mat3T<float>> dinv = diagonalInverses(a);
    for (KernelRun run : kKernelRuns) {
        expectSameBits([&] { return runKernel(run, a, dinv, x0, b); }, kKernelRunNames[int(run)]);
    }
}

TEST(BlockKernels, AWholeSolveHasTheSameBitsWithEitherInstructionSet) {
    // a matrix large enough for the multigrid's coloured levels, solved to a tight tolerance
    const std::uint32_t n = 9000;
    const BlockMatrix<float> a = randomMatrix(n, 8);
    const auto b = randomVector(n, 9);
    const std::vector<std::uint8_t> fixed(n, 0);
    expectSameBits(
        [&] {
            AggregationMultigrid<float> mg;
            mg.update(a);
            std::vector<Vec3T<float>> x(n);
            PcgVectors<float> work;
            const SolveStats stats = solvePcg(a, b, x, mg, fixed, 1e-5, 100, work);
            EXPECT_TRUE(stats.converged);
            return x;
        },
        "the solution");
}

/// Under each instruction set this processor has, runs `pair` and compares its two vectors bit for bit.
void expectPairSameBits(
    const std::function<std::pair<std::vector<Vec3T<float>>, std::vector<Vec3T<float>>>()>& pair,
    const char* what) {
    const Simd before = activeSimd();
    std::vector<Simd> sets{Simd::Sse2};
    if (avx2Available()) {
        sets.push_back(Simd::Avx2);
    }
    for (Simd set : sets) {
        forceSimd(set);
        const auto [want, got] = pair();
        ASSERT_EQ(want.size(), got.size());
        EXPECT_EQ(std::memcmp(want.data(), got.data(), want.size() * sizeof(want[0])), 0)
            << what << (set == Simd::Avx2 ? " (AVX2)" : " (SSE2)");
    }
    forceSimd(before);
}

/// Runs fn with the matrix as stored and packed (its blocks' upper triangles, BlockMatrix::packed), under
/// each instruction set this processor has, and compares the two bit for bit.
void expectPackedSameBits(const BlockMatrix<float>& a,
                          const std::function<std::vector<Vec3T<float>>(const BlockMatrix<float>&)>& fn,
                          const char* what) {
    BlockMatrix<float> packed = a;
    ASSERT_TRUE(packSymmetric(packed));
    ASSERT_TRUE(packed.isPacked());
    ASSERT_FALSE(a.isPacked());
    expectPairSameBits([&] { return std::make_pair(fn(a), fn(packed)); }, what);
}

TEST(BlockKernels, PackedUpperTrianglesGiveTheBitsOfTheStoredBlocks) {
    const std::uint32_t n = kPackedRows + 7;
    const BlockMatrix<float> a = randomMatrix(n, 21);
    const auto x0 = randomVector(n, 22), b = randomVector(n, 23);
    const std::vector<Mat3T<float>> dinv = diagonalInverses(a);
    for (KernelRun run : kKernelRuns) {
        expectPackedSameBits(
            a, [&](const BlockMatrix<float>& m) { return runKernel(run, m, dinv, x0, b); },
            kKernelRunNames[int(run)]);
    }
}

// A multigrid over a packed matrix packs its coarse levels of kPackedRows rows or more, after their
// Galerkin sums, on the first update (the levels' build) and every one after: a solve after a second
// update with other values has the bits of the same solve with nothing packed.
TEST(BlockKernels, APackedMultigridSolvesWithTheBitsOfAStoredOneStepAfterStep) {
    const std::uint32_t n = 8 * kPackedRows;
    const BlockMatrix<float> first = randomMatrix(n, 26);
    std::vector<Mat3T<float>> next = first.val; // the next step's values, the same pattern
    for (Mat3T<float>& block : next) {
        for (float& e : block.m) {
            e *= 1.5f;
        }
    }
    const auto b = randomVector(n, 27);
    const std::vector<std::uint8_t> fixed(n, 0);
    auto solve = [&](bool pack) {
        BlockMatrix<float> a = first;
        AggregationMultigrid<float> mg;
        for (int step = 0; step < 2; ++step) {
            if (step == 1) {
                a.val = next;
                a.packed.clear();
            }
            if (pack) {
                EXPECT_TRUE(packSymmetric(a));
            }
            mg.update(a);
            EXPECT_GE(mg.levelSize(1).first, kPackedRows) << "the first coarse level is large enough to pack";
            EXPECT_EQ(mg.levelPacked(1), pack);
        }
        std::vector<Vec3T<float>> x(n);
        PcgVectors<float> work;
        EXPECT_TRUE(solvePcg(a, b, x, mg, fixed, 1e-5, 100, work).converged);
        return x;
    };
    expectPairSameBits([&] { return std::make_pair(solve(false), solve(true)); },
                       "the solve, stored and packed");
}

TEST(BlockKernels, OnlyALargeMatrixOfSymmetricBlocksIsPacked) {
    BlockMatrix<float> small = randomMatrix(kPackedRows - 1, 24);
    EXPECT_FALSE(packSymmetric(small));
    EXPECT_TRUE(small.packed.empty());
    BlockMatrix<float> a = randomMatrix(kPackedRows, 25);
    ASSERT_TRUE(packSymmetric(a));
    // one block's (0, 2) entry off its (2, 0) by one unit in the last place: not packed (an fem body's
    // blocks are not symmetric), and what was packed before is cleared
    const std::uint32_t k = a.rowStart[100] + 1;
    a.val[k].m[2] = std::nextafter(a.val[k].m[6], 1e9f);
    EXPECT_FALSE(packSymmetric(a));
    EXPECT_FALSE(a.isPacked());
    // nor one whose mirror entries are -0 and +0: equal numbers, other bits (a sum of zeros keeps the sign)
    a.val[k].m[2] = 0.0f;
    a.val[k].m[6] = -0.0f;
    EXPECT_FALSE(packSymmetric(a));
    a.val[k].m[6] = 0.0f;
    EXPECT_TRUE(packSymmetric(a));
    // nor a double matrix: its kernels are plain code
    BlockMatrix<double> d = BlockMatrix<double>::fromPairs(kPackedRows, {});
    EXPECT_FALSE(packSymmetric(d));
}

} // namespace
} // namespace tumble
