#pragma once
// The linear solver of implicit Euler: preconditioned conjugate gradients on the symmetric positive
// definite system (M - h dF/dv - h^2 dF/dx) dv = b, with an aggregation multigrid V-cycle as the
// preconditioner.
//
// Why multigrid: what decides the cost is the number of CG iterations. Block-Jacobi with a warm start needs
// about 83 iterations on the 35 x 35 curtain and 198 on a 100 x 100 cloth (they grow with the grid's
// size); a multigrid preconditioner holds them near 10 at any size (BASELINES.md measured both).
//
// The hierarchy: masses are grouped by double pairwise matching along the strongest couplings (each level
// about 4 times smaller), the prolongation is piecewise constant over a group, and every coarse operator
// is the Galerkin product P^T A P, which for such a P is a plain sum of fine blocks into coarse slots. The
// groups and the coarse patterns are chosen once, from the first matrix, and reused; each step only
// re-sums the values. Smoothing is block Gauss-Seidel, forward before the coarse correction and backward
// after, so the V-cycle is symmetric as CG requires; the coarsest level is solved exactly (dense Cholesky).
// The row kernels (products and sweeps) are in block_kernels.h, in SSE2 and AVX2 with the same bits.
//
// Why the rows stay in their own order: numbering a level colour by colour (multicolour Gauss-Seidel, every
// row of a colour at once) was tried and took 20% more iterations on a 100 x 100 cloth (23 -> 28, and 40
// when the pairing also visited rows in colour order), which ate what the sweeps gained; so large levels
// are coloured by blocks of consecutive rows instead (kSmoothBlock, or an eighth of the level if fewer),
// which keeps nearly the convergence of sweeping row after row.
//
// Why the prolongation stays piecewise constant and unsmoothed (measured on the systems of the curtain and of
// a 100 x 100 cloth after 120 frames, in a double-precision prototype, CG from zero to 1e-3): smoothed
// aggregation (P = (I - w D^-1 A) P0) over 3 x 3 patches took the 100 x 100 from 18 iterations to 11, but its
// coarse operators are denser, so a solve still read 49 fine-matrix passes against 67, and forming
// P^T A P anew each step costs 20-25 passes against 1.5 for the block sums here. Rotations in the tentative
// prolongator (6 unknowns an aggregate) cut a two-grid method's iterations from 11 to 7, which the
// unsmoothed coarse levels of a V-cycle lose again (16-19); smoothed as well, the coarse operators grow to
// 0.6-2.7 times the fine one. Nor did leaving the weak couplings out of the fine level's sweeps pay: a
// cloth's bend springs are a third of its blocks and couple 100 times more weakly than its stretch springs
// (|A_ij| / sqrt(|A_ii| |A_jj|) 0.003-0.005 against 0.3-0.5), yet the solver sweeping without them took
// 16.2 iterations a step instead of 15.2 on the 100 x 100 and no less time (the sweeps did not go as the
// blocks they read: a forward sweep from zero, row after row, read half the blocks of a product and took
// about as long; it waits on each row, which kernels::forwardRowPairFromZero has since overlapped).
//
// How blocks are read: the kernels apply a stored block's rows as its columns (A v = row0 v.x + row1 v.y +
// row2 v.z, three broadcasts), and so does the dense factor of the coarsest level. For the springs it makes
// no difference: every block is symmetric (a spring's h kd uu^T + h^2 K, the mass and damping diagonal,
// and their sums). An fem body's off-diagonal blocks are not (systems/fem.h): it stores at (i, j) the
// transpose of A_ij, which the matrix's symmetry makes A_ji, so that read as columns it applies A_ij; sums
// of such blocks (the Galerkin products) keep the convention. The double kernels (plain Mat3T products)
// read rows as rows, so an fem body solves in float only.

#include "engine/parallel.h"
#include "systems/block_kernels.h"
#include "systems/block_sparse.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

namespace tumble {

/// The numbers of a step admit no solution (a matrix that is not positive definite): the physics diverged
/// or was set up so that it must. A spring network that throws it is frozen as a blow-up; any other
/// exception from a system is a programming error and ends the run.
struct SolverError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// A multigrid V-cycle over a BlockMatrix; see the header comment.
template <class S>
class AggregationMultigrid {
public:
    using Vec = Vec3T<S>;
    using Mat = Mat3T<S>;

    /// Prepares for a new matrix value set (same pattern as the first call, which also builds the levels).
    void update(const BlockMatrix<S>& a, WorkerPool& pool = serialPool());
    /// z = one V-cycle applied to r (an approximation of A^-1 r). Levels of kColouredRows rows or more
    /// smooth colour by colour, each colour's blocks of rows shared out over the pool's threads.
    void apply(const std::vector<Vec>& r, std::vector<Vec>& z, WorkerPool& pool = serialPool());
    /// Colours of a level's smoother (0 for a level smoothed row after row).
    std::size_t colours(std::size_t level) const {
        return level < m_colours.size() && !m_colours[level].start.empty() ? m_colours[level].start.size() - 1
                                                                           : 0;
    }
    /// Number of levels, the finest included.
    std::size_t levels() const { return m_levels.size() + 1; }
    /// Rows and stored blocks of a coarse level (1 = the first coarse one).
    std::pair<std::uint32_t, std::size_t> levelSize(std::size_t level) const {
        return {m_levels[level - 1].a.n, m_levels[level - 1].a.col.size()};
    }
    /// Whether a coarse level's blocks are packed (BlockMatrix::packed; 1 = the first coarse one).
    bool levelPacked(std::size_t level) const { return m_levels[level - 1].a.isPacked(); }

private:
    /// Lists in compressed-row form: the entries of item i are items[start[i] .. start[i + 1]).
    struct Lists {
        std::vector<std::uint32_t> start, items;
    };
    struct Level {
        BlockMatrix<S> a;                 ///< the Galerkin operator of this level
        std::vector<std::uint32_t> group; ///< finer row -> row of this level
        Lists members;                    ///< row of this level -> its finer rows, ascending
        Lists sources;                ///< block of this level -> the finer blocks summed into it, ascending
        std::vector<Mat> diagInverse; ///< of this level's diagonal blocks (for the smoother)
        std::vector<Vec> x, b, r;     ///< work vectors
    };

    /// The level's rows cut into blocks of `rows` consecutive rows, the blocks grouped by colour: no two
    /// blocks of a colour share a matrix block, so a colour's blocks can be smoothed at once, each row
    /// after row inside. blocks[start[c] .. start[c + 1]) are colour c's, in order; `order` lists each
    /// row's blocks as the forward sweep meets them (for the sweep from zero and the residual after it).
    struct Colouring {
        std::uint32_t rows = 0;
        std::vector<std::uint32_t> start, blocks;
        kernels::SweepOrder order;
    };

    void build(const BlockMatrix<S>& fine);
    /// The first forward sweep, as if from x = 0 (fromZero), or a backward sweep from x as it is, colour by
    /// colour; a forward one given `residual` also forms the residual b - A x of the last colour's rows there
    /// (kernels::residualAfterForward), the other rows' being left to the caller.
    void smoothColours(const BlockMatrix<S>& a, const std::vector<Mat>& dinv, const Colouring& colours,
                       bool fromZero, const std::vector<Vec>& b, std::vector<Vec>& x,
                       std::vector<Vec>* residual, WorkerPool& pool) const;
    void cycle(std::size_t level, const std::vector<Vec>& b, std::vector<Vec>& x, WorkerPool& pool);
    void factorCoarsest();
    bool factorDense(std::size_t dim, double shift);
    void solveCoarsest(const std::vector<Vec>& b, std::vector<Vec>& x) const;

    const BlockMatrix<S>* m_fine = nullptr;
    std::vector<Mat> m_fineDiagInverse;
    std::vector<Level> m_levels;      ///< coarser and coarser; the last is solved directly
    std::vector<Colouring> m_colours; ///< per smoothed level (0: the fine one); empty: row after row
    std::vector<double> m_cholesky;   ///< dense lower factor of the coarsest operator (or of the fine one)
    std::vector<double> m_dense;      ///< the coarsest operator before factorisation (for a shifted retry)
    mutable std::vector<double> m_coarseWork;
    std::size_t m_coarsestDim = 0;
    bool m_built = false;
    std::vector<Vec> m_fineResidual;
};

/// Solutions a solve remembers for the next one's first guess (see PcgVectors).
constexpr std::size_t kGuessHistory = 3;

/// The work vectors of a conjugate-gradient solve, kept between steps so a step allocates nothing, and the
/// last solutions, from which the next solve starts.
///
/// The first guess: of the x given (the last step's solution, the warm start) and the solutions of the
/// kGuessHistory - 1 solves before it, the combination nearest the new solution in the A-norm, which is
/// found from their products with the new A alone (a Galerkin projection onto their span; Fischer 1998,
/// "Projection techniques for iterative solution of Ax = b with successive right-hand sides"). It costs
/// kGuessHistory products, taken together chunk by chunk of rows (the warm start paid one), and it is no
/// further from the solution in the A-norm than the plain warm start, which is one of the combinations (up
/// to rounding). Measured over 300 steps after 120 frames (60 for the 100 x 100): the curtain's CG
/// iterations 8.28 -> 7.13 a step, a 100 x 100 cloth's 16.5 -> 14.6. Two solutions remembered gave 7.10 and
/// 15.9, four 7.00 and 14.4 for a fourth product: three for the larger cloths.
template <class S>
struct PcgVectors {
    std::vector<Vec3T<S>> r, z, p, ap;
    /// the remembered solutions, the newest first, and their products with the current matrix
    std::array<std::vector<Vec3T<S>>, kGuessHistory> solutions, products;
    std::size_t remembered = 0;
};

/// Result of a conjugate-gradient solve.
struct SolveStats {
    int iterations = 0;
    double relativeResidual = 0.0; ///< |b - A x| / |b| at the end
    bool converged = false;
    bool solvedAgain = false; ///< an fem body's step: solved a second time, resting contacts let go
};

/// Solves A x = b by preconditioned CG, from the first guess that PcgVectors describes (x given is the
/// last solution; a size other than the remembered ones' starts the history again). Rows with `fixed` set are
/// held at zero (constraint filtering: their residual and search direction are zeroed). Stops when |r| <= tol
/// |b| or after maxIterations. The products, updates and dot products share out over the pool's threads, and
/// so do the V-cycle's residuals, restrictions, Galerkin sums and the sweeps of its coloured levels; a dot
/// product adds one partial per chunk of kDotRows rows in chunk order, so any thread count gives the same
/// bits.
template <class S>
SolveStats solvePcg(const BlockMatrix<S>& a, const std::vector<Vec3T<S>>& b, std::vector<Vec3T<S>>& x,
                    AggregationMultigrid<S>& preconditioner, const std::vector<std::uint8_t>& fixed,
                    double tol, int maxIterations, PcgVectors<S>& work, WorkerPool& pool = serialPool());

/// Fills a.packed (BlockMatrix::packed) from a.val when a has kPackedRows rows or more and every block is
/// symmetric to the bit (the springs' are: sums of h kd u u^T + h^2 K and diagonal terms, each entry
/// formed as its mirror is), else clears it; says which. Packed or not, the kernels give the same bits.
/// The spring integrator packs its matrix each step; an fem body never does (its blocks are not
/// symmetric). A multigrid over a packed matrix packs its coarse levels of kPackedRows rows or more too
/// (AggregationMultigrid::update).
template <class S>
bool packSymmetric(BlockMatrix<S>& a, WorkerPool& pool = serialPool());
/// Matrices smaller than this stay unpacked (small networks, the multigrid's small coarse levels: the
/// packing pass is not worth its fork-join there). Measured packed against stored, alternating: the
/// curtain's 1225 rows 2-3% faster a step (its matrix is in L2, where the shuffles that rebuild a packed
/// block's rows cost nearly what the bytes save), a 100 x 100 cloth's 10,000 rows 6-7%.
constexpr std::uint32_t kPackedRows = 1024;

/// Rows per chunk of the solver's dot products (a system this small or smaller sums in plain index order)
/// and of the passes that compute a product or update vectors as they sum (the other loops share out in
/// smaller chunks, which change no bit).
constexpr std::size_t kDotRows = 512;
/// A multigrid level of this many rows or more is smoothed by multicolour block Gauss-Seidel (blocks of
/// kSmoothBlock rows, or an eighth of the level if fewer; a colour's blocks shared out over threads, rows
/// in order inside a block); a smaller one row after row, as one block.
constexpr std::uint32_t kColouredRows = 1024;
constexpr std::uint32_t kSmoothBlock = 256;

extern template class AggregationMultigrid<float>;
extern template class AggregationMultigrid<double>;

} // namespace tumble
