#pragma once
// The row kernels of the implicit solver (linear_solver.h): products and Gauss-Seidel sweeps over the rows
// of a 3x3-block matrix. They are most of an implicit step's time (70% of the curtain's), so the float
// ones have an SSE2 and an AVX2 version, chosen at run time (engine/simd.h), that give the same bits.
//
// How the bits stay the same: a row's sum over its blocks is kept in two partial sums, the even-numbered
// blocks of the row in one and the odd-numbered ones in the other, added at the end (even + odd). AVX2
// holds the two partials in the two halves of one register and multiplies a pair of blocks at once; SSE2
// holds them in two registers and multiplies one block at a time; every lane sees the same operations in
// the same order (a block times a vector is (row0 x + row1 y) + row2 z, no fused multiply-add). The double
// versions keep the same order in plain code.

#include "systems/block_sparse.h"

#include <cstdint>
#include <vector>

namespace tumble::kernels {

/// y_i = sum_j A_ij x_j for the rows [first, end) (every block symmetric, as the solver's are).
template <class S>
void multiplyRows(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* y, std::uint32_t first,
                  std::uint32_t end);

/// Gauss-Seidel over the rows [first, end), in order (forward) or in reverse: x_i = D_i^-1 (b_i - sum_{j !=
/// i} A_ij x_j), each row seeing the rows updated before it. dinv holds the inverses of the diagonal blocks.
template <class S>
void smoothRows(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                std::uint32_t first, std::uint32_t end, bool forward);

/// Rows [first, end) of a sweep.
struct RowRange {
    std::uint32_t first = 0, end = 0;
    std::uint32_t size() const { return end - first; }
};

/// The order of a forward sweep that visits rows out of their numbering (colour by colour): each row's
/// off-diagonal blocks in two lists, those of rows swept before it, then those of rows swept after it,
/// each in column order. Row i's are items[first(i) .. split[i]) and items[split[i] .. first(i + 1)),
/// where first(i) = rowStart[i] - i (the off-diagonal blocks of the rows before it).
struct SweepOrder {
    std::vector<std::uint32_t> items, split;
};

/// The first forward Gauss-Seidel sweep, as if from x = 0, over the rows [first, end): x_i = D_i^-1 (b_i -
/// sum_{j before i} A_ij x_j), where the rows swept before i are those left of the diagonal, or those
/// `order` lists first (built for this matrix's pattern). The rows after i would hold zero and are not
/// read, so x need not be cleared: each x_i is written before any row reads it.
template <class S>
void forwardRowsFromZero(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                         std::uint32_t first, std::uint32_t end, const SweepOrder* order = nullptr);

/// forwardRowsFromZero over two ranges at once, a row of each in turn (the k-th row of one, then the k-th of
/// the other): for two ranges neither of which reads the other's rows of x (two blocks of one colour of a
/// coloured sweep), the bits of sweeping one after the other.
///
/// Why: a sweep from zero waits on each row's result before it can finish the next, so it runs at the
/// latency of a row, not at the rate its loads and arithmetic allow; rows of two independent ranges in
/// turn overlap those waits. Measured on a 100 x 100 cloth's matrix (AVX2, packed, rows in order): 12.2 ns
/// a row, or 8.3 with two ranges in turn (a product, twice the blocks and no waiting, 11.1); four ranges
/// in turn were slower again (9.6). A backward sweep, which reads every block of a row, was not faster
/// in turn (14.3 ns a row, 14.9 in turn): its loads and arithmetic already take longer than the wait.
template <class S>
void forwardRowPairFromZero(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                            RowRange one, RowRange other, const SweepOrder* order = nullptr);

/// The residual b - A x after forwardRowsFromZero swept every row, for the rows [first, end): since D_i x_i
/// = b_i - sum_{j before i} A_ij x_j, it is r_i = -sum_{j after i} A_ij x_j (the blocks right of the
/// diagonal, or as `order` lists them).
template <class S>
void residualAfterForward(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* r, std::uint32_t first,
                          std::uint32_t end, const SweepOrder* order = nullptr);

} // namespace tumble::kernels
