#include "systems/air_solver.h"

#include "engine/simd.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <tuple>
#include <type_traits>

#include <immintrin.h>

// This file is compiled twice: as it is, its loops for SSE2 (namespace air_sse2), and by
// systems/air_solver_avx2.cpp for AVX2 (air_avx2: eight floats a vector where g++ vectorises a loop).
// Both do the same operations on every value in the same order (no fused multiply-add: the build has
// -ffp-contract=off, and AVX2 alone does not enable FMA; sums keep their order), so they give the same
// bits; the public functions at the end choose by activeSimd() (TUMBLE_SIMD forces either), and
// tests/air_test.cpp compares the two in one process. The target is set after the includes, so that the
// headers' inline functions, shared with the rest of the program, stay SSE2.
#ifdef TUMBLE_AIR_AVX2
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC target("avx2")
#endif
#define TUMBLE_AIR_VARIANT air_avx2
#else
#define TUMBLE_AIR_VARIANT air_sse2
#endif

namespace tumble {
namespace TUMBLE_AIR_VARIANT {

namespace {

constexpr std::size_t kSlabs = 2; ///< z-slabs a chunk of work (fixed: the same bits at any thread count)
constexpr float kJacobiWeight =
    6.0f / 7.0f;                    ///< weighted Jacobi's best smoothing weight for the 3D 7-point stencil
constexpr int kSmoothing = 2;       ///< Jacobi sweeps before and after the coarse correction, finest level
constexpr int kCoarseSmoothing = 3; ///< the same on the coarser levels (but the coarsest)
constexpr int kCoarsestSweeps = 30; ///< on the coarsest level (a few cells a side), at kJacobiWeight
/// Each coarser level's stencil weighs this much more than the one above: 2 is the stencil rediscretised on
/// cells twice as wide, in the fine one's units (the restriction sums eight cells); the coarse correction a
/// tenth stronger took fewer CG iterations in each of five scenes (a 64^3 plume 3.6 -> 3.0 a step, a 32^3
/// one 2.5 -> 2.0, a fan's jet round a block 2.65 -> 2.6, a closed box's 1.8 the same; a random field from
/// scratch 18 -> 18 over three boxes), 2.1 and 2.3 fewer than 2 but more than 2.2, 2.6 and 3 more than 2.
constexpr float kCoarseWeightGrowth = 2.2f;
constexpr std::uint32_t kMostIterations = 200;
constexpr int kMostStarts = 4; ///< CG started again from the true residual at most this many times

/// A grid of n cells padded by one cell of zeros on every side.
struct Padded {
    int nx, ny, nz;
    std::ptrdiff_t sx, sy;

    explicit Padded(const std::array<int, 3>& n)
        : nx(n[0]), ny(n[1]), nz(n[2]), sx(nx + 2), sy(std::ptrdiff_t(nx + 2) * (ny + 2)) {}
    std::size_t size() const { return std::size_t(sy) * std::size_t(nz + 2); }
    std::size_t at(int i, int j, int k) const { return std::size_t((i + 1) + sx * (j + 1) + sy * (k + 1)); }
};

/// Rows of cells a grid needs before its loops are shared out: a coarse level's loop takes a few
/// microseconds, less than waking the workers and waiting for them (the same chunks run in the same order
/// on one thread, so the bits are the same).
constexpr std::size_t kSharedRows = 256;

WorkerPool& poolForRows(WorkerPool& pool, int ny, int nz) {
    return std::size_t(ny) * std::size_t(nz) < kSharedRows ? serialPool() : pool;
}

/// Calls fn(j, k) for every row of cells (j, k), z-slabs shared out over the pool.
template <class F>
void forRows(WorkerPool& pool, int ny, int nz, F&& fn) {
    poolForRows(pool, ny, nz)
        .forChunks(std::size_t(nz), kSlabs, [&](std::size_t, std::size_t k0, std::size_t k1) {
            for (std::size_t k = k0; k < k1; ++k) {
                for (int j = 0; j < ny; ++j) {
                    fn(j, int(k));
                }
            }
        });
}

/// The sum over the rows of rowSum(j, k), per slab chunk and then in chunk order.
template <class T, class F>
T sumRows(WorkerPool& pool, int ny, int nz, T zero, F&& rowSum) {
    return poolForRows(pool, ny, nz).sum(std::size_t(nz), kSlabs, zero, [&](std::size_t k0, std::size_t k1) {
        T s = zero;
        for (std::size_t k = k0; k < k1; ++k) {
            for (int j = 0; j < ny; ++j) {
                s += rowSum(j, int(k));
            }
        }
        return s;
    });
}

/// A sum and a count that pool.sum can combine (for a mean).
struct Total {
    double sum = 0.0, count = 0.0;
    Total& operator+=(const Total& o) {
        sum += o.sum;
        count += o.count;
        return *this;
    }
};

/// A maximum that pool.sum can combine (+= keeps the larger).
struct Largest {
    double value = 0.0;
    Largest& operator+=(const Largest& o) {
        value = std::max(value, o.value);
        return *this;
    }
};

/// Four floats, or ints, on an SSE2 register, and eight on an AVX2 one: the loops below that work on several
/// cells at a time take four in the SSE2 build, eight in the AVX2 one.
using Float4 = float __attribute__((vector_size(16)));
using Int4 = std::int32_t __attribute__((vector_size(16)));
using Float8 = float __attribute__((vector_size(32)));
using Int8 = std::int32_t __attribute__((vector_size(32)));
#ifdef TUMBLE_AIR_AVX2
using Lanes = Float8;
using IntLanes = Int8;
#else
using Lanes = Float4;
using IntLanes = Int4;
#endif
constexpr int kLanes = int(sizeof(Lanes) / sizeof(float));

/// One value of a field, or a vector of them along x (for the advection several points at a time).
template <class T>
T loadAs(const float* p) {
    if constexpr (std::is_same_v<T, float>) {
        return *p;
    } else {
        T v;
        std::memcpy(&v, p, sizeof v);
        return v;
    }
}

/// Stores a vector's values at p.
inline void storeLanes(float* p, Lanes v) {
    std::memcpy(p, &v, sizeof v);
}

/// Each of p's first kLanes / 2 values twice: p[0], p[0], p[1], p[1], ...
inline Lanes doubledLanes(const float* p) {
#ifdef TUMBLE_AIR_AVX2
    const Float4 half = loadAs<Float4>(p);
    return __builtin_shufflevector(half, half, 0, 0, 1, 1, 2, 2, 3, 3);
#else
    Float4 half{};
    std::memcpy(&half, p, 2 * sizeof(float));
    return __builtin_shufflevector(half, half, 0, 0, 1, 1);
#endif
}

// ---- the projection's multigrid ----

/// The six neighbours of the cell at c in a padded grid, in a fixed order (the padding reads zero).
inline float neighbourSum(const float* c, const Padded& g) {
    return ((c[-1] + c[1]) + (c[-g.sx] + c[g.sx])) + (c[-g.sy] + c[g.sy]);
}

/// Calls fn(p, around) for every cell of a level, p its index in the padded vectors and around the sum
/// of x at its six neighbours (the padding reading zero).
template <class F>
void forStencil(const AirLevel& level, const float* x, WorkerPool& pool, F&& fn) {
    const Padded g(level.n);
    forRows(pool, g.ny, g.nz, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        for (int i = 0; i < g.nx; ++i) {
            const std::size_t p = row + std::size_t(i);
            fn(p, neighbourSum(x + p, g));
        }
    });
}

/// y = A x on a level: A x = weight (count x_c - sum of the six neighbours), the padding reading zero.
void applyLevel(const AirLevel& level, const float* x, float* y, WorkerPool& pool) {
    const float weight = level.weight;
    const float *d = level.diagonal.data(), *in = level.inAir.data(); // a solid cell stays out: 0
    forStencil(level, x, pool,
               [&](std::size_t p, float around) { y[p] = in[p] * (d[p] * x[p] - weight * around); });
}

/// out = b - A x on a level, in one pass (the same arithmetic as applyLevel, then the difference).
void residualLevel(const AirLevel& level, const float* x, const float* b, float* out, WorkerPool& pool) {
    const float weight = level.weight;
    const float *d = level.diagonal.data(), *in = level.inAir.data();
    forStencil(level, x, pool,
               [&](std::size_t p, float around) { out[p] = b[p] - in[p] * (d[p] * x[p] - weight * around); });
}

/// The smoother's weights: its Jacobi sweeps weighted by the roots of a Chebyshev polynomial (the sweeps'
/// error factor, the product of (1 - w_k lambda) over the eigenvalues lambda of D^-1 A, is 1 / T_m((b + a) /
/// (b - a)) at most on [a, b]; Saad, "Iterative methods for sparse linear systems", 12.3): w_k = 1 /
/// lambda_k at the roots lambda_k = (b + a) / 2 + (b - a) / 2 cos(pi (2k - 1) / 2m), m sweeps. D^-1 A's
/// eigenvalues lie in [0, 2] (Gershgorin: a row's neighbours weigh no more than its diagonal), and those of
/// the modes a grid of cells twice as wide cannot hold (a wave number past half the largest along some
/// axis) in [1/3, 2]: so a = 1/3, b = 2. Two sweeps leave at most 0.34 of such a mode, three 0.15, against
/// 0.51 and 0.36 at kJacobiWeight (whose factor is 5/7 a sweep); between 0 and a the factor stays in (0, 1),
/// so the V-cycle stays positive definite. The finest level sweeps twice, the coarser ones (an eighth of
/// the cells each) three times. The roots need only square roots (cos(pi/4) = sqrt(1/2), cos(pi/6) =
/// sqrt(3)/2), which are exact to the last bit everywhere; cos from the C library need not be.
struct SmoothingWeights {
    std::array<float, kSmoothing> fine;
    std::array<float, kCoarseSmoothing> coarse;
    std::array<float, kCoarsestSweeps> coarsest; ///< plain weighted Jacobi, kJacobiWeight each
};

const SmoothingWeights& smoothingWeights() {
    static_assert(kSmoothing == 2 && kCoarseSmoothing == 3, "the roots below are those of T_2 and T_3");
    static const SmoothingWeights weights = [] {
        const double a = 1.0 / 3.0, b = 2.0, centre = (b + a) / 2.0, half = (b - a) / 2.0;
        const double two = half * std::sqrt(0.5), three = half * std::sqrt(3.0) / 2.0;
        SmoothingWeights w{};
        w.fine = {float(1.0 / (centre + two)), float(1.0 / (centre - two))};
        w.coarse = {float(1.0 / (centre + three)), float(1.0 / centre), float(1.0 / (centre - three))};
        w.coarsest.fill(kJacobiWeight);
        return w;
    }();
    return weights;
}

/// One weighted Jacobi sweep: out = x + omega D^-1 (b - A x).
void jacobi(const AirLevel& level, const float* x, const float* b, float* out, float omega,
            WorkerPool& pool) {
    // everything taken by value: with omega by reference g++ did not vectorise the loop (it ran a cell at a
    // time, a third slower a step)
    const float weight = level.weight, w = omega;
    const float *d = level.diagonal.data(), *inverse = level.inverse.data();
    forStencil(level, x, pool, [=](std::size_t p, float around) {
        out[p] = x[p] + (w * inverse[p]) * (b[p] - (d[p] * x[p] - weight * around));
    });
}

/// Jacobi sweeps from zero on a level, for right-hand side b, one for each of the `sweeps` weights in turn;
/// the result in level.x.
void smoothFromZero(AirLevel& level, const float* b, const float* omegas, std::size_t sweeps,
                    WorkerPool& pool) {
    const Padded g(level.n);
    const float first = omegas[0];
    forRows(pool, g.ny, g.nz, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        for (int i = 0; i < g.nx; ++i) {
            level.x[row + std::size_t(i)] =
                (first * level.inverse[row + std::size_t(i)]) * b[row + std::size_t(i)];
        }
    });
    for (std::size_t s = 1; s < sweeps; ++s) {
        jacobi(level, level.x.data(), b, level.scratch.data(), omegas[s], pool);
        level.x.swap(level.scratch);
    }
}

/// x[i] += in[i] from[i / 2] along a row, kLanes cells at a time (each coarse value loaded once and put in
/// two lanes; the same operations on each cell as one at a time). g++ left the loop a cell at a time: 2.9%
/// of a 64^3 plume's step.
inline void prolongRow(const float* from, const float* in, float* x, int n) {
    int i = 0;
    for (; i + kLanes <= n; i += kLanes) {
        storeLanes(x + i, loadAs<Lanes>(x + i) + loadAs<Lanes>(in + i) * doubledLanes(from + i / 2));
    }
    for (; i < n; ++i) {
        x[i] += in[i] * from[i / 2];
    }
}

/// The V-cycle on level l for right-hand side b (level 0's is the CG residual; the others' their b), the
/// result in the level's x: Jacobi from zero, the residual summed onto the coarser level's cells, its
/// correction added back to every cell it merged, Jacobi again (the same weights in the reverse order: the
/// cycle is symmetric, as CG needs).
void vcycle(std::vector<AirLevel>& levels, std::size_t l, const float* b, WorkerPool& pool) {
    AirLevel& level = levels[l];
    const SmoothingWeights& weights = smoothingWeights();
    if (l + 1 == levels.size()) {
        smoothFromZero(level, b, weights.coarsest.data(), weights.coarsest.size(), pool);
        return;
    }
    const float* omegas = l == 0 ? weights.fine.data() : weights.coarse.data();
    const std::size_t sweeps = l == 0 ? weights.fine.size() : weights.coarse.size();
    smoothFromZero(level, b, omegas, sweeps, pool);
    const Padded g(level.n);
    AirLevel& coarse = levels[l + 1];
    const Padded c(coarse.n);
    residualLevel(level, level.x.data(), b, level.scratch.data(), pool);
    // restriction: the sum of a coarse cell's (up to) eight cells; a missing one is padding, zero
    forRows(pool, c.ny, c.nz, [&](int j, int k) {
        for (int i = 0; i < c.nx; ++i) {
            const float* f = level.scratch.data() + g.at(2 * i, 2 * j, 2 * k);
            coarse.b[c.at(i, j, k)] = ((f[0] + f[1]) + (f[g.sx] + f[g.sx + 1])) +
                                      ((f[g.sy] + f[g.sy + 1]) + (f[g.sy + g.sx] + f[g.sy + g.sx + 1]));
        }
    });
    vcycle(levels, l + 1, coarse.b.data(), pool);
    forRows(pool, g.ny, g.nz, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        const float* from = coarse.x.data() + c.at(0, j / 2, k / 2);
        const float* in = level.inAir.data() + row;
        float* x = level.x.data() + row;
        prolongRow(from, in, x, g.nx);
    });
    for (std::size_t s = sweeps; s-- > 0;) {
        jacobi(level, level.x.data(), b, level.scratch.data(), omegas[s], pool);
        level.x.swap(level.scratch);
    }
}

/// The levels for the air's grid: each merges 2 x 2 x 2 cells of the one above (an odd side's last cells
/// alone), down to a side of 2 or fewer than 64 cells.
void buildLevels(Air& air) {
    std::vector<AirLevel>& levels = air.scratch.levels;
    levels.clear();
    std::array<int, 3> n = air.cells;
    float weight = 1.0f;
    for (;;) {
        AirLevel level;
        level.n = n;
        level.weight = weight;
        const Padded g(n);
        level.diagonal.assign(g.size(), 0.0f);
        level.inverse.assign(g.size(), 0.0f);
        level.inAir.assign(g.size(), 0.0f);
        level.x.assign(g.size(), 0.0f);
        level.b.assign(g.size(), 0.0f);
        level.scratch.assign(g.size(), 0.0f);
        level.solid.assign(std::size_t(n[0]) * std::size_t(n[1]) * std::size_t(n[2]), 0);
        levels.push_back(std::move(level));
        if (std::min({n[0], n[1], n[2]}) <= 2 || std::size_t(n[0]) * n[1] * n[2] < 64) {
            break;
        }
        n = {(n[0] + 1) / 2, (n[1] + 1) / 2, (n[2] + 1) / 2};
        weight *= kCoarseWeightGrowth;
    }
}

/// Each level's solid cells (a coarse cell is solid when all its cells are) and its diagonal: weight times
/// the neighbours that are air plus the open sides (zero pressure beyond them); a solid cell's is zero, and
/// so is its Jacobi weight, which keeps it at zero.
void shapeLevels(Air& air) {
    std::vector<AirLevel>& levels = air.scratch.levels;
    for (std::size_t l = 0; l < levels.size(); ++l) {
        AirLevel& level = levels[l];
        const std::array<int, 3> n = level.n;
        auto cell = [&](int i, int j, int k) {
            return std::size_t(i) + std::size_t(n[0]) * (std::size_t(j) + std::size_t(n[1]) * std::size_t(k));
        };
        if (l == 0) {
            if (air.solid.empty()) {
                std::fill(level.solid.begin(), level.solid.end(), std::uint8_t(0));
            } else {
                // a body's cells and a driving source's alike: out of the pressure problem
                std::transform(air.solid.begin(), air.solid.end(), level.solid.begin(),
                               [](std::uint8_t s) { return std::uint8_t(s != 0 ? 1 : 0); });
            }
        } else {
            const AirLevel& fine = levels[l - 1];
            for (int k = 0; k < n[2]; ++k) {
                for (int j = 0; j < n[1]; ++j) {
                    for (int i = 0; i < n[0]; ++i) {
                        std::uint8_t all = 1;
                        for (int c = 0; c < 8; ++c) {
                            const int fi = 2 * i + (c & 1), fj = 2 * j + ((c >> 1) & 1),
                                      fk = 2 * k + (c >> 2);
                            if (fi < fine.n[0] && fj < fine.n[1] && fk < fine.n[2]) {
                                all = std::uint8_t(
                                    all & fine.solid[std::size_t(fi) +
                                                     std::size_t(fine.n[0]) *
                                                         (std::size_t(fj) + std::size_t(fine.n[1]) * fk)]);
                            }
                        }
                        level.solid[cell(i, j, k)] = all;
                    }
                }
            }
        }
        const Padded g(n);
        for (int k = 0; k < n[2]; ++k) {
            for (int j = 0; j < n[1]; ++j) {
                for (int i = 0; i < n[0]; ++i) {
                    int count = 0;
                    if (!level.solid[cell(i, j, k)]) {
                        for (int a = 0; a < 3; ++a) {
                            for (int side = 0; side < 2; ++side) {
                                int m[3] = {i, j, k};
                                m[a] += side == 0 ? -1 : 1;
                                if (m[a] < 0 || m[a] >= n[std::size_t(a)]) {
                                    count += air.border[std::size_t(2 * a + side)] == AirBorder::Open ? 1 : 0;
                                } else {
                                    count += level.solid[cell(m[0], m[1], m[2])] ? 0 : 1;
                                }
                            }
                        }
                    }
                    level.diagonal[g.at(i, j, k)] = level.weight * float(count);
                    level.inverse[g.at(i, j, k)] = count > 0 ? 1.0f / (level.weight * float(count)) : 0.0f;
                    level.inAir[g.at(i, j, k)] = count > 0 ? 1.0f : 0.0f;
                    level.x[g.at(i, j, k)] = 0.0f;
                }
            }
        }
    }
}

bool allClosed(const Air& air) {
    return std::all_of(air.border.begin(), air.border.end(),
                       [](AirBorder b) { return b == AirBorder::Closed; });
}

/// The normal velocity on the closed sides' faces set to zero.
void closeSides(Air& air) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            const std::size_t row = std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
            if (air.border[0] == AirBorder::Closed) {
                air.u[row] = 0.0f;
            }
            if (air.border[1] == AirBorder::Closed) {
                air.u[row + std::size_t(nx)] = 0.0f;
            }
        }
        for (int i = 0; i < nx; ++i) {
            if (air.border[2] == AirBorder::Closed) {
                air.v[std::size_t(i) + std::size_t(nx) * std::size_t(ny + 1) * k] = 0.0f;
            }
            if (air.border[3] == AirBorder::Closed) {
                air.v[std::size_t(i) + std::size_t(nx) * (std::size_t(ny) + std::size_t(ny + 1) * k)] = 0.0f;
            }
        }
    }
    const std::size_t layer = std::size_t(nx) * std::size_t(ny);
    for (std::size_t c = 0; c < layer; ++c) {
        if (air.border[4] == AirBorder::Closed) {
            air.w[c] = 0.0f;
        }
        if (air.border[5] == AirBorder::Closed) {
            air.w[c + layer * std::size_t(nz)] = 0.0f;
        }
    }
}

/// The faces of the cells of row (j, k): cell i's low faces are u[i], v[i] and w[i], its high ones u[i + 1],
/// v[i + sv] and w[i + sw].
struct RowFaces {
    const float *u, *v, *w;
    std::size_t sv, sw;

    RowFaces(const Air& air, int j, int k) {
        const std::size_t nx = std::size_t(air.cells[0]), ny = std::size_t(air.cells[1]);
        u = air.u.data() + (nx + 1) * (std::size_t(j) + ny * std::size_t(k));
        v = air.v.data() + nx * (std::size_t(j) + (ny + 1) * std::size_t(k));
        w = air.w.data() + nx * (std::size_t(j) + ny * std::size_t(k));
        sv = nx;
        sw = nx * ny;
    }
    /// Face flows of cell i: (u_{i+1} - u_i) + (v_{j+1} - v_j) + (w_{k+1} - w_k), m/s.
    float outflow(int i) const {
        const auto n = std::size_t(i);
        return ((u[n + 1] - u[n]) + (v[n + sv] - v[n])) + (w[n + sw] - w[n]);
    }
};

/// Subtracts the mean over the air's cells (not the solid ones) from a padded vector: the all-closed
/// problem's constant null space.
void removeMean(const Air& air, std::vector<float>& x, WorkerPool& pool) {
    const Padded g(air.cells);
    const std::vector<float>& inverse = air.scratch.levels[0].inverse;
    const Total total = sumRows(pool, g.ny, g.nz, Total{}, [&](int j, int k) {
        Total t;
        const std::size_t row = g.at(0, j, k);
        for (int i = 0; i < g.nx; ++i) {
            if (inverse[row + std::size_t(i)] > 0.0f) {
                t.sum += double(x[row + std::size_t(i)]);
                t.count += 1.0;
            }
        }
        return t;
    });
    if (!(total.count > 0.0)) {
        return;
    }
    const auto mean = float(total.sum / total.count);
    forRows(pool, g.ny, g.nz, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        for (int i = 0; i < g.nx; ++i) {
            if (inverse[row + std::size_t(i)] > 0.0f) {
                x[row + std::size_t(i)] -= mean;
            }
        }
    });
}

/// The solid cells' faces set to their owners' velocities (a body's, a driving source's).
void holdFixedFaces(Air& air) {
    std::vector<float>* faces[3] = {&air.u, &air.v, &air.w};
    for (const AirFixedFace& f : air.fixedFaces) {
        (*faces[f.axis])[f.index] = f.velocity;
    }
}

/// The sum over a row of n cells of a_i b_i in double, in eight running sums (cell i in sum i mod 8, the
/// cells past the last eight in a ninth) added in a fixed order at the end. One running sum waits on every
/// addition before the next (four cycles each: a 64^3 grid's dot product took 0.25 ms); eight overlap.
double rowDot(const float* a, const float* b, int n) {
    __m128d s0 = _mm_setzero_pd(), s1 = s0, s2 = s0, s3 = s0;
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        const __m128 a0 = _mm_loadu_ps(a + i), b0 = _mm_loadu_ps(b + i);
        const __m128 a1 = _mm_loadu_ps(a + i + 4), b1 = _mm_loadu_ps(b + i + 4);
        s0 = _mm_add_pd(s0, _mm_mul_pd(_mm_cvtps_pd(a0), _mm_cvtps_pd(b0)));
        s1 = _mm_add_pd(s1,
                        _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(a0, a0)), _mm_cvtps_pd(_mm_movehl_ps(b0, b0))));
        s2 = _mm_add_pd(s2, _mm_mul_pd(_mm_cvtps_pd(a1), _mm_cvtps_pd(b1)));
        s3 = _mm_add_pd(s3,
                        _mm_mul_pd(_mm_cvtps_pd(_mm_movehl_ps(a1, a1)), _mm_cvtps_pd(_mm_movehl_ps(b1, b1))));
    }
    double rest = 0.0;
    for (; i < n; ++i) {
        rest += double(a[i]) * double(b[i]);
    }
    const __m128d all = _mm_add_pd(_mm_add_pd(s0, s1), _mm_add_pd(s2, s3));
    return (_mm_cvtsd_f64(all) + _mm_cvtsd_f64(_mm_unpackhi_pd(all, all))) + rest;
}

double dotCells(const Air& air, const std::vector<float>& a, const std::vector<float>& b, WorkerPool& pool) {
    const Padded g(air.cells);
    return sumRows(pool, g.ny, g.nz, 0.0, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        return rowDot(a.data() + row, b.data() + row, g.nx);
    });
}

/// The largest |v| seen, four floats at a time (g++ leaves a loop that keeps a maximum scalar): lane by
/// lane, then over the lanes. A maximum does not depend on the order it is taken in, and maxps(v, m) is (v
/// > m ? v : m), std::max(m, v) to the bit, a NaN passed over as there; so the value is exactly the one a
/// plain loop finds.
struct LargestAbs {
    __m128 most = _mm_setzero_ps();

    void add(__m128 v) { most = _mm_max_ps(_mm_andnot_ps(_mm_set1_ps(-0.0f), v), most); }
    /// One value, into the first lane (maxss keeps the upper lanes of its first operand, here the new
    /// value's zeros: taken alone, it wiped the largest of the cells i = 1 mod 4 whenever a row's length was
    /// not a multiple of four, and CG stopped, and divergence_max read, without them).
    void add(float v) { most = _mm_move_ss(most, _mm_max_ss(_mm_set_ss(std::abs(v)), most)); }
    /// In double (each float exactly; the largest float is the largest double of them). The lanes were
    /// kept in double until 2026-11-29: twice the instructions for the same value.
    double value() const {
        float lanes[4];
        _mm_storeu_ps(lanes, most);
        return double(std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3])));
    }
};

/// out = b - A x on the finest level (residualLevel's arithmetic) and the largest |out| of a cell, in one
/// pass (the row's largest taken while it is in the cache).
double residualAndLargest(const AirLevel& level, const float* x, const float* b, float* out,
                          WorkerPool& pool) {
    const Padded g(level.n);
    const float weight = level.weight;
    const float *d = level.diagonal.data(), *in = level.inAir.data();
    return sumRows(pool, g.ny, g.nz, Largest{},
                   [=](int j, int k) {
                       const std::size_t row = g.at(0, j, k);
                       for (int i = 0; i < g.nx; ++i) {
                           const std::size_t c = row + std::size_t(i);
                           out[c] = b[c] - in[c] * (d[c] * x[c] - weight * neighbourSum(x + c, g));
                       }
                       LargestAbs m;
                       int i = 0;
                       for (; i + 4 <= g.nx; i += 4) {
                           m.add(_mm_loadu_ps(out + row + std::size_t(i)));
                       }
                       for (; i < g.nx; ++i) {
                           m.add(out[row + std::size_t(i)]);
                       }
                       return Largest{m.value()};
                   })
        .value;
}

/// CG's update, in one pass: x += alpha p, r -= alpha q; returns the largest |r| of a cell. Four cells at
/// a time, each with the arithmetic of one (no fused multiply-add): the bits of the plain loop.
double stepAndLargest(const Air& air, std::vector<float>& x, std::vector<float>& r, float alpha,
                      const std::vector<float>& p, const std::vector<float>& q, WorkerPool& pool) {
    const Padded g(air.cells);
    const __m128 a4 = _mm_set1_ps(alpha), minusA4 = _mm_set1_ps(-alpha);
    return sumRows(pool, g.ny, g.nz, Largest{},
                   [&](int j, int k) {
                       LargestAbs m;
                       const std::size_t row = g.at(0, j, k);
                       float *xs = x.data() + row, *rs = r.data() + row;
                       const float *ps = p.data() + row, *qs = q.data() + row;
                       int i = 0;
                       for (; i + 4 <= g.nx; i += 4) {
                           _mm_storeu_ps(xs + i, _mm_add_ps(_mm_loadu_ps(xs + i),
                                                            _mm_mul_ps(a4, _mm_loadu_ps(ps + i))));
                           const __m128 ri =
                               _mm_add_ps(_mm_loadu_ps(rs + i), _mm_mul_ps(minusA4, _mm_loadu_ps(qs + i)));
                           _mm_storeu_ps(rs + i, ri);
                           m.add(ri);
                       }
                       for (; i < g.nx; ++i) {
                           xs[i] += alpha * ps[i];
                           rs[i] += -alpha * qs[i];
                           m.add(rs[i]);
                       }
                       return Largest{m.value()};
                   })
        .value;
}

// ---- advection and forces ----

/// Where a trilinear sample falls on a lattice: its first corner and the weights along each axis.
struct Corner {
    std::size_t base;
    float tx, ty, tz;
};

/// A field sampled on a lattice: value (a, b, c) sits at (a + ox, b + oy, c + oz) in cell units from the
/// box's lowest corner.
struct Lattice {
    const float* f;
    int nx, ny, nz;
    float ox, oy, oz;

    /// The corner and weights of the point (x, y, z) in cell units, clamped to the lattice.
    Corner corner(float x, float y, float z) const {
        const float fx = std::clamp(x - ox, 0.0f, float(nx - 1));
        const float fy = std::clamp(y - oy, 0.0f, float(ny - 1));
        const float fz = std::clamp(z - oz, 0.0f, float(nz - 1));
        const int i = std::min(int(fx), nx - 2), j = std::min(int(fy), ny - 2), k = std::min(int(fz), nz - 2);
        return {std::size_t(i) + std::size_t(nx) * (std::size_t(j) + std::size_t(ny) * std::size_t(k)),
                fx - float(i), fy - float(j), fz - float(k)};
    }
    /// Trilinear at a corner (of any field on this lattice).
    float at(const float* field, const Corner& c) const {
        const std::size_t sy = std::size_t(nx), sz = std::size_t(nx) * std::size_t(ny);
        const float* p = field + c.base;
        auto lerp = [](float a, float b, float t) { return a + t * (b - a); };
        const float x00 = lerp(p[0], p[1], c.tx), x10 = lerp(p[sy], p[sy + 1], c.tx);
        const float x01 = lerp(p[sz], p[sz + 1], c.tx), x11 = lerp(p[sz + sy], p[sz + sy + 1], c.tx);
        return lerp(lerp(x00, x10, c.ty), lerp(x01, x11, c.ty), c.tz);
    }
    float at(float x, float y, float z) const { return at(f, corner(x, y, z)); }
};

struct Lattices {
    Lattice u, v, w;
};

Lattices velocityLattices(const Air& air) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    return {{air.u.data(), nx + 1, ny, nz, 0.0f, 0.5f, 0.5f},
            {air.v.data(), nx, ny + 1, nz, 0.5f, 0.0f, 0.5f},
            {air.w.data(), nx, ny, nz + 1, 0.5f, 0.5f, 0.0f}};
}

/// The two indices (or one) of a lattice along an axis around a point offset from index i by d half
/// cells (d = -1, 0 or 1), clamped to [0, n) when `Clamp` (at the box's sides; elsewhere they are inside).
template <int D, bool Clamp>
void around(int i, int n, int (&out)[2]) {
    if constexpr (Clamp) {
        out[0] = std::clamp(D < 0 ? i - 1 : i, 0, n - 1);
        out[1] = std::clamp(D > 0 ? i + 1 : i, 0, n - 1);
    } else {
        out[0] = D < 0 ? i - 1 : i;
        out[1] = D > 0 ? i + 1 : i;
    }
}

/// Lattice c at a point of another lattice whose offsets differ by (DX, DY, DZ) half cells, at that
/// lattice's index (i, j, k): the mean of the two values either side along each axis where the point is
/// half way, which is what trilinear sampling there gives, without the search for the corner. With T =
/// Lanes, at i .. i + kLanes - 1: the lattice's values along a row are contiguous (clamped rows and layers
/// are the same for every lane; no lane's x may need clamping: velocityAtLanes).
template <int DX, int DY, int DZ, bool Clamp, class T = float>
T aligned(const Lattice& c, int i, int j, int k) {
    int is[2], js[2], ks[2];
    around<DX, Clamp>(i, c.nx, is);
    around<DY, Clamp>(j, c.ny, js);
    around<DZ, Clamp>(k, c.nz, ks);
    constexpr int cx = DX != 0 ? 2 : 1, cy = DY != 0 ? 2 : 1, cz = DZ != 0 ? 2 : 1;
    T sum{};
    for (int z = 0; z < cz; ++z) {
        for (int y = 0; y < cy; ++y) {
            for (int x = 0; x < cx; ++x) {
                sum += loadAs<T>(c.f + std::size_t(is[x]) +
                                 std::size_t(c.nx) * (std::size_t(js[y]) + std::size_t(c.ny) * ks[z]));
            }
        }
    }
    return sum * (1.0f / float(cx * cy * cz));
}

/// The velocity (in cells a step) at point (i, j, k) of lattice L: 0 the u faces, 1 the v faces, 2 the w
/// faces, 3 the cells' centres; `Clamp` for a point whose neighbours may lie past the box's sides.
template <int L, bool Clamp>
void velocityAt(const Lattices& vel, int i, int j, int k, float scale, float& x, float& y, float& z) {
    const auto index = [](const Lattice& l, int a, int b, int c) {
        return std::size_t(a) + std::size_t(l.nx) * (std::size_t(b) + std::size_t(l.ny) * c);
    };
    if constexpr (L == 0) {
        x = vel.u.f[index(vel.u, i, j, k)];
        y = aligned<-1, 1, 0, Clamp>(vel.v, i, j, k);
        z = aligned<-1, 0, 1, Clamp>(vel.w, i, j, k);
    } else if constexpr (L == 1) {
        x = aligned<1, -1, 0, Clamp>(vel.u, i, j, k);
        y = vel.v.f[index(vel.v, i, j, k)];
        z = aligned<0, -1, 1, Clamp>(vel.w, i, j, k);
    } else if constexpr (L == 2) {
        x = aligned<1, 0, -1, Clamp>(vel.u, i, j, k);
        y = aligned<0, 1, -1, Clamp>(vel.v, i, j, k);
        z = vel.w.f[index(vel.w, i, j, k)];
    } else {
        x = aligned<1, 0, 0, Clamp>(vel.u, i, j, k);
        y = aligned<0, 1, 0, Clamp>(vel.v, i, j, k);
        z = aligned<0, 0, 1, Clamp>(vel.w, i, j, k);
    }
    x *= scale;
    y *= scale;
    z *= scale;
}

/// velocityAt for a point of lattice L (whose shape `from` has), clamping only where a neighbour the
/// averages read may lie past the box's sides: the first and last faces along the lattice's own axis
/// (the cells' centres never reach past them). Both give the same bits where neither clamps.
template <int L>
void velocityAtPoint(const Lattices& vel, const Lattice& from, int i, int j, int k, float scale, float& x,
                     float& y, float& z) {
    const bool side = (L == 0 && (i == 0 || i == from.nx - 1)) || (L == 1 && (j == 0 || j == from.ny - 1)) ||
                      (L == 2 && (k == 0 || k == from.nz - 1));
    if (side) {
        velocityAt<L, true>(vel, i, j, k, scale, x, y, z);
    } else {
        velocityAt<L, false>(vel, i, j, k, scale, x, y, z);
    }
}

// ---- the advection kLanes points at a time: the same operations in the same order as one at a time
// (lane by lane, IEEE single precision, no contraction), so the same bits. GCC's vector extensions rather
// than a library: nothing packaged offers gathers and per-lane selects on plain SSE2.

/// velocityAt<L, ClampRows> at (i .. i + kLanes - 1, j, k), where no lane's neighbour along x lies past
/// the box's sides (the rows and layers the averages read may be clamped: they are the same for every lane).
template <int L, bool ClampRows>
void velocityAtLanes(const Lattices& vel, int i, int j, int k, float scale, Lanes& x, Lanes& y, Lanes& z) {
    const auto own = [&](const Lattice& l) {
        return loadAs<Lanes>(l.f + std::size_t(i) +
                             std::size_t(l.nx) * (std::size_t(j) + std::size_t(l.ny) * k));
    };
    if constexpr (L == 0) {
        x = own(vel.u);
        y = aligned<-1, 1, 0, ClampRows, Lanes>(vel.v, i, j, k);
        z = aligned<-1, 0, 1, ClampRows, Lanes>(vel.w, i, j, k);
    } else if constexpr (L == 1) {
        x = aligned<1, -1, 0, ClampRows, Lanes>(vel.u, i, j, k);
        y = own(vel.v);
        z = aligned<0, -1, 1, ClampRows, Lanes>(vel.w, i, j, k);
    } else if constexpr (L == 2) {
        x = aligned<1, 0, -1, ClampRows, Lanes>(vel.u, i, j, k);
        y = aligned<0, 1, -1, ClampRows, Lanes>(vel.v, i, j, k);
        z = own(vel.w);
    } else {
        x = aligned<1, 0, 0, ClampRows, Lanes>(vel.u, i, j, k);
        y = aligned<0, 1, 0, ClampRows, Lanes>(vel.v, i, j, k);
        z = aligned<0, 0, 1, ClampRows, Lanes>(vel.w, i, j, k);
    }
    x *= scale;
    y *= scale;
    z *= scale;
}

/// Lattice::corner for kLanes points: the first corners' indices and the weights.
struct CornerLanes {
    IntLanes base;
    IntLanes i, j, k; ///< the first corners' indices along each axis
    Lanes tx, ty, tz;
};

inline Lanes clampLanes(Lanes v, float lo, float hi) {
    const Lanes low = Lanes{} + lo, high = Lanes{} + hi; // every lane lo, hi
    const Lanes r = v < low ? low : v;                   // std::clamp's comparisons, lane by lane
    return high < r ? high : r;
}

inline CornerLanes cornerLanes(const Lattice& l, Lanes x, Lanes y, Lanes z) {
    const Lanes fx = clampLanes(x - l.ox, 0.0f, float(l.nx - 1));
    const Lanes fy = clampLanes(y - l.oy, 0.0f, float(l.ny - 1));
    const Lanes fz = clampLanes(z - l.oz, 0.0f, float(l.nz - 1));
    IntLanes i = __builtin_convertvector(fx, IntLanes), j = __builtin_convertvector(fy, IntLanes),
             k = __builtin_convertvector(fz, IntLanes);
    i = i > l.nx - 2 ? l.nx - 2 : i;
    j = j > l.ny - 2 ? l.ny - 2 : j;
    k = k > l.nz - 2 ? l.nz - 2 : k;
    return {i + l.nx * (j + l.ny * k),
            i,
            j,
            k,
            fx - __builtin_convertvector(i, Lanes),
            fy - __builtin_convertvector(j, Lanes),
            fz - __builtin_convertvector(k, Lanes)};
}

/// The eight values of the trilinear samples of lanes first .. first + 3 of c in a field: each lane's values
/// gathered as four pairs along x (each pair one 8-byte load, the four lanes' pairs transposed into two
/// vectors), v[2n] the lower of pair n and v[2n + 1] the upper, for pairs at offsets `pairs`.
inline void gatherFour(const float* field, const CornerLanes& c, int first, const std::size_t (&pairs)[4],
                       Float4 (&v)[8]) {
    const float* p[4];
    for (int lane = 0; lane < 4; ++lane) {
        p[lane] = field + std::size_t(c.base[first + lane]);
    }
    for (int n = 0; n < 4; ++n) {
        const auto pairAt = [&](int lane) {
            double two; // the lane's value and the next along x, in one load
            std::memcpy(&two, p[lane] + pairs[n], sizeof two);
            return _mm_castpd_ps(_mm_set_sd(two));
        };
        const __m128 ab = _mm_unpacklo_ps(pairAt(0), pairAt(1)); // a0 b0 a1 b1
        const __m128 cd = _mm_unpacklo_ps(pairAt(2), pairAt(3)); // c0 d0 c1 d1
        v[2 * n] = Float4(_mm_movelh_ps(ab, cd));                // a0 b0 c0 d0
        v[2 * n + 1] = Float4(_mm_movehl_ps(cd, ab));            // a1 b1 c1 d1
    }
}

/// a + t (b - a), lane by lane (a function, not a lambda: a lambda's conversion to a function pointer is
/// not compiled for AVX2, and passing eight floats to it would change the calling convention).
inline Lanes lerpLanes(Lanes a, Lanes b, Lanes t) {
    return a + t * (b - a);
}

/// Lattice::at for kLanes points: the values gathered four lanes at a time (gatherFour), then the same
/// interpolations as one point's, lane by lane.
inline Lanes atLanes(const Lattice& l, const float* field, const CornerLanes& c) {
    const std::size_t sy = std::size_t(l.nx), sz = std::size_t(l.nx) * std::size_t(l.ny);
    const std::size_t pairs[4] = {0, sy, sz, sz + sy};
    Lanes v[8];
#ifdef TUMBLE_AIR_AVX2
    Float4 low[8], high[8]; // lanes 0-3 and 4-7, joined in registers (through memory, a 32-byte load of two
                            // 16-byte stores waits for them: as slow as four lanes at a time)
    gatherFour(field, c, 0, pairs, low);
    gatherFour(field, c, 4, pairs, high);
    for (int n = 0; n < 8; ++n) {
        v[n] = __builtin_shufflevector(low[n], high[n], 0, 1, 2, 3, 4, 5, 6, 7);
    }
#else
    gatherFour(field, c, 0, pairs, v);
#endif
    const Lanes x00 = lerpLanes(v[0], v[1], c.tx), x10 = lerpLanes(v[2], v[3], c.tx);
    const Lanes x01 = lerpLanes(v[4], v[5], c.tx), x11 = lerpLanes(v[6], v[7], c.tx);
    return lerpLanes(lerpLanes(x00, x10, c.ty), lerpLanes(x01, x11, c.ty), c.tz);
}

/// Whether the samples of the points (i .. i + kLanes - 1, j, k) all fall in the 3 x 3 x 3 block of
/// lattice values around each point: every lane's first corner is its point's own index, or the one
/// before, along each axis (a flow of under a cell a step), and the block's rows, a value either side, lie
/// inside the field's `size` values (the values past a side that the rows take in are never chosen).
inline bool nearLanes(const Lattice& l, const CornerLanes& c, int i, int j, int k, std::size_t size) {
    const auto sy = std::ptrdiff_t(l.nx), sz = std::ptrdiff_t(l.nx) * std::ptrdiff_t(l.ny);
    if (std::ptrdiff_t(i - 1) + sy * (j - 1) + sz * (k - 1) < 0 ||
        std::ptrdiff_t(i + kLanes) + sy * (j + 1) + sz * (k + 1) >= std::ptrdiff_t(size)) {
        return false;
    }
    IntLanes own;
    for (int lane = 0; lane < kLanes; ++lane) {
        own[lane] = i + lane;
    }
    // each offset plus one is 0 or 1 exactly when the offset is -1 or 0: then their bits above the lowest
    // are clear in every lane
    const IntLanes off = ((c.i - own + 1) | (c.j - j + 1) | (c.k - k + 1)) >> 1;
    std::uint64_t words[sizeof off / sizeof(std::uint64_t)];
    std::memcpy(words, &off, sizeof off);
    std::uint64_t any = 0;
    for (const std::uint64_t w : words) {
        any |= w;
    }
    return any == 0;
}

/// atLanes where nearLanes holds: the block's 27 rows of kLanes values loaded whole, and each lane's
/// corners chosen from them lane by lane, rather than gathered. Each corner is the same value, and the
/// interpolations the same operations on the chosen values, so the bits are atLanes' (the rows the choice
/// leaves out are interpolated too: cheaper than gathering). The 64^3 plume's step 4.0-4.3 -> 3.8-4.2 ms
/// at two threads, 7.7-8.0 -> 7.2-7.5 at one (`BM_Air64Step`).
inline Lanes atNear(const Lattice& l, const float* field, const CornerLanes& c, int i, int j, int k) {
    const auto sy = std::ptrdiff_t(l.nx), sz = std::ptrdiff_t(l.nx) * std::ptrdiff_t(l.ny);
    const float* centre = field + (std::ptrdiff_t(i) + sy * j + sz * k);
    IntLanes own;
    for (int lane = 0; lane < kLanes; ++lane) {
        own[lane] = i + lane;
    }
    const IntLanes backX = c.i < own, backY = c.j < j, backZ = c.k < k; // the corner one before
    Lanes layers[3];
    for (int z = 0; z < 3; ++z) {
        Lanes rows[3];
        for (int y = 0; y < 3; ++y) {
            const float* row = centre + (sy * (y - 1) + sz * (z - 1));
            const Lanes before = loadAs<Lanes>(row - 1), at = loadAs<Lanes>(row),
                        after = loadAs<Lanes>(row + 1);
            rows[y] = lerpLanes(backX ? before : at, backX ? at : after, c.tx);
        }
        layers[z] = lerpLanes(backY ? rows[0] : rows[1], backY ? rows[1] : rows[2], c.ty);
    }
    return lerpLanes(backZ ? layers[0] : layers[1], backZ ? layers[1] : layers[2], c.tz);
}

/// The stretch of a row of lattice L whose points' velocity averages read no neighbour past the box's
/// sides along x (all of it, but the u faces' first and last points), and whether the averages clamp the
/// rows or layers they read: on the first and last rows of v faces, and layers of w faces (the same
/// clamping for every point of the row).
template <int L>
std::tuple<int, int, bool> lanesSpan(const Lattice& from, int j, int k) {
    if constexpr (L == 0) {
        return {1, from.nx - 1, false};
    } else if constexpr (L == 1) {
        return {0, from.nx, j == 0 || j == from.ny - 1};
    } else if constexpr (L == 2) {
        return {0, from.nx, k == 0 || k == from.nz - 1};
    } else {
        return {0, from.nx, false};
    }
}

/// advectLattice's row loop for points i .. i + kLanes - 1 (inside lanesSpan's stretch).
template <int L, bool ClampRows>
void advectLanes(const Lattices& velocity, const Lattice& from, const float* second, float* out, float* out2,
                 float scale, int i, int j, int k) {
    Lanes vx, vy, vz;
    velocityAtLanes<L, ClampRows>(velocity, i, j, k, scale, vx, vy, vz);
    Lanes x;
    for (int lane = 0; lane < kLanes; ++lane) {
        x[lane] = float(i) + float(lane); // exact: the points' own x, as float(i + lane)
    }
    x = x + from.ox - vx;
    const Lanes y = (float(j) + from.oy) - vy, z = (float(k) + from.oz) - vz;
    const CornerLanes c = cornerLanes(from, x, y, z);
    const std::size_t at =
        std::size_t(from.nx) * (std::size_t(j) + std::size_t(from.ny) * k) + std::size_t(i);
    const std::size_t size = std::size_t(from.nx) * std::size_t(from.ny) * std::size_t(from.nz);
    const bool near = nearLanes(from, c, i, j, k, size);
    const Lanes a = near ? atNear(from, from.f, c, i, j, k) : atLanes(from, from.f, c);
    std::memcpy(out + at, &a, sizeof a);
    if (second != nullptr) {
        const Lanes b = near ? atNear(from, second, c, i, j, k) : atLanes(from, second, c);
        std::memcpy(out2 + at, &b, sizeof b);
    }
}

/// Every point of lattice L (whose shape `from` has) takes `from`'s fields (one, or two sharing the
/// weights: smoke and heat) at the point the flow brought there over the step: the point followed back
/// along the velocity there (`scale` = dt / dx, in cells). kLanes at a time where the velocity's averages
/// need no clamping along x, one at a time elsewhere.
template <int L>
void advectLattice(const Lattices& velocity, const Lattice& from, const float* second, float* out,
                   float* out2, float scale, WorkerPool& pool) {
    forRows(pool, from.ny, from.nz, [&](int j, int k) {
        const std::size_t row = std::size_t(from.nx) * (std::size_t(j) + std::size_t(from.ny) * k);
        const float y = float(j) + from.oy, z = float(k) + from.oz;
        const auto [begin, end, clampRows] = lanesSpan<L>(from, j, k);
        const auto block = [&, clamp = clampRows](int i) {
            if (clamp) {
                advectLanes<L, true>(velocity, from, second, out, out2, scale, i, j, k);
            } else {
                advectLanes<L, false>(velocity, from, second, out, out2, scale, i, j, k);
            }
        };
        int lanesEnd = begin;
        for (; lanesEnd + kLanes <= end; lanesEnd += kLanes) {
            block(lanesEnd);
        }
        if (lanesEnd < end && end - begin >= kLanes) {
            // the last points of the span in one more block, overlapping the one before: a point computed
            // twice gets the same bits both times (and reads only `from`), and a block costs what a couple
            // of points one at a time do
            block(end - kLanes);
            lanesEnd = end;
        }
        for (int i = 0; i < from.nx; ++i) {
            if (i == begin && lanesEnd > begin) {
                i = lanesEnd - 1;
                continue;
            }
            float vx, vy, vz;
            velocityAtPoint<L>(velocity, from, i, j, k, scale, vx, vy, vz);
            const Corner c = from.corner(float(i) + from.ox - vx, y - vy, z - vz);
            out[row + std::size_t(i)] = from.at(from.f, c);
            if (second != nullptr) {
                out2[row + std::size_t(i)] = from.at(second, c);
            }
        }
    });
}

/// `value` if it is within the lowest and highest of the eight lattice values a trilinear sample at c
/// mixed, else `fallback`.
inline float withinCorner(float value, float fallback, const Lattice& l, const float* field,
                          const Corner& c) {
    const std::size_t sy = std::size_t(l.nx), sz = std::size_t(l.nx) * std::size_t(l.ny);
    const float* p = field + c.base;
    const float corners[8] = {p[0], p[1], p[sy], p[sy + 1], p[sz], p[sz + 1], p[sz + sy], p[sz + sy + 1]};
    const auto [lo, hi] = std::minmax_element(std::begin(corners), std::end(corners));
    return value >= *lo && value <= *hi ? value : fallback;
}

/// MacCormack's correction (Selle, Fedkiw, Kim, Liu and Rossignac 2008), after the forward step gave
/// `out` and `out` carried back by the reverse step gave `back`: out + (from - back) / 2, half the forward
/// step's error taken off; where that leaves the values the forward step's sample mixed (a new extremum),
/// the forward step's own value, as Selle et al. propose. (Clamped to those values instead, the chimney
/// demo's air gained energy: its kinetic energy, 36 J in the steady crosswind, burst to 200-1100 J after
/// 10-16 s, vorticity and buoyancy off too; with the forward value it stays at 31-38 J for a minute.)
template <int L>
void correctLattice(const Lattices& velocity, const Lattice& from, const float* second, const float* back,
                    const float* back2, float* out, float* out2, float scale, WorkerPool& pool) {
    forRows(pool, from.ny, from.nz, [&](int j, int k) {
        const std::size_t row = std::size_t(from.nx) * (std::size_t(j) + std::size_t(from.ny) * k);
        const float y = float(j) + from.oy, z = float(k) + from.oz;
        for (int i = 0; i < from.nx; ++i) {
            float vx, vy, vz;
            velocityAtPoint<L>(velocity, from, i, j, k, scale, vx, vy, vz);
            const Corner c = from.corner(float(i) + from.ox - vx, y - vy, z - vz);
            const std::size_t at = row + std::size_t(i);
            out[at] = withinCorner(out[at] + 0.5f * (from.f[at] - back[at]), out[at], from, from.f, c);
            if (second != nullptr) {
                out2[at] =
                    withinCorner(out2[at] + 0.5f * (second[at] - back2[at]), out2[at], from, second, c);
            }
        }
    });
}

/// Lattice L's fields (`from`, and `second` on the same lattice) advected into out (and out2): one
/// semi-Lagrangian step, or with MacCormack's correction, which needs a step back along the same velocity
/// (into the scratch's `back` vectors).
template <int L>
void advectFields(Air& air, const Lattices& velocity, const Lattice& from, const float* second, float* out,
                  float* out2, float scale, WorkerPool& pool) {
    advectLattice<L>(velocity, from, second, out, out2, scale, pool);
    if (!air.maccormack) {
        return;
    }
    AirScratch& s = air.scratch;
    const Lattice forward{out, from.nx, from.ny, from.nz, from.ox, from.oy, from.oz};
    advectLattice<L>(velocity, forward, out2, s.back.data(), s.back2.data(), -scale, pool);
    correctLattice<L>(velocity, from, second, s.back.data(), s.back2.data(), out, out2, scale, pool);
}

/// max(x, 0) lane by lane, as std::max(x, 0.0f) gives it.
inline Lanes ahead(Lanes x) {
    return x < 0.0f ? Lanes{} : x;
}

/// The most a cell's faces carry out of it, or into it, a step, in cells (the sum of its outward, or inward,
/// face speeds times dt over dx): what the conserving advection's substeps keep at one or under (out: no
/// cell gives more than it has; in as well: every face's own speed is then within a cell a substep, which
/// keeps Lax-Wendroff's factor 1 - c |s| from going negative). Infinite when a face's speed is not finite.
double largestOutflow(const Air& air, double scale, WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const std::size_t sv = std::size_t(nx), sw = std::size_t(nx) * std::size_t(ny);
    return sumRows(
               pool, ny, nz, Largest{},
               [&](int j, int k) {
                   const float* u =
                       air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
                   const float* v = air.v.data() + sv * (std::size_t(j) + std::size_t(ny + 1) * k);
                   const float* w = air.w.data() + sw * std::size_t(k) + sv * std::size_t(j);
                   // kLanes cells at a time (g++ leaves a loop that keeps a maximum scalar), the rest
                   // one at a time: a maximum is the same in any order
                   Lanes mostLanes{};
                   IntLanes unordered{};
                   int i = 0;
                   for (; i + kLanes <= nx; i += kLanes) {
                       const Lanes u0 = loadAs<Lanes>(u + i), u1 = loadAs<Lanes>(u + i + 1),
                                   v0 = loadAs<Lanes>(v + i), v1 = loadAs<Lanes>(v + i + sv),
                                   w0 = loadAs<Lanes>(w + i), w1 = loadAs<Lanes>(w + i + sw);
                       const Lanes out =
                           ((ahead(-u0) + ahead(u1)) + (ahead(-v0) + ahead(v1))) + (ahead(-w0) + ahead(w1));
                       const Lanes in =
                           ((ahead(u0) + ahead(-u1)) + (ahead(v0) + ahead(-v1))) + (ahead(w0) + ahead(-w1));
                       const Lanes larger = out < in ? in : out;
                       mostLanes = mostLanes < larger ? larger : mostLanes;
                       unordered |= (out != out) | (in != in);
                   }
                   float most = 0.0f;
                   bool notFinite = false;
                   for (int lane = 0; lane < kLanes; ++lane) {
                       most = std::max(most, mostLanes[lane]);
                       notFinite = notFinite || unordered[lane] != 0;
                   }
                   for (; i < nx; ++i) {
                       const float out = ((std::max(-u[i], 0.0f) + std::max(u[i + 1], 0.0f)) +
                                          (std::max(-v[i], 0.0f) + std::max(v[i + sv], 0.0f))) +
                                         (std::max(-w[i], 0.0f) + std::max(w[i + sw], 0.0f));
                       const float in = ((std::max(u[i], 0.0f) + std::max(-u[i + 1], 0.0f)) +
                                         (std::max(v[i], 0.0f) + std::max(-v[i + sv], 0.0f))) +
                                        (std::max(w[i], 0.0f) + std::max(-w[i + sw], 0.0f));
                       most = std::max(most, std::max(out, in));
                       notFinite = notFinite || std::isnan(out) || std::isnan(in);
                   }
                   // a NaN, which a maximum passes over, as an infinite flow
                   return Largest{notFinite ? std::numeric_limits<double>::infinity() : double(most) * scale};
               })
        .value;
}

/// A flow faster than this many cells a step is carried semi-Lagrangian (stable at any speed, not
/// conserving) rather than in as many conserving substeps.
constexpr int kMostConservingSubsteps = 64;

/// A cell of the grid as the conserving advection visits it: its index, where it lies, and its low faces
/// (u, v, w of the faces across x, y, z on its low side; the high ones are 1, nx and nx ny further on).
struct CellAt {
    std::size_t at;
    int i, j, k;
    const float *u, *v, *w;
};
using Interior = std::true_type; ///< all six of a cell's neighbours are in the box
using AtSide = std::false_type;  ///< some may not be

/// Calls fn(CellAt, Interior or AtSide) for every cell of the air's grid, z-slabs shared out over the pool;
/// a row's cells between its two ends, in a row away from the box's sides, are Interior and in a loop of
/// their own, which reads their neighbours without checks (the same values, so the same bits).
template <class F>
void forCells(const Air& air, WorkerPool& pool, F&& fn) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    forRows(pool, ny, nz, [&](int j, int k) {
        const std::size_t row = std::size_t(nx) * (std::size_t(j) + std::size_t(ny) * k);
        const float* u = air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
        const float* v = air.v.data() + std::size_t(nx) * (std::size_t(j) + std::size_t(ny + 1) * k);
        const float* w = air.w.data() + row;
        const auto cell = [&](int i) { return CellAt{row + std::size_t(i), i, j, k, u + i, v + i, w + i}; };
        if (!(j > 0 && j + 1 < ny && k > 0 && k + 1 < nz && nx > 2)) {
            for (int i = 0; i < nx; ++i) {
                fn(cell(i), AtSide{});
            }
            return;
        }
        fn(cell(0), AtSide{});
        for (int i = 1; i + 1 < nx; ++i) {
            fn(cell(i), Interior{});
        }
        fn(cell(nx - 1), AtSide{});
    });
}

/// A cell's value and its six neighbours' (`outside` past the box's sides).
struct Around {
    float here, west, east, below, above, behind, ahead;
};

inline float lowestOf(const Around& a) {
    return std::min(std::min(std::min(a.here, a.west), std::min(a.east, a.below)),
                    std::min(std::min(a.above, a.behind), a.ahead));
}
inline float highestOf(const Around& a) {
    return std::max(std::max(std::max(a.here, a.west), std::max(a.east, a.below)),
                    std::max(std::max(a.above, a.behind), a.ahead));
}

template <class Where>
inline Around aroundOf(const Air& air, const float* f, const CellAt& c, Where, float outside = 0.0f) {
    const std::ptrdiff_t sv = air.cells[0], sw = std::ptrdiff_t(air.cells[0]) * air.cells[1];
    const float* p = f + c.at;
    if constexpr (Where::value) {
        return {p[0], p[-1], p[1], p[-sv], p[sv], p[-sw], p[sw]};
    } else {
        return {p[0],
                c.i > 0 ? p[-1] : outside,
                c.i + 1 < air.cells[0] ? p[1] : outside,
                c.j > 0 ? p[-sv] : outside,
                c.j + 1 < air.cells[1] ? p[sv] : outside,
                c.k > 0 ? p[-sw] : outside,
                c.k + 1 < air.cells[2] ? p[sw] : outside};
    }
}

/// The speeds across a cell's six faces (m/s along their axes): low and high along x, y, z.
struct Faces {
    float west, east, below, above, behind, ahead;
};

inline Faces facesOf(const Air& air, const CellAt& c) {
    const std::ptrdiff_t sv = air.cells[0], sw = std::ptrdiff_t(air.cells[0]) * air.cells[1];
    return {c.u[0], c.u[1], c.v[0], c.v[sv], c.w[0], c.w[sw]};
}

/// The upwind flux across a face of speed s between values a (its low side) and b (its high side).
inline float upwindFlux(float s, float a, float b) {
    const float upwind = s > 0.0f ? a : b; // a select, not a branch: carryCells' loop vectorises
    return s * upwind;
}

/// The net upwind flux into a cell.
inline float upwindNet(const Around& a, const Faces& f) {
    return ((upwindFlux(f.west, a.west, a.here) - upwindFlux(f.east, a.here, a.east)) +
            (upwindFlux(f.below, a.below, a.here) - upwindFlux(f.above, a.here, a.above))) +
           (upwindFlux(f.behind, a.behind, a.here) - upwindFlux(f.ahead, a.here, a.ahead));
}

/// The antidiffusive flux of a face: Lax-Wendroff's flux (MacCormack's scheme on this linear problem)
/// less the upwind one, 0.5 |s| (1 - c |s|) (b - a), with c = dt / dx a substep.
inline float antidiffusiveFlux(float s, float a, float b, float c) {
    const float speed = std::abs(s);
    return 0.5f * speed * (1.0f - c * speed) * (b - a);
}

/// One conserving substep of two cell fields (smoke and heat: finite volumes, first-order upwind): each face
/// passes its speed times c (dt / dx a substep) of the cell upwind of it, and what one cell gives its
/// neighbour gains, to the bit (both compute the face's flux from the same numbers). Past an open side the
/// air is clean and at ambient temperature (zero); a closed side's faces are still. A row's cells away from
/// the box's sides go through a loop with plain indices, which g++ vectorises (upwindNet's arithmetic, so
/// the bits of the cells at the sides' one at a time).
void carryCells(const Air& air, const std::array<const float*, 2>& fields, const std::array<float*, 2>& out,
                float c, WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const std::ptrdiff_t sv = nx, sw = std::ptrdiff_t(nx) * ny;
    forRows(pool, ny, nz, [&](int j, int k) {
        const std::size_t row = std::size_t(nx) * (std::size_t(j) + std::size_t(ny) * k);
        const float* u = air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
        const float* v = air.v.data() + std::size_t(sv) * (std::size_t(j) + std::size_t(ny + 1) * k);
        const float* w = air.w.data() + row;
        const bool inside = j > 0 && j + 1 < ny && k > 0 && k + 1 < nz && nx > 2;
        for (std::size_t n = 0; n < 2; ++n) {
            const float* f = fields[n] + row;
            float* o = out[n] + row;
            const auto checked = [&](int i) {
                const CellAt cell{row + std::size_t(i), i, j, k, u + i, v + i, w + i};
                const Around a = aroundOf(air, fields[n], cell, AtSide{});
                o[i] = a.here + c * upwindNet(a, facesOf(air, cell));
            };
            if (!inside) {
                for (int i = 0; i < nx; ++i) {
                    checked(i);
                }
                continue;
            }
            checked(0);
            const float step = c; // a copy: the stores through o cannot change it, so the loop vectorises
            for (int i = 1; i + 1 < nx; ++i) {
                const float flows =
                    ((upwindFlux(u[i], f[i - 1], f[i]) - upwindFlux(u[i + 1], f[i], f[i + 1])) +
                     (upwindFlux(v[i], f[i - sv], f[i]) - upwindFlux(v[i + sv], f[i], f[i + sv]))) +
                    (upwindFlux(w[i], f[i - sw], f[i]) - upwindFlux(w[i + sw], f[i], f[i + sw]));
                o[i] = f[i] + step * flows; // upwindNet's sum
            }
            checked(nx - 1);
        }
    });
}

/// The antidiffusive fluxes into a cell through its six faces (out through a high face counts negative).
inline std::array<float, 6> antidiffusiveInflows(const Around& a, const Faces& f, float c) {
    return {
        antidiffusiveFlux(f.west, a.west, a.here, c),     -antidiffusiveFlux(f.east, a.here, a.east, c),
        antidiffusiveFlux(f.below, a.below, a.here, c),   -antidiffusiveFlux(f.above, a.here, a.above, c),
        antidiffusiveFlux(f.behind, a.behind, a.here, c), -antidiffusiveFlux(f.ahead, a.here, a.ahead, c)};
}

/// Flux-corrected transport (Zalesak 1979), the first pass: how much of the antidiffusive fluxes into
/// (plus) and out of (minus) each cell can be taken without the cell passing the highest or lowest value
/// around it before and after the upwind substep (`low`): the ratios R+ and R-, in [0, 1].
void limiterRatios(const Air& air, const float* field, const float* low, float* plus, float* minus, float c,
                   WorkerPool& pool) {
    forCells(air, pool, [&air, field, low, plus, minus, c](const CellAt& cell, auto where) {
        const Around a = aroundOf(air, field, cell, where);
        const std::array<float, 6> in = antidiffusiveInflows(a, facesOf(air, cell), c);
        // the bounds from the cells of the box alone (a side's outside, past a wall, is no value the cell
        // may reach; clean air coming in through an open side is in the upwind result already)
        const Around around = aroundOf(air, field, cell, where, field[cell.at]);
        const Around l = aroundOf(air, low, cell, where, low[cell.at]);
        const float gain = ((std::max(in[0], 0.0f) + std::max(in[1], 0.0f)) +
                            (std::max(in[2], 0.0f) + std::max(in[3], 0.0f))) +
                           (std::max(in[4], 0.0f) + std::max(in[5], 0.0f));
        const float loss = ((std::min(in[0], 0.0f) + std::min(in[1], 0.0f)) +
                            (std::min(in[2], 0.0f) + std::min(in[3], 0.0f))) +
                           (std::min(in[4], 0.0f) + std::min(in[5], 0.0f));
        const float highest = std::max(highestOf(around), highestOf(l));
        const float lowest = std::min(lowestOf(around), lowestOf(l));
        plus[cell.at] = gain > 0.0f ? std::min(1.0f, (highest - l.here) / (c * gain)) : 0.0f;
        minus[cell.at] = loss < 0.0f ? std::min(1.0f, (lowest - l.here) / (c * loss)) : 0.0f;
    });
}

/// The antidiffusive flux of a face from the cell before it (value a0, ratios p0, m0) to the one after (a1,
/// p1, m1), scaled by the smaller ratio of the cell it fills and the cell it drains.
inline float limitedFlux(float s, float a0, float a1, float p0, float m0, float p1, float m1, float c) {
    const float flux = antidiffusiveFlux(s, a0, a1, c);
    const float filling = std::min(p1, m0), draining = std::min(p0, m1);
    return flux * (flux >= 0.0f ? filling : draining);
}

/// Flux-corrected transport, the second pass: each face's limited antidiffusive flux (past a side the
/// outside's ratios are 1: the inside cell's alone count) added to the upwind substep's result (`low`, in
/// place). Both cells of a face scale it alike, so the total is kept.
void addLimitedFluxes(const Air& air, const float* field, const float* plus, const float* minus, float* low,
                      float c, WorkerPool& pool) {
    forCells(air, pool, [&air, field, plus, minus, low, c](const CellAt& cell, auto where) {
        const Around a = aroundOf(air, field, cell, where);
        const Around p = aroundOf(air, plus, cell, where, 1.0f);
        const Around m = aroundOf(air, minus, cell, where, 1.0f);
        const Faces f = facesOf(air, cell);
        const float net = ((limitedFlux(f.west, a.west, a.here, p.west, m.west, p.here, m.here, c) -
                            limitedFlux(f.east, a.here, a.east, p.here, m.here, p.east, m.east, c)) +
                           (limitedFlux(f.below, a.below, a.here, p.below, m.below, p.here, m.here, c) -
                            limitedFlux(f.above, a.here, a.above, p.here, m.here, p.above, m.above, c))) +
                          (limitedFlux(f.behind, a.behind, a.here, p.behind, m.behind, p.here, m.here, c) -
                           limitedFlux(f.ahead, a.here, a.ahead, p.here, m.here, p.ahead, m.ahead, c));
        low[cell.at] += c * net;
    });
}

/// The cells' smoke and heat carried by the faces' flows so that nothing is made or lost: the totals change
/// only by what crosses an open side. (The semi-Lagrangian step is not conserving: each cell samples the
/// point its own velocity came from, and where the flow turns those points crowd, or spread; in a closed box
/// with a fan, smoke grew by a third in a second, whatever the step, and by two thirds with MacCormack.) In
/// as many substeps as keep every cell's outflow (and inflow) within one cell a substep, so no cell gives
/// more than it has. A substep is first-order upwind (it smooths as the semi-Lagrangian step does where a
/// step carries under a cell); with `advection = "maccormack"`, Lax-Wendroff's second-order fluxes (what
/// MacCormack's predictor and corrector make of this linear problem) limited by flux-corrected transport, so
/// that no new extremum appears and the total is still kept.
void carryCellsConserving(Air& air, double outflow, double scale, WorkerPool& pool) {
    AirScratch& s = air.scratch;
    const int n = std::max(int(std::ceil(outflow)), 1);
    const auto c = float(scale / n);
    for (int step = 0; step < n; ++step) {
        carryCells(air, {air.smoke.data(), air.heat.data()}, {s.smoke.data(), s.heat.data()}, c, pool);
        for (auto [field, out] : {std::pair{&air.smoke, &s.smoke}, std::pair{&air.heat, &s.heat}}) {
            if (air.maccormack) {
                limiterRatios(air, field->data(), out->data(), s.back.data(), s.back2.data(), c, pool);
                addLimitedFluxes(air, field->data(), s.back.data(), s.back2.data(), out->data(), c, pool);
            }
            field->swap(*out);
        }
    }
}

bool advect(Air& air, double dt, WorkerPool& pool) {
    AirScratch& s = air.scratch;
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const Lattices velocity = velocityLattices(air);
    const auto scale = float(dt / air.cell);
    const double outflow = largestOutflow(air, dt / air.cell, pool);
    if (!(outflow * air.cell <= kMostAirSpeed * dt)) {
        return false; // blown up: not advected (a NaN position sent the trilinear gathers past the arrays)
    }
    // the cells first, while the faces still hold the step's (divergence-free) velocity
    if (outflow <= double(kMostConservingSubsteps)) {
        carryCellsConserving(air, outflow, dt / air.cell, pool);
    } else {
        advectFields<3>(air, velocity, {air.smoke.data(), nx, ny, nz, 0.5f, 0.5f, 0.5f}, air.heat.data(),
                        s.smoke.data(), s.heat.data(), scale, pool);
        air.smoke.swap(s.smoke);
        air.heat.swap(s.heat);
    }
    advectFields<0>(air, velocity, velocity.u, nullptr, s.u.data(), nullptr, scale, pool);
    advectFields<1>(air, velocity, velocity.v, nullptr, s.v.data(), nullptr, scale, pool);
    advectFields<2>(air, velocity, velocity.w, nullptr, s.w.data(), nullptr, scale, pool);
    air.u.swap(s.u);
    air.v.swap(s.v);
    air.w.swap(s.w);
    return true;
}

/// Buoyancy on every face inside the box: along gravity's direction, smoke_weight s - heat_lift (T - mean
/// T), with s and T the mean of the face's two cells.
void buoyancy(Air& air, const Vec3& gravity, double dt, WorkerPool& pool) {
    const int n[3] = {air.cells[0], air.cells[1], air.cells[2]};
    const double g = length(gravity);
    const Vec3 down = g > 0.0 ? gravity * (1.0 / g) : Vec3{0.0, -1.0, 0.0};
    // the mean over the cells outside bodies (which hold no heat); a driving source's cells count (they
    // hold air, and its heat)
    const Total heatInAir = sumRows(pool, n[1], n[2], Total{}, [&](int j, int k) {
        Total t;
        for (int i = 0; i < n[0]; ++i) {
            if (air.solid.empty() || air.solid[air.at(i, j, k)] != kBodyCell) {
                t.sum += double(air.heat[air.at(i, j, k)]);
                t.count += 1.0;
            }
        }
        return t;
    });
    const double meanHeat = heatInAir.count > 0.0 ? heatInAir.sum / heatInAir.count : 0.0;
    const auto weight = float(air.smokeWeight), lift = float(air.heatLift), mean = float(meanHeat);
    std::vector<float>* faces[3] = {&air.u, &air.v, &air.w};
    const double along[3] = {down.x, down.y, down.z};
    for (int a = 0; a < 3; ++a) {
        if (along[a] == 0.0) {
            continue;
        }
        const auto push = float(along[a] * dt);
        const std::size_t step = a == 0   ? 1
                                 : a == 1 ? std::size_t(n[0])
                                          : std::size_t(n[0]) * std::size_t(n[1]);
        std::array<int, 3> f{n[0], n[1], n[2]};
        f[std::size_t(a)] += 1;
        std::vector<float>& face = *faces[a];
        forRows(pool, f[1], f[2], [&](int j, int k) {
            // a face on the box's side is left alone (the projection sets it): along x the row's ends,
            // along y or z whole rows
            if ((a == 1 && (j == 0 || j == n[1])) || (a == 2 && (k == 0 || k == n[2]))) {
                return;
            }
            float* row = face.data() + std::size_t(f[0]) * (std::size_t(j) + std::size_t(f[1]) * k);
            const std::size_t c0 = air.at(0, j, k);
            const float *smokeOf = air.smoke.data(), *heatOf = air.heat.data();
            const int first = a == 0 ? 1 : 0, end = a == 0 ? n[0] : f[0];
            for (int i = first; i < end; ++i) {
                const std::size_t hi = c0 + std::size_t(i), lo = hi - step; // the cells on either side
                const float smoke = 0.5f * (smokeOf[lo] + smokeOf[hi]);
                const float heat = 0.5f * (heatOf[lo] + heatOf[hi]) - mean;
                row[i] += push * (weight * smoke - lift * heat);
            }
        });
    }
}

/// Three planes of n floats: a vector per cell, its x components, then its y, then its z.
struct Planes {
    std::array<float*, 3> of;
};

/// Each cell's velocity, the mean of its two faces along each axis.
void cellVelocities(const Air& air, const Planes& cv, WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    forRows(pool, ny, nz, [&](int j, int k) {
        const std::size_t c0 = air.at(0, j, k);
        const float* u = air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
        const float* v = air.v.data() + std::size_t(nx) * (std::size_t(j) + std::size_t(ny + 1) * k);
        const float* w = air.w.data() + c0;
        const std::size_t up = std::size_t(nx), back = std::size_t(nx) * std::size_t(ny);
        float *cx = cv.of[0] + c0, *cy = cv.of[1] + c0, *cz = cv.of[2] + c0;
        int i = 0;
        for (; i + kLanes <= nx; i += kLanes) { // the same operations, kLanes cells at a time (g++ left the
                                                // loop a cell at a time: 3.6% of a 64^3 plume's step)
            const auto m = std::size_t(i);
            storeLanes(cx + i, 0.5f * (loadAs<Lanes>(u + m) + loadAs<Lanes>(u + m + 1)));
            storeLanes(cy + i, 0.5f * (loadAs<Lanes>(v + m) + loadAs<Lanes>(v + m + up)));
            storeLanes(cz + i, 0.5f * (loadAs<Lanes>(w + m) + loadAs<Lanes>(w + m + back)));
        }
        for (; i < nx; ++i) {
            cx[i] = 0.5f * (u[i] + u[i + 1]);
            cy[i] = 0.5f * (v[i] + v[std::size_t(i) + up]);
            cz[i] = 0.5f * (w[i] + w[std::size_t(i) + back]);
        }
    });
}

/// A difference along one axis at one cell: central where it can be, one-sided at the box's sides (the two
/// cells either side, clamped, and one over the distance between them).
struct Span {
    int lo, hi;
    float scale;

    static Span at(int i, int size, float inv) {
        const int lo = std::max(i - 1, 0), hi = std::min(i + 1, size - 1);
        return Span{lo, hi, hi > lo ? inv / float(hi - lo) : 0.0f};
    }
};

/// Calls cell(i, x) for the cells of a row of nx, x its Span, and lanes(i, scale) for kLanes inner cells at
/// a time (for each, x.lo = i - 1 and x.hi = i + 1, the same scale), which must give the bits of cell() on
/// each.
template <class Cell, class Several>
void alongRow(int nx, float inv, Cell&& cell, Several&& lanes) {
    const int inner = std::max(nx - 1, 1);
    cell(0, Span::at(0, nx, inv));
    const Span middle = Span::at(1, nx, inv);
    int i = 1;
    for (; i + kLanes <= inner; i += kLanes) {
        lanes(i, Lanes{} + middle.scale);
    }
    for (; i < inner; ++i) {
        cell(i, Span{i - 1, i + 1, middle.scale});
    }
    if (nx > 1) {
        cell(nx - 1, Span::at(nx - 1, nx, inv));
    }
}

inline Lanes ld(const float* p) {
    return loadAs<Lanes>(p);
}
/// The square root of every lane (IEEE: exact to the last bit, as std::sqrt).
inline Lanes sqrtLanes(Lanes v) {
#ifdef TUMBLE_AIR_AVX2
    return Lanes(_mm256_sqrt_ps(__m256(v)));
#else
    return Lanes(_mm_sqrt_ps(__m128(v)));
#endif
}

/// omega = curl of the cell velocities, and |omega|.
void curlOf(const Air& air, const Planes& cv, const Planes& curl, float* length, WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const auto inv = float(1.0 / air.cell);
    const std::size_t row = std::size_t(nx), layer = std::size_t(nx) * std::size_t(ny);
    forRows(pool, ny, nz, [&](int j, int k) {
        const Span y = Span::at(j, ny, inv), z = Span::at(k, nz, inv);
        const std::size_t c0 = air.at(0, j, k);
        const std::size_t ym = row * std::size_t(y.lo) + layer * std::size_t(k);
        const std::size_t yp = row * std::size_t(y.hi) + layer * std::size_t(k);
        const std::size_t zm = row * std::size_t(j) + layer * std::size_t(z.lo);
        const std::size_t zp = row * std::size_t(j) + layer * std::size_t(z.hi);
        const float *vx = cv.of[0], *vy = cv.of[1], *vz = cv.of[2];
        float *wxs = curl.of[0] + c0, *wys = curl.of[1] + c0, *wzs = curl.of[2] + c0, *len = length + c0;
        alongRow(
            nx, inv,
            [&](int i, const Span& x) {
                const std::size_t m = std::size_t(i);
                const float wx = (vz[yp + m] - vz[ym + m]) * y.scale - (vy[zp + m] - vy[zm + m]) * z.scale;
                const float wy =
                    (vx[zp + m] - vx[zm + m]) * z.scale - (vz[c0 + x.hi] - vz[c0 + x.lo]) * x.scale;
                const float wz =
                    (vy[c0 + x.hi] - vy[c0 + x.lo]) * x.scale - (vx[yp + m] - vx[ym + m]) * y.scale;
                wxs[i] = wx;
                wys[i] = wy;
                wzs[i] = wz;
                len[i] = std::sqrt(wx * wx + wy * wy + wz * wz);
            },
            [&](int i, Lanes xs) {
                const std::size_t m = std::size_t(i);
                const Lanes ys = Lanes{} + y.scale, zs = Lanes{} + z.scale;
                const Lanes wx =
                    (ld(vz + yp + m) - ld(vz + ym + m)) * ys - (ld(vy + zp + m) - ld(vy + zm + m)) * zs;
                const Lanes wy = (ld(vx + zp + m) - ld(vx + zm + m)) * zs -
                                 (ld(vz + c0 + m + 1) - ld(vz + c0 + m - 1)) * xs;
                const Lanes wz = (ld(vy + c0 + m + 1) - ld(vy + c0 + m - 1)) * xs -
                                 (ld(vx + yp + m) - ld(vx + ym + m)) * ys;
                storeLanes(wxs + i, wx);
                storeLanes(wys + i, wy);
                storeLanes(wzs + i, wz);
                storeLanes(len + i, sqrtLanes(wx * wx + wy * wy + wz * wz));
            });
    });
}

/// The confinement force eps dx (N x omega) per cell, N the unit gradient of |omega|.
void confinementForce(const Air& air, const Planes& curl, const float* length, const Planes& force,
                      WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const auto inv = float(1.0 / air.cell);
    const std::size_t row = std::size_t(nx), layer = std::size_t(nx) * std::size_t(ny);
    const auto strength = float(air.vorticity * air.cell);
    forRows(pool, ny, nz, [&](int j, int k) {
        const Span y = Span::at(j, ny, inv), z = Span::at(k, nz, inv);
        const std::size_t c0 = air.at(0, j, k);
        const float* here = length + c0;
        const float* ym = length + row * std::size_t(y.lo) + layer * std::size_t(k);
        const float* yp = length + row * std::size_t(y.hi) + layer * std::size_t(k);
        const float* zm = length + row * std::size_t(j) + layer * std::size_t(z.lo);
        const float* zp = length + row * std::size_t(j) + layer * std::size_t(z.hi);
        const float *w0 = curl.of[0] + c0, *w1 = curl.of[1] + c0, *w2 = curl.of[2] + c0;
        float *fx = force.of[0] + c0, *fy = force.of[1] + c0, *fz = force.of[2] + c0;
        alongRow(
            nx, inv,
            [&](int i, const Span& x) {
                const float gx = (here[x.hi] - here[x.lo]) * x.scale;
                const float gy = (yp[i] - ym[i]) * y.scale;
                const float gz = (zp[i] - zm[i]) * z.scale;
                const float scale = strength / (std::sqrt(gx * gx + gy * gy + gz * gz) + 1e-20f);
                const float nxv = gx * scale, nyv = gy * scale, nzv = gz * scale;
                fx[i] = nyv * w2[i] - nzv * w1[i];
                fy[i] = nzv * w0[i] - nxv * w2[i];
                fz[i] = nxv * w1[i] - nyv * w0[i];
            },
            [&](int i, Lanes xs) {
                const Lanes gx = (ld(here + i + 1) - ld(here + i - 1)) * xs;
                const Lanes gy = (ld(yp + i) - ld(ym + i)) * y.scale;
                const Lanes gz = (ld(zp + i) - ld(zm + i)) * z.scale;
                const Lanes size = sqrtLanes(gx * gx + gy * gy + gz * gz);
                const Lanes scale = strength / (size + 1e-20f);
                const Lanes nxv = gx * scale, nyv = gy * scale, nzv = gz * scale;
                const Lanes a = ld(w0 + i), b = ld(w1 + i), c = ld(w2 + i);
                storeLanes(fx + i, nyv * c - nzv * b);
                storeLanes(fy + i, nzv * a - nxv * c);
                storeLanes(fz + i, nxv * b - nyv * a);
            });
    });
}

/// Each face inside the box += h times the sum of its two cells' forces.
void addFaceMeans(Air& air, const Planes& force, float h, WorkerPool& pool) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const auto row = std::ptrdiff_t(nx), layer = std::ptrdiff_t(nx) * ny;
    forRows(pool, ny, nz, [&](int j, int k) {
        const std::size_t c0 = air.at(0, j, k);
        const float *fx = force.of[0] + c0, *fy = force.of[1] + c0, *fz = force.of[2] + c0;
        float* u = air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
        for (int i = 1; i < nx; ++i) {
            u[i] += h * (fx[i] + fx[i - 1]);
        }
        if (j > 0) {
            float* v = air.v.data() + std::size_t(nx) * (std::size_t(j) + std::size_t(ny + 1) * k);
            for (int i = 0; i < nx; ++i) {
                v[i] += h * (fy[i] + fy[i - row]);
            }
        }
        if (k > 0) {
            float* w = air.w.data() + c0;
            for (int i = 0; i < nx; ++i) {
                w[i] += h * (fz[i] + fz[i - layer]);
            }
        }
    });
}

/// Vorticity confinement (Fedkiw, Stam and Jensen 2001): at each cell the curl omega of the cells'
/// velocities (central differences, one-sided at the box's sides), N the unit gradient of |omega|, and the
/// force eps dx (N x omega), which spins up the small eddies the grid's interpolation smooths away; each
/// face inside the box takes the mean of its two cells' forces.
void confineVorticity(Air& air, double dt, WorkerPool& pool) {
    // Scratch in planes (x components, then y, then z), not cell after cell, and kLanes inner cells of a row
    // at a time: g++ left the interleaved loops scalar (13% of a 64^3 step). Every value is computed by the
    // same operations as cell by cell, so the bits do not depend on either.
    AirScratch& s = air.scratch;
    const std::size_t n = air.cellCount();
    s.cellVelocity.resize(3 * n);
    s.curl.resize(3 * n);
    s.curlLength.resize(n);
    const Planes cv{{s.cellVelocity.data(), s.cellVelocity.data() + n, s.cellVelocity.data() + 2 * n}};
    const Planes curl{{s.curl.data(), s.curl.data() + n, s.curl.data() + 2 * n}};
    cellVelocities(air, cv, pool);
    curlOf(air, cv, curl, s.curlLength.data(), pool);
    // the force, in place of the cell velocities (no longer needed)
    confinementForce(air, curl, s.curlLength.data(), cv, pool);
    addFaceMeans(air, cv, float(0.5 * dt), pool);
}

} // namespace

namespace {

/// Viscosity, explicit: each velocity component diffused by nu dt Lap on its own lattice (a neighbour past
/// the lattice's end reads as the point itself), in as many substeps as nu h / dx^2 <= 1/6 needs (the load
/// refuses more than kMostViscositySubsteps: they would take minutes a step).
void diffuseVelocity(Air& air, double dt, WorkerPool& pool) {
    const double rate = air.viscosity * dt / (air.cell * air.cell);
    const int substeps = std::min(airViscositySubsteps(air, dt), kMostViscositySubsteps);
    const auto c = float(rate / substeps);
    const Lattices lattices = velocityLattices(air);
    std::vector<float>* fields[3] = {&air.u, &air.v, &air.w};
    std::vector<float>* outs[3] = {&air.scratch.u, &air.scratch.v, &air.scratch.w};
    const Lattice* shapes[3] = {&lattices.u, &lattices.v, &lattices.w};
    for (int a = 0; a < 3; ++a) {
        const Lattice& l = *shapes[a];
        for (int step = 0; step < substeps; ++step) {
            const float* f = fields[a]->data();
            float* o = outs[a]->data();
            forRows(pool, l.ny, l.nz, [&](int j, int k) {
                const std::size_t sy = std::size_t(l.nx), sz = std::size_t(l.nx) * std::size_t(l.ny);
                const std::size_t row = sy * (std::size_t(j) + std::size_t(l.ny) * k);
                for (int i = 0; i < l.nx; ++i) {
                    const std::size_t p = row + std::size_t(i);
                    const float x0 = i > 0 ? f[p - 1] : f[p], x1 = i + 1 < l.nx ? f[p + 1] : f[p];
                    const float y0 = j > 0 ? f[p - sy] : f[p], y1 = j + 1 < l.ny ? f[p + sy] : f[p];
                    const float z0 = k > 0 ? f[p - sz] : f[p], z1 = k + 1 < l.nz ? f[p + sz] : f[p];
                    o[p] = f[p] + c * (((x0 + x1) + (y0 + y1)) + (z0 + z1) - 6.0f * f[p]);
                }
            });
            fields[a]->swap(*outs[a]);
        }
    }
}

} // namespace

void initAir(Air& air) {
    const std::size_t nx = std::size_t(air.cells[0]), ny = std::size_t(air.cells[1]),
                      nz = std::size_t(air.cells[2]);
    air.u.assign((nx + 1) * ny * nz, 0.0f);
    air.v.assign(nx * (ny + 1) * nz, 0.0f);
    air.w.assign(nx * ny * (nz + 1), 0.0f);
    air.smoke.assign(nx * ny * nz, 0.0f);
    air.heat.assign(nx * ny * nz, 0.0f);
    buildLevels(air);
    shapeLevels(air);
    const std::size_t padded = Padded(air.cells).size();
    air.pressure.assign(padded, 0.0f);
    air.earlierPressure.assign(padded, 0.0f);
    air.projections = 0;
    AirScratch& s = air.scratch;
    s.r.assign(padded, 0.0f);
    s.p.assign(padded, 0.0f);
    s.q.assign(padded, 0.0f);
    s.u.assign(air.u.size(), 0.0f);
    s.v.assign(air.v.size(), 0.0f);
    s.w.assign(air.w.size(), 0.0f);
    s.smoke.assign(air.smoke.size(), 0.0f);
    s.heat.assign(air.heat.size(), 0.0f);
    if (air.maccormack) {
        s.back.assign(std::max({air.u.size(), air.v.size(), air.w.size()}), 0.0f);
        s.back2.assign(air.heat.size(), 0.0f);
    }
}

double airDivergenceMax(const Air& air, WorkerPool& pool) {
    const Padded g(air.cells);
    const std::vector<float>& inAir = air.scratch.levels[0].inAir;
    const int nx = air.cells[0];
    return sumRows(pool, air.cells[1], air.cells[2], Largest{},
                   [&](int j, int k) {
                       // the row's flows, 64 cells at a time, zero outside the pressure problem (a body's
                       // cells, air shut in by bodies), in a loop g++ vectorises; then their largest, four
                       // at a time (a NaN passed over, as std::max does)
                       const RowFaces faces(air, j, k);
                       const float* in = inAir.data() + g.at(0, j, k);
                       LargestAbs m;
                       for (int start = 0; start < nx; start += 64) {
                           const int n = std::min(64, nx - start);
                           float flows[64];
                           for (int i = 0; i < n; ++i) {
                               flows[i] = in[start + i] * faces.outflow(start + i);
                           }
                           int i = 0;
                           for (; i + 4 <= n; i += 4) {
                               m.add(_mm_loadu_ps(flows + i));
                           }
                           for (; i < n; ++i) {
                               m.add(flows[i]);
                           }
                       }
                       return Largest{m.value()};
                   })
               .value /
           air.cell;
}

/// A row's right-hand side of the projection, b = -dx (outflow) in the air's cells (zero in the others),
/// kLanes cells at a time: g++ left its loop a cell at a time, with a branch for the choice, and with
/// guessRow's loop it took 6.4% of a 64^3 plume's step (now 3.1%; the step at one thread 7.5-7.8 -> 7.1-7.3
/// ms, at two within the noise).
inline void rhsRow(const RowFaces& faces, const float* inverse, float* b, float dx, int n) {
    int i = 0;
    for (; i + kLanes <= n; i += kLanes) {
        const Lanes flow = ((loadAs<Lanes>(faces.u + i + 1) - loadAs<Lanes>(faces.u + i)) +
                            (loadAs<Lanes>(faces.v + i + faces.sv) - loadAs<Lanes>(faces.v + i))) +
                           (loadAs<Lanes>(faces.w + i + faces.sw) - loadAs<Lanes>(faces.w + i));
        storeLanes(b + i, loadAs<Lanes>(inverse + i) > 0.0f ? -dx * flow : Lanes{});
    }
    for (; i < n; ++i) {
        b[i] = inverse[i] > 0.0f ? -dx * faces.outflow(i) : 0.0f;
    }
}

/// The projection's first guess for a row of cells: the pressure carried on in time from the last two
/// projections, 2 q_n - q_n-1 (a solid cell's zero), the last kept in `before` for the next guess (the
/// last one alone is the guess until there are two). On a smoothly changing flow it starts CG nearer the
/// solution than the last pressure: CG iterations a step in four scenes 3.0 -> 2.3 (a 64^3 plume), 2.0 ->
/// 1.5 (a 32^3 one), 1.8 -> 1.0 (a closed box's), 2.6 -> 1.8 (a fan's jet round a block); where the flow
/// changes at once it may start further off, which costs iterations, never accuracy (CG runs to the
/// tolerance from any guess).
inline void guessRow(const float* inverse, float* now, float* before, int n) {
    int i = 0;
    for (; i + kLanes <= n; i += kLanes) { // kLanes at a time, the same operations on each (as rhsRow)
        const Lanes last = loadAs<Lanes>(now + i);
        storeLanes(now + i,
                   loadAs<Lanes>(inverse + i) > 0.0f ? 2.0f * last - loadAs<Lanes>(before + i) : Lanes{});
        storeLanes(before + i, last);
    }
    for (; i < n; ++i) {
        const float last = now[i];
        now[i] = inverse[i] > 0.0f ? 2.0f * last - before[i] : 0.0f;
        before[i] = last;
    }
}

/// The levels made again for the solid cells as they now are: a solid cell's pressures are zero, and the
/// cells let go by a body are listed, so that after their first solve their pressure before last is set
/// to it (carried on from a zero, the next guess would double it).
void reshapeForSolids(Air& air) {
    AirScratch& s = air.scratch;
    AirLevel& fine = s.levels[0];
    fine.scratch = fine.diagonal; // the cells' diagonals before: 0 for those out of the problem
    shapeLevels(air);
    air.solidChanged = false;
    s.freed.clear();
    for (std::size_t c = 0; c < air.pressure.size(); ++c) {
        if (!(fine.inverse[c] > 0.0f)) { // a solid cell's is zero
            air.pressure[c] = 0.0f;
            air.earlierPressure[c] = 0.0f;
        } else if (!(fine.scratch[c] > 0.0f)) {
            s.freed.push_back(std::uint32_t(c));
        }
    }
}

/// CG on the finest level from r = b - A q (q in air.pressure, r in the scratch), preconditioned by the
/// V-cycle, until no cell's residual is over `enough`; the iterations, and whether it got there.
std::pair<std::uint32_t, bool> solvePressure(Air& air, bool singular, double enough, WorkerPool& pool) {
    AirScratch& s = air.scratch;
    AirLevel& fine = s.levels[0];
    const Padded g(air.cells);
    vcycle(s.levels, 0, s.r.data(), pool);
    if (singular) {
        removeMean(air, fine.x, pool);
    }
    s.p.swap(fine.x); // p = z (the V-cycle writes every cell of its x again; the padding stays zero)
    double rz = dotCells(air, s.r, s.p, pool);
    for (std::uint32_t it = 0; it < kMostIterations; ++it) {
        applyLevel(fine, s.p.data(), s.q.data(), pool);
        const double pq = dotCells(air, s.p, s.q, pool);
        if (!(pq > 0.0)) {
            return {it, false};
        }
        const auto alpha = float(rz / pq);
        if (stepAndLargest(air, air.pressure, s.r, alpha, s.p, s.q, pool) <= enough) {
            return {it + 1, true};
        }
        vcycle(s.levels, 0, s.r.data(), pool);
        if (singular) {
            removeMean(air, fine.x, pool);
        }
        const double rzNext = dotCells(air, s.r, fine.x, pool);
        const auto beta = float(rzNext / rz);
        rz = rzNext;
        forRows(pool, g.ny, g.nz, [&](int j, int k) {
            const std::size_t row = g.at(0, j, k);
            for (int i = 0; i < g.nx; ++i) {
                s.p[row + std::size_t(i)] = fine.x[row + std::size_t(i)] + beta * s.p[row + std::size_t(i)];
            }
        });
    }
    return {kMostIterations, false};
}

void projectAir(Air& air, WorkerPool& pool) {
    AirScratch& s = air.scratch;
    AirLevel& fine = s.levels[0];
    const Padded g(air.cells);
    if (air.solidChanged) {
        reshapeForSolids(air);
    }
    closeSides(air);
    holdFixedFaces(air);
    const auto dx = float(air.cell);
    // b = -dx^2 div u = -dx (outflow) in the air's cells, and the first guess q (guessRow), in one pass;
    // r = b - A q
    const bool guessed = air.projections >= 2;
    if (!guessed) {
        air.earlierPressure = air.pressure;
        ++air.projections;
    }
    forRows(pool, g.ny, g.nz, [&](int j, int k) {
        const std::size_t row = g.at(0, j, k);
        const RowFaces faces(air, j, k);
        float* b = fine.b.data() + row;
        const float* inverse = fine.inverse.data() + row;
        rhsRow(faces, inverse, b, dx, g.nx);
        if (guessed) {
            guessRow(inverse, air.pressure.data() + row, air.earlierPressure.data() + row, g.nx);
        }
    });
    const bool singular = allClosed(air);
    if (singular) {
        removeMean(air, fine.b, pool);
        // the guess's constant too: CG leaves it as it is, and carried on from step to step, its rounding
        // would add up without bound
        removeMean(air, air.pressure, pool);
    }
    // a cell's divergence is its residual over dx^2
    const double enough = air.tolerance * double(dx) * double(dx);
    std::uint32_t it = 0;
    bool converged = true;
    // CG's running residual drifts from b - A q by rounding: once it is under the tolerance, the true one
    // is taken, and CG starts again from it while that is over (a closed 64 x 4 x 4 box ended at 1.003
    // times the tolerance without)
    for (int start = 0;
         start < kMostStarts && converged &&
         residualAndLargest(fine, air.pressure.data(), fine.b.data(), s.r.data(), pool) > enough;
         ++start) {
        std::uint32_t more = 0;
        std::tie(more, converged) = solvePressure(air, singular, enough, pool);
        it += more;
    }
    for (const std::uint32_t c : s.freed) {
        air.earlierPressure[c] = air.pressure[c];
    }
    s.freed.clear();
    if (!converged) {
        // no guess carried on from a pressure CG did not finish (air shut in by bodies, whose pressure
        // problem has no solution, would see its level run away): the next starts from this one alone
        air.projections = 1;
    }
    air.lastIterations = it;
    // u -= grad q, the padding's zero beyond an open side (a closed side's faces are set back to zero)
    const float inv = 1.0f / dx;
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const float* q = air.pressure.data();
    forRows(pool, ny, nz, [&](int j, int k) {
        float* u = air.u.data() + std::size_t(nx + 1) * (std::size_t(j) + std::size_t(ny) * k);
        const float* c = q + g.at(0, j, k);
        for (int i = 0; i <= nx; ++i) {
            u[i] -= (c[i] - c[i - 1]) * inv;
        }
    });
    forRows(pool, ny + 1, nz, [&](int j, int k) {
        float* v = air.v.data() + std::size_t(nx) * (std::size_t(j) + std::size_t(ny + 1) * k);
        const float* c = q + g.at(0, j, k);
        for (int i = 0; i < nx; ++i) {
            v[i] -= (c[i] - c[i - g.sx]) * inv;
        }
    });
    forRows(pool, ny, nz + 1, [&](int j, int k) {
        float* w = air.w.data() + std::size_t(nx) * (std::size_t(j) + std::size_t(ny) * k);
        const float* c = q + g.at(0, j, k);
        for (int i = 0; i < nx; ++i) {
            w[i] -= (c[i] - c[i - g.sy]) * inv;
        }
    });
    closeSides(air);
    holdFixedFaces(air); // a face of a solid cell keeps its body's (or source's) velocity
    air.divergenceMax = TUMBLE_AIR_VARIANT::airDivergenceMax(air, pool);
}

bool advectAir(Air& air, double dt, WorkerPool& pool) {
    return advect(air, dt, pool);
}

void finishAirStep(Air& air, const Vec3& gravity, double dt, WorkerPool& pool) {
    if (!air.solid.empty()) {
        // nothing is carried into a body (a driving source's cells keep what they hold and are fed)
        for (std::size_t c = 0; c < air.solid.size(); ++c) {
            if (air.solid[c] == kBodyCell) {
                air.smoke[c] = 0.0f;
                air.heat[c] = 0.0f;
            }
        }
    }
    if (air.dissipation > 0.0) {
        const auto keep = float(1.0 / (1.0 + dt * air.dissipation));
        for (float& s : air.smoke) {
            s *= keep;
        }
    }
    if (air.smokeWeight != 0.0 || air.heatLift != 0.0) {
        buoyancy(air, gravity, dt, pool);
    }
    if (air.vorticity > 0.0) {
        confineVorticity(air, dt, pool);
    }
    if (air.viscosity > 0.0) {
        diffuseVelocity(air, dt, pool);
    }
    TUMBLE_AIR_VARIANT::projectAir(air, pool);
}

Vec3 airVelocityAt(const Air& air, const Vec3& point) {
    const Lattices velocity = velocityLattices(air);
    const Vec3 local = (point - air.origin()) * (1.0 / air.cell);
    const auto x = float(local.x), y = float(local.y), z = float(local.z);
    return {velocity.u.at(x, y, z), velocity.v.at(x, y, z), velocity.w.at(x, y, z)};
}

} // namespace TUMBLE_AIR_VARIANT

#ifndef TUMBLE_AIR_AVX2

namespace air_avx2 { // the functions above, compiled for AVX2 (systems/air_solver_avx2.cpp)
bool advectAir(Air& air, double dt, WorkerPool& pool);
void finishAirStep(Air& air, const Vec3& gravity, double dt, WorkerPool& pool);
void projectAir(Air& air, WorkerPool& pool);
double airDivergenceMax(const Air& air, WorkerPool& pool);
} // namespace air_avx2

namespace {
constexpr double kAirDensity = 1.2; ///< kg/m^3, for the kinetic energy

bool avx2() {
    return activeSimd() == Simd::Avx2;
}
} // namespace

int airViscositySubsteps(const Air& air, double dt) {
    const double needed = std::ceil(air.viscosity * dt / (air.cell * air.cell) * 6.0);
    return needed <= 1.0                             ? 1
           : needed > double(kMostViscositySubsteps) ? kMostViscositySubsteps + 1
                                                     : int(needed);
}

void initAir(Air& air) {
    air_sse2::initAir(air);
}

bool stepAir(Air& air, const Vec3& gravity, double dt, WorkerPool& pool) {
    if (!advectAir(air, dt, pool)) {
        return false;
    }
    finishAirStep(air, gravity, dt, pool);
    return true;
}

bool advectAir(Air& air, double dt, WorkerPool& pool) {
    return avx2() ? air_avx2::advectAir(air, dt, pool) : air_sse2::advectAir(air, dt, pool);
}

void finishAirStep(Air& air, const Vec3& gravity, double dt, WorkerPool& pool) {
    if (avx2()) {
        air_avx2::finishAirStep(air, gravity, dt, pool);
    } else {
        air_sse2::finishAirStep(air, gravity, dt, pool);
    }
}

void projectAir(Air& air, WorkerPool& pool) {
    if (avx2()) {
        air_avx2::projectAir(air, pool);
    } else {
        air_sse2::projectAir(air, pool);
    }
}

double airDivergenceMax(const Air& air, WorkerPool& pool) {
    return avx2() ? air_avx2::airDivergenceMax(air, pool) : air_sse2::airDivergenceMax(air, pool);
}

bool airContains(const Air& air, const Vec3& point) {
    const Vec3 local = point - air.origin();
    return local.x >= 0.0 && local.y >= 0.0 && local.z >= 0.0 && local.x <= air.cells[0] * air.cell &&
           local.y <= air.cells[1] * air.cell && local.z <= air.cells[2] * air.cell;
}

Vec3 airVelocityAt(const Air& air, const Vec3& point) {
    return air_sse2::airVelocityAt(air, point);
}

double airSmokeTotal(const Air& air) {
    double total = 0.0;
    for (float s : air.smoke) {
        total += double(s);
    }
    return total * air.cell * air.cell * air.cell;
}

Vec3 airSmokeCentroid(const Air& air) {
    double total = 0.0;
    Vec3 moment;
    for (int k = 0; k < air.cells[2]; ++k) {
        for (int j = 0; j < air.cells[1]; ++j) {
            for (int i = 0; i < air.cells[0]; ++i) {
                const double s = air.smoke[air.at(i, j, k)];
                total += s;
                moment += Vec3{i + 0.5, j + 0.5, k + 0.5} * s;
            }
        }
    }
    if (!(total > 0.0)) {
        return air.centre;
    }
    return air.origin() + moment * (air.cell / total);
}

double airKineticEnergy(const Air& air) {
    // each face stands for the cell of air between the centres either side of it: half a cell for a face
    // on the box's side (counted whole, a uniform flow through an open box read 12.5% high at 8 cells)
    double sum = 0.0;
    const std::vector<float>* fields[3] = {&air.u, &air.v, &air.w};
    for (int a = 0; a < 3; ++a) {
        std::array<int, 3> n = air.cells;
        n[std::size_t(a)] += 1;
        const std::vector<float>& f = *fields[a];
        std::size_t at = 0;
        for (int k = 0; k < n[2]; ++k) {
            for (int j = 0; j < n[1]; ++j) {
                for (int i = 0; i < n[0]; ++i, ++at) {
                    const int along = a == 0 ? i : a == 1 ? j : k;
                    const double share = along == 0 || along == n[std::size_t(a)] - 1 ? 0.5 : 1.0;
                    sum += share * double(f[at]) * double(f[at]);
                }
            }
        }
    }
    return 0.5 * kAirDensity * sum * air.cell * air.cell * air.cell;
}

#endif // TUMBLE_AIR_AVX2

} // namespace tumble

#if defined(TUMBLE_AIR_AVX2) && defined(__clang__)
#pragma clang attribute pop
#endif
