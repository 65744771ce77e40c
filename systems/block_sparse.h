#pragma once
// 3x3-block sparse matrices (block compressed rows) for the implicit spring solver. Each block couples the
// three coordinates of two masses, so the pattern is the network's link graph plus the diagonal; it is
// built once per network and every step only refills the values, in place, through indices the builder
// saved (no search, no allocation per step).
//
// Our own rather than Eigen's SparseMatrix: with a fixed 3x3 block pattern, assembly is a scatter into
// known slots and the multigrid preconditioner (linear_solver.h) needs the block structure; Eigen's
// triplet assembly + Jacobi CG, the plain way, measures 29 ms per 35 x 35 cloth step here (BASELINES.md).

#include "engine/math.h"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace tumble {

/// A 3x3 matrix, row-major.
struct Mat3 {
    std::array<double, 9> m{};

    static Mat3 identity(double s = 1.0) {
        Mat3 r;
        r.m[0] = r.m[4] = r.m[8] = s;
        return r;
    }
    /// s * a a^T
    static Mat3 outer(const Vec3& a, double s) {
        Mat3 r;
        const double c[3] = {a.x, a.y, a.z};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                r.m[std::size_t(3 * i + j)] = s * c[i] * c[j];
            }
        }
        return r;
    }
    Mat3& operator+=(const Mat3& o) {
        for (std::size_t i = 0; i < 9; ++i) {
            m[i] += o.m[i];
        }
        return *this;
    }
    Mat3& operator-=(const Mat3& o) {
        for (std::size_t i = 0; i < 9; ++i) {
            m[i] -= o.m[i];
        }
        return *this;
    }
    Vec3 operator*(const Vec3& v) const {
        return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                m[6] * v.x + m[7] * v.y + m[8] * v.z};
    }
    double trace() const { return m[0] + m[4] + m[8]; }
    /// The inverse (the matrix must be invertible; used on SPD diagonal blocks).
    Mat3 inverse() const;
};

/// A square sparse matrix of 3x3 blocks in block-compressed-row form.
struct BlockMatrix {
    std::uint32_t n = 0;                 ///< block rows (= masses)
    std::vector<std::uint32_t> rowStart; ///< n + 1 offsets into col / val
    std::vector<std::uint32_t> col;      ///< block column of each stored block, ascending within a row
    std::vector<std::uint32_t> diag;     ///< index of the diagonal block of each row
    std::vector<Mat3> val;               ///< the blocks

    /// The pattern with the diagonal and both (i, j) and (j, i) for every pair; values zero.
    static BlockMatrix fromPairs(std::uint32_t n, std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs);

    /// Index of block (i, j); the block must be in the pattern.
    std::uint32_t find(std::uint32_t i, std::uint32_t j) const;
    void setZero();
    /// y = A x
    void multiply(const std::vector<Vec3>& x, std::vector<Vec3>& y) const;
};

} // namespace tumble
