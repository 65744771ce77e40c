#include "systems/linear_solver.h"

#include "systems/block_kernels.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <type_traits>

namespace tumble {

namespace {

constexpr std::uint32_t kCoarsestRows = 8; // solved by dense Cholesky (24 x 24 at most)
constexpr std::size_t kMaxLevels = 32;

/// Rows per chunk of the solver's loops that are not sums (the V-cycle's restrictions and prolongations,
/// the residuals of levels swept row after row, CG's direction update, the diagonal inverses): small enough
/// that the curtain's 1225 rows share out evenly over two threads (see kMassGrain); they change no bit. The
/// products that CG sums as it goes keep kDotRows; a coloured level's residuals go by its blocks of rows.
constexpr std::size_t kShareRows = 128;

/// Coupling strength of each stored block: the off-diagonal blocks of these matrices are -(h kd uu^T + h^2 K)
/// sums, so minus their trace measures how strongly two rows pull on each other.
template <class S>
std::vector<double> strengths(const BlockMatrix<S>& a) {
    std::vector<double> s(a.val.size(), 0.0);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[std::size_t(i) + 1]; ++b) {
            s[b] = a.col[b] == i ? 0.0 : std::max(0.0, -double(a.val[b].trace()));
        }
    }
    return s;
}

/// Greedy pairwise matching in row order: each unmatched row joins its strongest unmatched neighbour.
/// Rows coupled to nothing (pinned masses, whose rows are the identity) pair with each other, so that they
/// too shrink level by level instead of piling up on the coarsest one.
template <class S>
std::uint32_t matchPairs(const BlockMatrix<S>& pattern, const std::vector<double>& strength,
                         std::vector<std::uint32_t>& group) {
    constexpr std::uint32_t kNone = 0xffffffffu;
    group.assign(pattern.n, kNone);
    std::uint32_t count = 0;
    std::uint32_t lonely = kNone; // an isolated row still waiting for a partner
    for (std::uint32_t i = 0; i < pattern.n; ++i) {
        if (group[i] != kNone) {
            continue;
        }
        std::uint32_t best = kNone;
        double bestStrength = 0.0;
        bool coupled = false;
        for (std::uint32_t b = pattern.rowStart[i]; b < pattern.rowStart[std::size_t(i) + 1]; ++b) {
            const std::uint32_t j = pattern.col[b];
            coupled = coupled || (j != i && strength[b] > 0.0);
            if (j != i && group[j] == kNone && strength[b] > bestStrength) {
                best = j;
                bestStrength = strength[b];
            }
        }
        if (!coupled) {
            if (lonely != kNone) {
                group[i] = group[lonely];
                lonely = kNone;
                continue;
            }
            lonely = i;
        }
        if (best == kNone && coupled) {
            // every neighbour is taken (the leaves of a star): join the strongest neighbour's group rather
            // than stay alone, so that coarsening never stalls
            double strongest = 0.0;
            for (std::uint32_t b = pattern.rowStart[i]; b < pattern.rowStart[std::size_t(i) + 1]; ++b) {
                const std::uint32_t j = pattern.col[b];
                if (j != i && group[j] != kNone && strength[b] > strongest) {
                    strongest = strength[b];
                    group[i] = group[j];
                }
            }
            if (group[i] != kNone) {
                continue;
            }
        }
        group[i] = count;
        if (best != kNone) {
            group[best] = count;
        }
        ++count;
    }
    return count;
}

/// The pattern of the matrix coarsened by a grouping.
template <class S>
BlockMatrix<S> coarsePattern(const BlockMatrix<S>& fine, const std::vector<std::uint32_t>& group,
                             std::uint32_t count) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    pairs.reserve(fine.col.size());
    for (std::uint32_t i = 0; i < fine.n; ++i) {
        for (std::uint32_t b = fine.rowStart[i]; b < fine.rowStart[std::size_t(i) + 1]; ++b) {
            pairs.emplace_back(group[i], group[fine.col[b]]);
        }
    }
    return BlockMatrix<S>::fromPairs(count, std::move(pairs));
}

/// Lists in compressed-row form from a map item -> list: list l gets its items in ascending order.
void invert(const std::vector<std::uint32_t>& listOf, std::uint32_t lists, std::vector<std::uint32_t>& start,
            std::vector<std::uint32_t>& items) {
    start.assign(std::size_t(lists) + 1, 0);
    for (std::uint32_t l : listOf) {
        ++start[std::size_t(l) + 1];
    }
    for (std::uint32_t l = 0; l < lists; ++l) {
        start[std::size_t(l) + 1] += start[l];
    }
    items.resize(listOf.size());
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::uint32_t k = 0; k < listOf.size(); ++k) {
        items[next[listOf[k]]++] = k;
    }
}

/// Coarse blocks as sums of fine ones, accumulated in double (where couplings cancel, a free body's springs,
/// float sums would lose what is left): each coarse block gathers its fine blocks in ascending order, the
/// additions a scatter in fine order would make, so threads may share out the coarse blocks.
template <class S>
void galerkin(const BlockMatrix<S>& fine, const std::vector<std::uint32_t>& sourceStart,
              const std::vector<std::uint32_t>& sources, BlockMatrix<S>& coarse, WorkerPool& pool) {
    pool.forEach(coarse.val.size(), 1024, [&](std::size_t c) {
        Mat3 sum;
        for (std::uint32_t k = sourceStart[c]; k < sourceStart[c + 1]; ++k) {
            const Mat3T<S>& from = fine.val[sources[k]];
            for (std::size_t e = 0; e < 9; ++e) {
                sum.m[e] += double(from.m[e]);
            }
        }
        coarse.val[c] = sum.template cast<S>();
    });
}

/// Where each fine block of a grouping sums into, as lists per coarse block.
template <class S>
void findSources(const BlockMatrix<S>& fine, const std::vector<std::uint32_t>& group, BlockMatrix<S>& coarse,
                 std::vector<std::uint32_t>& start, std::vector<std::uint32_t>& sources) {
    std::vector<std::uint32_t> slot(fine.col.size());
    for (std::uint32_t i = 0; i < fine.n; ++i) {
        for (std::uint32_t b = fine.rowStart[i]; b < fine.rowStart[std::size_t(i) + 1]; ++b) {
            slot[b] = coarse.find(group[i], group[fine.col[b]]);
        }
    }
    invert(slot, std::uint32_t(coarse.val.size()), start, sources);
}

template <class S>
void invertDiagonal(const BlockMatrix<S>& a, std::vector<Mat3T<S>>& out, WorkerPool& pool) {
    out.resize(a.n);
    pool.forEach(a.n, kShareRows, [&](std::size_t i) { out[i] = a.val[a.diag[i]].inverse(); });
}

/// a . b over rows [first, end), in double, in index order.
template <class S>
double dotRows(const std::vector<Vec3T<S>>& a, const std::vector<Vec3T<S>>& b, std::size_t first,
               std::size_t end) {
    double s = 0.0;
    for (std::size_t i = first; i < end; ++i) {
        s += double(a[i].x) * double(b[i].x) + double(a[i].y) * double(b[i].y) +
             double(a[i].z) * double(b[i].z);
    }
    return s;
}

/// a . b over the rows of [first, end) that are not fixed, in double, in index order.
template <class S>
double freeDot(const std::vector<Vec3T<S>>& a, const std::vector<Vec3T<S>>& b,
               const std::vector<std::uint8_t>& fixed, std::size_t first, std::size_t end) {
    double s = 0.0;
    for (std::size_t i = first; i < end; ++i) {
        if (!fixed[i]) {
            s += double(a[i].x) * double(b[i].x) + double(a[i].y) * double(b[i].y) +
                 double(a[i].z) * double(b[i].z);
        }
    }
    return s;
}

/// Dot product accumulated in double: in index order within each chunk of kDotRows rows, the chunks'
/// partials added in chunk order (the same bits at any thread count, and exact enough for float vectors).
template <class S>
double dotAll(const std::vector<Vec3T<S>>& a, const std::vector<Vec3T<S>>& b, WorkerPool& pool) {
    return pool.sum(a.size(), kDotRows, 0.0,
                    [&](std::size_t first, std::size_t end) { return dotRows(a, b, first, end); });
}

/// Zeroes b's fixed rows in [first, end) and returns a . b over them in double, in index order.
template <class S>
double filteredDot(const std::vector<Vec3T<S>>& a, std::vector<Vec3T<S>>& b,
                   const std::vector<std::uint8_t>& fixed, std::size_t first, std::size_t end) {
    double s = 0.0;
    for (std::size_t i = first; i < end; ++i) {
        if (fixed[i]) {
            b[i] = Vec3T<S>{};
        }
        s += double(a[i].x) * double(b[i].x) + double(a[i].y) * double(b[i].y) +
             double(a[i].z) * double(b[i].z);
    }
    return s;
}

/// filteredDot over every row, in chunks of kDotRows (partials added in chunk order, as dotAll's).
template <class S>
double filteredDot(const std::vector<Vec3T<S>>& a, std::vector<Vec3T<S>>& b,
                   const std::vector<std::uint8_t>& fixed, WorkerPool& pool) {
    return pool.sum(a.size(), kDotRows, 0.0,
                    [&](std::size_t first, std::size_t end) { return filteredDot(a, b, fixed, first, end); });
}

template <class S>
void filter(std::vector<Vec3T<S>>& v, const std::vector<std::uint8_t>& fixed) {
    for (std::size_t i = 0; i < v.size(); ++i) {
        if (fixed[i]) {
            v[i] = Vec3T<S>{};
        }
    }
}

/// Rows per block of a coloured level: kSmoothBlock, or an eighth of the level if that is fewer (so a level
/// of a few thousand rows still has blocks enough to share out evenly). Fixed by the level's size.
std::uint32_t smoothBlockRows(std::uint32_t n) {
    return std::min(kSmoothBlock, (n + 7) / 8);
}

/// Greedy colouring of a level's blocks of `rows` rows, in block order: each block takes the lowest colour
/// none of its earlier neighbours has (a neighbour: a block holding a column of one of its rows). A grid
/// numbered row by row couples only nearby blocks, so two or three colours do. Then each row's
/// off-diagonal blocks listed as the sweep meets them (SweepOrder): those of rows swept before it (an
/// earlier colour, or its own block left of it) first. Fixed by the pattern.
template <class S>
void colourBlocks(const BlockMatrix<S>& a, std::uint32_t rows, std::vector<std::uint32_t>& start,
                  std::vector<std::uint32_t>& blocks, kernels::SweepOrder& order) {
    const std::uint32_t count = (a.n + rows - 1) / rows;
    std::vector<std::uint32_t> colour(count, 0);
    std::vector<std::uint8_t> used;
    std::uint32_t colours = 0;
    for (std::uint32_t k = 0; k < count; ++k) {
        used.assign(std::size_t(colours) + 1, 0);
        for (std::uint32_t i = k * rows; i < std::min(a.n, (k + 1) * rows); ++i) {
            for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[std::size_t(i) + 1]; ++b) {
                const std::uint32_t other = a.col[b] / rows;
                if (other < k) {
                    used[colour[other]] = 1;
                }
            }
        }
        std::uint32_t c = 0;
        while (used[c]) {
            ++c;
        }
        colour[k] = c;
        colours = std::max(colours, c + 1);
    }
    start.assign(std::size_t(colours) + 1, 0);
    for (std::uint32_t k = 0; k < count; ++k) {
        ++start[colour[k] + 1];
    }
    for (std::uint32_t c = 0; c < colours; ++c) {
        start[c + 1] += start[c];
    }
    blocks.resize(count);
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::uint32_t k = 0; k < count; ++k) {
        blocks[next[colour[k]]++] = k;
    }
    // a block's neighbours have other colours, so "before" is an earlier colour or, in its own block, a
    // lower row
    order.items.clear();
    order.split.resize(a.n);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        const std::uint32_t own = i / rows;
        auto before = [&](std::uint32_t j) {
            return j / rows == own ? j < i : colour[j / rows] < colour[own];
        };
        for (int pass = 0; pass < 2; ++pass) {
            if (pass == 1) {
                order.split[i] = std::uint32_t(order.items.size());
            }
            for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[std::size_t(i) + 1]; ++b) {
                if (b != a.diag[i] && before(a.col[b]) == (pass == 0)) {
                    order.items.push_back(b);
                }
            }
        }
    }
}

} // namespace

template <class S>
void AggregationMultigrid<S>::build(const BlockMatrix<S>& fine) {
    m_levels.clear();
    m_levels.reserve(kMaxLevels);
    const BlockMatrix<S>* current = &fine;
    while (current->n > kCoarsestRows && m_levels.size() < kMaxLevels) {
        // double pairwise matching: pairs of rows, then pairs of those pairs
        std::vector<std::uint32_t> first, second, middleStart, middleSources;
        const std::uint32_t n1 = matchPairs(*current, strengths(*current), first);
        BlockMatrix<S> middle = coarsePattern(*current, first, n1);
        findSources(*current, first, middle, middleStart, middleSources);
        galerkin(*current, middleStart, middleSources, middle, serialPool());
        const std::uint32_t n2 = matchPairs(middle, strengths(middle), second);
        if (n2 * 5 > current->n * 4) {
            break; // coarsening stalled (a graph with few couplings): solve what is left directly
        }
        Level level;
        level.group.resize(current->n);
        for (std::uint32_t i = 0; i < current->n; ++i) {
            level.group[i] = second[first[i]];
        }
        level.a = coarsePattern(*current, level.group, n2);
        findSources(*current, level.group, level.a, level.sources.start, level.sources.items);
        invert(level.group, n2, level.members.start, level.members.items);
        galerkin(*current, level.sources.start, level.sources.items, level.a, serialPool());
        m_levels.push_back(std::move(level));
        current = &m_levels.back().a;
    }
    // the levels that are smoothed (every one but the coarsest, solved directly) and big enough to share
    m_colours.assign(m_levels.size(), Colouring{});
    for (std::size_t l = 0; l < m_levels.size(); ++l) {
        const BlockMatrix<S>& a = l == 0 ? fine : m_levels[l - 1].a;
        if (a.n >= kColouredRows) {
            Colouring& c = m_colours[l];
            c.rows = smoothBlockRows(a.n);
            colourBlocks(a, c.rows, c.start, c.blocks, c.order);
        }
    }
    m_built = true;
}

template <class S>
bool packSymmetric(BlockMatrix<S>& a, WorkerPool& pool) {
    if constexpr (!std::is_same_v<S, float>) {
        a.packed.clear();
        return false; // the double kernels are plain code, reading val
    } else {
        if (a.n < kPackedRows) {
            a.packed.clear();
            return false;
        }
        const std::size_t blocks = a.val.size();
        a.packed.resize(6 * blocks); // step after step the same size: no pass of its own
        // bit for bit: -0 and +0 compare equal, and the packed rows must be the stored ones to the bit
        auto same = [](float u, float v) {
            return std::bit_cast<std::uint32_t>(u) == std::bit_cast<std::uint32_t>(v);
        };
        const std::size_t asymmetric =
            pool.sum(blocks, 4096, std::size_t(0), [&](std::size_t first, std::size_t end) {
                std::size_t count = 0;
                for (std::size_t k = first; k < end; ++k) {
                    const std::array<float, 9>& m = a.val[k].m;
                    count += !(same(m[1], m[3]) && same(m[2], m[6]) && same(m[5], m[7]));
                    float* out = a.packed.data() + 6 * k;
                    out[0] = m[0], out[1] = m[1], out[2] = m[2], out[3] = m[4], out[4] = m[5], out[5] = m[8];
                }
                return count;
            });
        if (asymmetric > 0) {
            a.packed.clear();
            return false;
        }
        return true;
    }
}

template <class S>
void AggregationMultigrid<S>::update(const BlockMatrix<S>& a, WorkerPool& pool) {
    m_fine = &a;
    if (!m_built) {
        build(a);
    } else {
        const BlockMatrix<S>* finer = &a;
        for (Level& level : m_levels) {
            galerkin(*finer, level.sources.start, level.sources.items, level.a, pool);
            finer = &level.a;
        }
    }
    // a coarse level of a packed matrix is symmetric block by block too (sums of its blocks)
    for (Level& level : m_levels) {
        if (a.isPacked()) {
            packSymmetric(level.a, pool);
        } else {
            level.a.packed.clear();
        }
    }
    invertDiagonal(a, m_fineDiagInverse, pool);
    for (Level& level : m_levels) {
        invertDiagonal(level.a, level.diagInverse, pool);
    }
    factorCoarsest();
}

template <class S>
void AggregationMultigrid<S>::factorCoarsest() {
    const BlockMatrix<S>& c = m_levels.empty() ? *m_fine : m_levels.back().a;
    const std::size_t d = 3 * std::size_t(c.n);
    m_coarsestDim = d;
    m_cholesky.assign(d * d, 0.0);
    for (std::uint32_t i = 0; i < c.n; ++i) {
        for (std::uint32_t b = c.rowStart[i]; b < c.rowStart[std::size_t(i) + 1]; ++b) {
            for (std::size_t r = 0; r < 3; ++r) {
                for (std::size_t k = 0; k < 3; ++k) {
                    // a block's rows are read as its columns, as the kernels do (linear_solver.h)
                    m_cholesky[(3 * i + r) * d + 3 * c.col[b] + k] = double(c.val[b].m[3 * k + r]);
                }
            }
        }
    }
    // in-place lower Cholesky, in double whatever S is. The operator is SPD by construction; if round-off
    // says otherwise, the diagonal is shifted a little and the factorisation tried again (it only has to
    // be a good preconditioner, not exact)
    m_dense = m_cholesky; // kept for a retry; a copy into storage reused step after step
    double largest = 0.0;
    for (std::size_t j = 0; j < d; ++j) {
        largest = std::max(largest, std::abs(m_dense[j * d + j]));
    }
    for (int attempt = 0; attempt < 8; ++attempt) {
        if (factorDense(d, attempt == 0 ? 0.0 : largest * 1e-7 * std::pow(10.0, attempt))) {
            return;
        }
        m_cholesky = m_dense;
    }
    throw SolverError("implicit solver: the system matrix is not positive definite (a negative "
                      "stiffness, mass or damping?)");
}

template <class S>
bool AggregationMultigrid<S>::factorDense(std::size_t d, double shift) {
    for (std::size_t j = 0; j < d; ++j) {
        m_cholesky[j * d + j] += shift;
    }
    for (std::size_t j = 0; j < d; ++j) {
        double diag = m_cholesky[j * d + j];
        for (std::size_t k = 0; k < j; ++k) {
            diag -= m_cholesky[j * d + k] * m_cholesky[j * d + k];
        }
        if (!(diag > 0.0)) {
            return false;
        }
        const double ljj = std::sqrt(diag);
        m_cholesky[j * d + j] = ljj;
        for (std::size_t i = j + 1; i < d; ++i) {
            double s = m_cholesky[i * d + j];
            for (std::size_t k = 0; k < j; ++k) {
                s -= m_cholesky[i * d + k] * m_cholesky[j * d + k];
            }
            m_cholesky[i * d + j] = s / ljj;
        }
    }
    return true;
}

template <class S>
void AggregationMultigrid<S>::solveCoarsest(const std::vector<Vec>& b, std::vector<Vec>& x) const {
    const std::size_t d = m_coarsestDim;
    std::vector<double>& y = m_coarseWork;
    y.resize(d);
    for (std::size_t i = 0; i < d; ++i) {
        const Vec& bi = b[i / 3];
        double s = double((i % 3 == 0) ? bi.x : (i % 3 == 1) ? bi.y : bi.z);
        for (std::size_t k = 0; k < i; ++k) {
            s -= m_cholesky[i * d + k] * y[k];
        }
        y[i] = s / m_cholesky[i * d + i];
    }
    for (std::size_t ii = d; ii-- > 0;) {
        double s = y[ii];
        for (std::size_t k = ii + 1; k < d; ++k) {
            s -= m_cholesky[k * d + ii] * y[k];
        }
        y[ii] = s / m_cholesky[ii * d + ii];
    }
    x.resize(d / 3);
    for (std::size_t i = 0; i < d / 3; ++i) {
        x[i] = {S(y[3 * i]), S(y[3 * i + 1]), S(y[3 * i + 2])};
    }
}

template <class S>
void AggregationMultigrid<S>::smoothColours(const BlockMatrix<S>& a, const std::vector<Mat>& dinv,
                                            const Colouring& colours, bool fromZero,
                                            const std::vector<Vec>& b, std::vector<Vec>& x,
                                            std::vector<Vec>* residual, WorkerPool& pool) const {
    // colour after colour, each colour's blocks at once, rows in order inside a block (forward: the first
    // sweep, as if from x = 0; backward: the exact reverse order, so the V-cycle stays symmetric). A block
    // reads other blocks of its colour nowhere, so any thread count gives the same bits.
    //
    // The forward sweep takes two blocks of a colour at once, a row of each in turn
    // (kernels::forwardRowPairFromZero: a sweep from zero waits on every row), when the colour has blocks
    // enough for every thread to get a pair; else one block at a time. Either gives the same bits: the
    // blocks of a colour read none of each other's rows.
    const std::size_t count = colours.start.size() - 1;
    const auto rowsOf = [&](std::uint32_t block) {
        const std::uint32_t begin = block * colours.rows;
        return kernels::RowRange{begin, std::min(a.n, begin + colours.rows)};
    };
    for (std::size_t k = 0; k < count; ++k) {
        const std::size_t c = fromZero ? k : count - 1 - k;
        const std::uint32_t first = colours.start[c], blocks = colours.start[c + 1] - first;
        const std::uint32_t perTask = fromZero && blocks >= 2 * std::uint32_t(pool.threads()) ? 2 : 1;
        pool.forEach((blocks + perTask - 1) / perTask, 1, [&](std::size_t task) {
            const std::uint32_t at = first + std::uint32_t(task) * perTask;
            const kernels::RowRange one = rowsOf(colours.blocks[at]);
            const kernels::RowRange other = perTask == 2 && at + 1 < first + blocks
                                                ? rowsOf(colours.blocks[at + 1])
                                                : kernels::RowRange{};
            if (fromZero) {
                // only the blocks of rows swept before a row count (x is not cleared: none other is read)
                kernels::forwardRowPairFromZero(a, dinv.data(), b.data(), x.data(), one, other,
                                                &colours.order);
                if (residual && c == count - 1) {
                    // the last colour's rows are swept after every row they read but those later in their
                    // own block: their residual is final here, while their blocks are still in the cache
                    for (const kernels::RowRange& rows : {one, other}) {
                        kernels::residualAfterForward(a, x.data(), residual->data(), rows.first, rows.end,
                                                      &colours.order);
                    }
                }
            } else {
                kernels::smoothRows(a, dinv.data(), b.data(), x.data(), one.first, one.end, false);
            }
        });
    }
}

template <class S>
void AggregationMultigrid<S>::cycle(std::size_t level, const std::vector<Vec>& b, std::vector<Vec>& x,
                                    WorkerPool& pool) {
    if (level == m_levels.size()) {
        solveCoarsest(b, x);
        return;
    }
    const BlockMatrix<S>& a = level == 0 ? *m_fine : m_levels[level - 1].a;
    const std::vector<Mat>& dinv = level == 0 ? m_fineDiagInverse : m_levels[level - 1].diagInverse;
    std::vector<Vec>& r = level == 0 ? m_fineResidual : m_levels[level - 1].r;
    Level& next = m_levels[level];
    x.resize(a.n);
    r.resize(a.n);
    auto rowChunks = [&](auto&& rows) {
        pool.forChunks(a.n, kShareRows, [&](std::size_t, std::size_t first, std::size_t end) {
            rows(std::uint32_t(first), std::uint32_t(end));
        });
    };
    const bool coloured = !m_colours[level].start.empty();
    if (coloured) {
        // forward by colour as if from x = 0, then the residual (the blocks of rows swept after a row only):
        // the last colour's as it is swept, the other colours' block by block after it
        const Colouring& colours = m_colours[level];
        smoothColours(a, dinv, colours, true, b, x, &r, pool);
        pool.forEach(colours.start[colours.start.size() - 2], 1, [&](std::size_t k) {
            const std::uint32_t first = colours.blocks[k] * colours.rows;
            kernels::residualAfterForward(a, x.data(), r.data(), first, std::min(a.n, first + colours.rows),
                                          &colours.order);
        });
    } else {
        // forward row after row as if from x = 0, then the residual (blocks right of the diagonal only)
        kernels::forwardRowsFromZero(a, dinv.data(), b.data(), x.data(), 0, a.n);
        rowChunks([&](std::uint32_t first, std::uint32_t end) {
            kernels::residualAfterForward(a, x.data(), r.data(), first, end);
        });
    }
    // restrict (each coarse row gathers its finer rows' residuals in ascending order), correct on the
    // coarser level, prolong, and sweep backwards, so that the V-cycle stays symmetric
    next.b.resize(next.a.n);
    pool.forEach(next.a.n, kShareRows, [&](std::size_t c) {
        Vec sum;
        for (std::uint32_t k = next.members.start[c]; k < next.members.start[c + 1]; ++k) {
            sum += r[next.members.items[k]];
        }
        next.b[c] = sum;
    });
    cycle(level + 1, next.b, next.x, pool);
    pool.forEach(a.n, kShareRows, [&](std::size_t i) { x[i] += next.x[next.group[i]]; });
    if (coloured) {
        smoothColours(a, dinv, m_colours[level], false, b, x, nullptr, pool);
    } else {
        kernels::smoothRows(a, dinv.data(), b.data(), x.data(), 0, a.n, false);
    }
}

template <class S>
void AggregationMultigrid<S>::apply(const std::vector<Vec>& r, std::vector<Vec>& z, WorkerPool& pool) {
    cycle(0, r, z, pool);
}

namespace {

/// Per chunk of rows, for the first guess: G(i, j) = s_i . A s_j over the remembered solutions s (the
/// upper triangle, i <= j) and c(i) = s_i . b, added chunk after chunk in chunk order.
struct GuessSums {
    static constexpr std::size_t kM = kGuessHistory;
    std::array<double, kM * kM + kM> v{};
    double& g(std::size_t i, std::size_t j) { return v[i * kM + j]; }
    double& c(std::size_t i) { return v[kM * kM + i]; }
    GuessSums& operator+=(const GuessSums& other) {
        for (std::size_t k = 0; k < v.size(); ++k) {
            v[k] += other.v[k];
        }
        return *this;
    }
};

/// The weights y of the remembered solutions that minimise the A-norm of the error, G y = c, by Cholesky in
/// double. A solution whose part independent of the newer ones has an A-norm below 1e-3 of its own (nearly
/// a combination of them: a cloth at rest repeats its solution) gets weight zero, which keeps the small
/// system well conditioned; every one does if a sum is not finite (a solution holding NaN or inf).
std::array<double, kGuessHistory> guessWeights(GuessSums& sums, std::size_t m) {
    constexpr std::size_t kM = kGuessHistory;
    constexpr double kIndependent = 1e-6; // of the squared A-norm
    std::array<double, kM> w{}, y{};
    for (std::size_t i = 0; i < m; ++i) {
        for (std::size_t j = i; j < m; ++j) {
            if (!std::isfinite(sums.g(i, j))) {
                return y;
            }
        }
        if (!std::isfinite(sums.c(i))) {
            return y;
        }
    }
    std::array<double, kM * kM> l{}; // lower factor of the kept rows and columns; zero elsewhere
    std::array<bool, kM> kept{};
    for (std::size_t j = 0; j < m; ++j) {
        double d = sums.g(j, j);
        for (std::size_t k = 0; k < j; ++k) {
            d -= l[j * kM + k] * l[j * kM + k];
        }
        kept[j] = d > kIndependent * sums.g(j, j);
        if (!kept[j]) {
            continue;
        }
        l[j * kM + j] = std::sqrt(d);
        for (std::size_t i = j + 1; i < m; ++i) {
            double t = sums.g(j, i); // the upper triangle holds G(j, i) = G(i, j)
            for (std::size_t k = 0; k < j; ++k) {
                t -= l[i * kM + k] * l[j * kM + k];
            }
            l[i * kM + j] = t / l[j * kM + j];
        }
    }
    for (std::size_t i = 0; i < m; ++i) {
        if (kept[i]) {
            double t = sums.c(i);
            for (std::size_t k = 0; k < i; ++k) {
                t -= l[i * kM + k] * w[k];
            }
            w[i] = t / l[i * kM + i];
        }
    }
    for (std::size_t i = m; i-- > 0;) {
        if (kept[i]) {
            double t = w[i];
            for (std::size_t k = i + 1; k < m; ++k) {
                t -= kept[k] ? l[k * kM + i] * y[k] : 0.0;
            }
            y[i] = t / l[i * kM + i];
        }
    }
    return y;
}

/// Remembers x (the last solution) and replaces it by the first guess that PcgVectors describes; sets
/// r = b - A x with the fixed rows of both zeroed, and returns |r|^2. The sums leave out the fixed rows (a
/// solution remembered before a mass was pinned may not be zero there; the filtered matrix's rows and
/// columns there are the identity, which would weigh it by a made-up unit mass). Weights too large for S
/// (a cloth at rest leaves solutions near S's smallest numbers) give the guess zero. Same bits at any
/// thread count: the sums are one partial per chunk of kDotRows rows, in chunk order.
template <class S>
double firstGuess(const BlockMatrix<S>& a, const std::vector<Vec3T<S>>& b, std::vector<Vec3T<S>>& x,
                  const std::vector<std::uint8_t>& fixed, PcgVectors<S>& work, WorkerPool& pool) {
    const std::size_t n = a.n;
    std::array<std::vector<Vec3T<S>>, kGuessHistory>& solutions = work.solutions;
    std::array<std::vector<Vec3T<S>>, kGuessHistory>& products = work.products;
    std::vector<Vec3T<S>>& r = work.r;
    if (work.remembered > 0 && solutions[0].size() != n) {
        work.remembered = 0; // another system: what was remembered does not apply
    }
    // the newest first; the oldest one's storage takes x
    std::rotate(solutions.begin(), solutions.end() - 1, solutions.end());
    solutions[0] = x;
    const std::size_t m = work.remembered = std::min(work.remembered + 1, kGuessHistory);
    for (std::size_t k = 0; k < m; ++k) {
        products[k].resize(n);
    }
    GuessSums sums = pool.sum(n, kDotRows, GuessSums{}, [&](std::size_t first, std::size_t end) {
        GuessSums part;
        for (std::size_t k = 0; k < m; ++k) {
            kernels::multiplyRows(a, solutions[k].data(), products[k].data(), std::uint32_t(first),
                                  std::uint32_t(end));
        }
        for (std::size_t i = 0; i < m; ++i) {
            for (std::size_t j = i; j < m; ++j) {
                part.g(i, j) = freeDot(solutions[i], products[j], fixed, first, end);
            }
            part.c(i) = freeDot(solutions[i], b, fixed, first, end);
        }
        return part;
    });
    // the solutions with a weight, and their weights in S (none if one is too large for S)
    std::array<std::size_t, kGuessHistory> used{};
    std::array<S, kGuessHistory> y{};
    std::size_t count = 0;
    const std::array<double, kGuessHistory> weights = guessWeights(sums, m);
    for (std::size_t k = 0; k < m; ++k) {
        const S weight = S(weights[k]);
        if (!std::isfinite(weight)) {
            count = 0;
            break;
        }
        if (weight != S(0)) {
            used[count] = k;
            y[count++] = weight;
        }
    }
    r.resize(n);
    return pool.sum(n, kDotRows, 0.0, [&](std::size_t first, std::size_t end) {
        for (std::size_t i = first; i < end; ++i) {
            Vec3T<S> xi, ri = b[i];
            for (std::size_t u = 0; u < count; ++u) {
                xi += solutions[used[u]][i] * y[u];
                ri -= products[used[u]][i] * y[u];
            }
            // a pinned row's column is zero off the diagonal: zeroing x there leaves the other rows' r as is
            x[i] = fixed[i] ? Vec3T<S>{} : xi;
            r[i] = fixed[i] ? Vec3T<S>{} : ri;
        }
        return dotRows(r, r, first, end);
    });
}

} // namespace

template <class S>
SolveStats solvePcg(const BlockMatrix<S>& a, const std::vector<Vec3T<S>>& b, std::vector<Vec3T<S>>& x,
                    AggregationMultigrid<S>& preconditioner, const std::vector<std::uint8_t>& fixed,
                    double tol, int maxIterations, PcgVectors<S>& work, WorkerPool& pool) {
    SolveStats stats;
    const std::size_t n = a.n;
    x.resize(n);
    filter(x, fixed);
    const double bnorm = std::sqrt(dotAll(b, b, pool));
    if (bnorm == 0.0) {
        std::fill(x.begin(), x.end(), Vec3T<S>{});
        stats.converged = true;
        return stats;
    }
    // named references, not a structured binding: clang 14 cannot capture a binding in a lambda
    std::vector<Vec3T<S>>& r = work.r;
    std::vector<Vec3T<S>>& z = work.z;
    std::vector<Vec3T<S>>& p = work.p;
    std::vector<Vec3T<S>>& ap = work.ap;
    ap.resize(n);
    double rnorm = std::sqrt(firstGuess(a, b, x, fixed, work, pool));
    preconditioner.apply(r, z, pool);
    double rz = filteredDot(r, z, fixed, pool);
    p = z;
    while (rnorm > tol * bnorm && stats.iterations < maxIterations) {
        // A p with the fixed rows zeroed, and p . A p, in one pass
        const double pap = pool.sum(n, kDotRows, 0.0, [&](std::size_t first, std::size_t end) {
            kernels::multiplyRows(a, p.data(), ap.data(), std::uint32_t(first), std::uint32_t(end));
            return filteredDot(p, ap, fixed, first, end);
        });
        if (!(pap > 0.0)) {
            break; // lost positive definiteness to round-off: keep what we have
        }
        const S alpha = S(rz / pap);
        // the update and the new residual's norm in one pass
        rnorm = std::sqrt(pool.sum(n, kDotRows, 0.0, [&](std::size_t first, std::size_t end) {
            double s = 0.0;
            for (std::size_t i = first; i < end; ++i) {
                x[i] += p[i] * alpha;
                r[i] -= ap[i] * alpha;
                s += double(r[i].x) * double(r[i].x) + double(r[i].y) * double(r[i].y) +
                     double(r[i].z) * double(r[i].z);
            }
            return s;
        }));
        ++stats.iterations;
        if (rnorm <= tol * bnorm) {
            break;
        }
        preconditioner.apply(r, z, pool);
        const double rzNext = filteredDot(r, z, fixed, pool);
        const S beta = S(rzNext / rz);
        rz = rzNext;
        pool.forChunks(n, kShareRows, [&](std::size_t, std::size_t first, std::size_t end) {
            for (std::size_t i = first; i < end; ++i) {
                p[i] = z[i] + p[i] * beta;
            }
        });
    }
    stats.relativeResidual = rnorm / bnorm;
    stats.converged = rnorm <= tol * bnorm;
    return stats;
}

template bool packSymmetric(BlockMatrix<float>&, WorkerPool&);
template bool packSymmetric(BlockMatrix<double>&, WorkerPool&);
template class AggregationMultigrid<float>;
template class AggregationMultigrid<double>;
template SolveStats solvePcg(const BlockMatrix<float>&, const std::vector<Vec3T<float>>&,
                             std::vector<Vec3T<float>>&, AggregationMultigrid<float>&,
                             const std::vector<std::uint8_t>&, double, int, PcgVectors<float>&, WorkerPool&);
template SolveStats solvePcg(const BlockMatrix<double>&, const std::vector<Vec3T<double>>&,
                             std::vector<Vec3T<double>>&, AggregationMultigrid<double>&,
                             const std::vector<std::uint8_t>&, double, int, PcgVectors<double>&, WorkerPool&);

} // namespace tumble
