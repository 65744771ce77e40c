#pragma once
// 3x3-block sparse matrices (block compressed rows) for the implicit spring solver. Each block couples the
// three coordinates of two masses, so the pattern is the network's link graph plus the diagonal; it is
// built once per network and every step only refills the values, in place, through indices the builder
// saved (no search, no allocation per step).
//
// Templated on the scalar: the solver runs in float by default (half the memory traffic of double, which
// is what its kernels are bound by; the solve only needs a relative residual of 1e-3), or in double when a
// scene asks for tight tolerances.
//
// Our own rather than Eigen's SparseMatrix: with a fixed 3x3 block pattern, assembly is a scatter into
// known slots and the multigrid preconditioner (linear_solver.h) needs the block structure; Eigen's
// triplet assembly + Jacobi CG, the plain way, measures 29 ms per 35 x 35 cloth step here (BASELINES.md).

#include "engine/math.h"

#include <emmintrin.h>

#include <array>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <vector>

namespace tumble {

/// A 3-vector of the solver's scalar.
template <class S>
struct Vec3T {
    S x{}, y{}, z{};

    Vec3T& operator+=(const Vec3T& o) {
        x += o.x;
        y += o.y;
        z += o.z;
        return *this;
    }
    Vec3T& operator-=(const Vec3T& o) {
        x -= o.x;
        y -= o.y;
        z -= o.z;
        return *this;
    }
    friend Vec3T operator+(Vec3T a, const Vec3T& b) { return a += b; }
    friend Vec3T operator-(Vec3T a, const Vec3T& b) { return a -= b; }
    friend Vec3T operator*(const Vec3T& a, S s) { return {a.x * s, a.y * s, a.z * s}; }
    friend S dot(const Vec3T& a, const Vec3T& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

    static Vec3T from(const Vec3& v) { return {S(v.x), S(v.y), S(v.z)}; }
    Vec3 toVec3() const { return {double(x), double(y), double(z)}; }
};

/// The float vector is padded to 16 bytes (the fourth lane is always zero), so the solver's kernels work on
/// it with one SSE register (SSE2 is in every x86-64 CPU, so this needs no -march and runs the same
/// instructions, and so gives the same bits, everywhere).
template <>
struct alignas(16) Vec3T<float> {
    float x{}, y{}, z{}, pad{};

    Vec3T() = default;
    Vec3T(float ax, float ay, float az) : x(ax), y(ay), z(az) {}
    explicit Vec3T(__m128 v) { _mm_store_ps(&x, v); }
    __m128 simd() const { return _mm_load_ps(&x); }

    Vec3T& operator+=(const Vec3T& o) {
        _mm_store_ps(&x, _mm_add_ps(simd(), o.simd()));
        return *this;
    }
    Vec3T& operator-=(const Vec3T& o) {
        _mm_store_ps(&x, _mm_sub_ps(simd(), o.simd()));
        return *this;
    }
    friend Vec3T operator+(Vec3T a, const Vec3T& b) { return a += b; }
    friend Vec3T operator-(Vec3T a, const Vec3T& b) { return a -= b; }
    friend Vec3T operator*(const Vec3T& a, float s) { return Vec3T(_mm_mul_ps(a.simd(), _mm_set1_ps(s))); }
    friend float dot(const Vec3T& a, const Vec3T& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

    static Vec3T from(const Vec3& v) { return {float(v.x), float(v.y), float(v.z)}; }
    Vec3 toVec3() const { return {double(x), double(y), double(z)}; }
};
static_assert(sizeof(Vec3T<float>) == 16);

/// A 3x3 matrix, row-major.
template <class S>
struct Mat3T {
    /// row-major, unpadded: a float block is 36 bytes, and the SSE kernels load its last row from the sixth
    /// entry (lastRow), not past the ninth
    std::array<S, 9> m{};

    static Mat3T identity(S s = S(1)) {
        Mat3T r;
        r.m[0] = r.m[4] = r.m[8] = s;
        return r;
    }
    /// s * a a^T
    static Mat3T outer(const Vec3& a, double s) {
        Mat3T r;
        const double c[3] = {a.x, a.y, a.z};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                r.m[std::size_t(3 * i + j)] = S(c[i] * c[j] * s); // c_i c_j first: bit-symmetric
            }
        }
        return r;
    }
    Mat3T& operator+=(const Mat3T& o) {
        for (std::size_t i = 0; i < 9; ++i) {
            m[i] += o.m[i];
        }
        return *this;
    }
    Mat3T& operator-=(const Mat3T& o) {
        for (std::size_t i = 0; i < 9; ++i) {
            m[i] -= o.m[i];
        }
        return *this;
    }
    /// The same matrix in another scalar.
    template <class T>
    Mat3T<T> cast() const {
        Mat3T<T> r;
        for (std::size_t i = 0; i < 9; ++i) {
            r.m[i] = T(m[i]);
        }
        return r;
    }
    template <class V>
    V operator*(const V& v) const {
        return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                m[6] * v.x + m[7] * v.y + m[8] * v.z};
    }
    S trace() const { return m[0] + m[4] + m[8]; }
    Mat3T transposed() const {
        Mat3T r;
        for (std::size_t i = 0; i < 3; ++i) {
            for (std::size_t j = 0; j < 3; ++j) {
                r.m[3 * i + j] = m[3 * j + i];
            }
        }
        return r;
    }
    /// The inverse (the matrix must be invertible; used on SPD diagonal blocks).
    Mat3T inverse() const;
};

/// The double-precision 3x3 matrix of force Jacobians.
using Mat3 = Mat3T<double>;

/// A v for a symmetric A (every block of the solver's matrices is symmetric: see linear_solver.h).
template <class S>
inline Vec3T<S> symmetricTimes(const Mat3T<S>& a, const Vec3T<S>& v) {
    return a * v;
}

/// The third row of a float block in lanes 0-2 (lane 3: m[5]), loaded without reading past the block.
inline __m128 lastRow(const Mat3T<float>& a) {
    const __m128 t = _mm_loadu_ps(&a.m[5]);
    return _mm_shuffle_ps(t, t, 0x39);
}

/// The float version: rows of a symmetric block are its columns, so A v = row0 v.x + row1 v.y + row2 v.z,
/// three broadcasts, three multiplies and two adds on SSE registers; the fourth lane is cleared.
template <>
inline Vec3T<float> symmetricTimes(const Mat3T<float>& a, const Vec3T<float>& v) {
    const __m128 xv = v.simd();
    __m128 r = _mm_mul_ps(_mm_loadu_ps(&a.m[0]), _mm_shuffle_ps(xv, xv, 0x00));
    r = _mm_add_ps(r, _mm_mul_ps(_mm_loadu_ps(&a.m[3]), _mm_shuffle_ps(xv, xv, 0x55)));
    r = _mm_add_ps(r, _mm_mul_ps(lastRow(a), _mm_shuffle_ps(xv, xv, 0xaa)));
    const __m128 keepXyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
    return Vec3T<float>(_mm_and_ps(r, keepXyz));
}

/// A square sparse matrix of 3x3 blocks in block-compressed-row form.
template <class S>
struct BlockMatrix {
    std::uint32_t n = 0;                 ///< block rows (= masses)
    std::vector<std::uint32_t> rowStart; ///< n + 1 offsets into col / val
    std::vector<std::uint32_t> col;      ///< block column of each stored block, ascending within a row
    std::vector<std::uint32_t> diag;     ///< index of the diagonal block of each row
    std::vector<Mat3T<S>> val;           ///< the blocks
    /// When every block is symmetric, their upper triangles (m00 m01 m02 m11 m12 m22), six scalars a block:
    /// the float kernels read these instead of val (24 bytes a block instead of 36; the sweeps over a large
    /// cloth's matrix go as the bytes they read). packSymmetric (linear_solver.h) fills them from val;
    /// whoever then changes val must pack again or clear them.
    std::vector<S> packed;

    /// Whether `packed` holds every block's upper triangle.
    bool isPacked() const { return !val.empty() && packed.size() == 6 * val.size(); }

    /// The pattern with the diagonal and both (i, j) and (j, i) for every pair; values zero.
    static BlockMatrix fromPairs(std::uint32_t n, std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs);

    /// Index of block (i, j); the block must be in the pattern.
    std::uint32_t find(std::uint32_t i, std::uint32_t j) const;
    void setZero();
    /// y = A x, for a matrix whose blocks are all symmetric (the solver's are); a range of rows:
    /// kernels::multiplyRows (block_kernels.h)
    void multiply(const std::vector<Vec3T<S>>& x, std::vector<Vec3T<S>>& y) const;
    /// The off-diagonal blocks in the rows of the fixed rows and in their columns, each (i, j) followed by
    /// its (j, i): what constraint filtering clears (a fixed row's diagonal becomes the identity).
    std::vector<std::uint32_t> fixedBlocks(const std::vector<std::uint8_t>& fixed) const {
        std::vector<std::uint32_t> out;
        for (std::uint32_t i = 0; i < n; ++i) {
            if (!fixed[i]) {
                continue;
            }
            for (std::uint32_t b = rowStart[i]; b < rowStart[std::size_t(i) + 1]; ++b) {
                if (col[b] != i) {
                    out.push_back(b);
                    out.push_back(find(col[b], i));
                }
            }
        }
        return out;
    }
};

extern template struct Mat3T<float>;
extern template struct Mat3T<double>;
extern template struct BlockMatrix<float>;
extern template struct BlockMatrix<double>;

} // namespace tumble
