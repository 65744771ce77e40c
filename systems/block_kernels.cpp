#include "systems/block_kernels.h"

#include "engine/simd.h"

#include <immintrin.h>

#include <algorithm>
#include <cassert>

namespace tumble::kernels {

namespace {

/// The blocks of one row as up to two ranges of block indices, [b0, e0) then [b1, e1) (a row without its
/// diagonal block is two ranges); k-th block of the row in order: at(k).
struct RowBlocks {
    std::uint32_t b0, e0, b1, e1;

    std::uint32_t count() const { return (e0 - b0) + (e1 - b1); }
    std::uint32_t at(std::uint32_t k) const { return k < e0 - b0 ? b0 + k : b1 + (k - (e0 - b0)); }
};

/// The blocks of one row as a list of block indices (a level swept colour by colour: SweepOrder).
struct ListedBlocks {
    const std::uint32_t* items;
    std::uint32_t n;

    std::uint32_t count() const { return n; }
    std::uint32_t at(std::uint32_t k) const { return items[k]; }
};

/// The blocks a forward sweep from zero reads for row i (those of rows swept before it) and those the
/// residual after it reads (the rest): left and right of the diagonal in row order, else as listed.
template <class S>
struct BeforeBlocks {
    const BlockMatrix<S>& a;
    RowBlocks operator()(std::uint32_t i) const { return {a.rowStart[i], a.diag[i], 0, 0}; }
};
template <class S>
struct AfterBlocks {
    const BlockMatrix<S>& a;
    RowBlocks operator()(std::uint32_t i) const {
        return {a.diag[i] + 1, a.rowStart[std::size_t(i) + 1], 0, 0};
    }
};
struct ListedBefore {
    const std::uint32_t* rowStart;
    const SweepOrder& order;
    ListedBlocks operator()(std::uint32_t i) const {
        const std::uint32_t first = rowStart[i] - i;
        return {order.items.data() + first, order.split[i] - first};
    }
};
struct ListedAfter {
    const std::uint32_t* rowStart;
    const SweepOrder& order;
    ListedBlocks operator()(std::uint32_t i) const {
        const std::uint32_t end = rowStart[std::size_t(i) + 1] - (i + 1);
        return {order.items.data() + order.split[i], end - order.split[i]};
    }
};

template <class S>
RowBlocks wholeRow(const BlockMatrix<S>& a, std::uint32_t i) {
    return {a.rowStart[i], a.rowStart[std::size_t(i) + 1], 0, 0};
}
template <class S>
RowBlocks offDiagonal(const BlockMatrix<S>& a, std::uint32_t i) {
    return {a.rowStart[i], a.diag[i], a.diag[i] + 1, a.rowStart[std::size_t(i) + 1]};
}

// ---- double (and any scalar): plain code, the same order ----

template <class S, class Row>
Vec3T<S> rowSum(const BlockMatrix<S>& a, const Vec3T<S>* x, const Row& row) {
    Vec3T<S> even, odd;
    const std::uint32_t count = row.count();
    std::uint32_t k = 0;
    for (; k + 1 < count; k += 2) {
        const std::uint32_t p = row.at(k), q = row.at(k + 1);
        even += symmetricTimes(a.val[p], x[a.col[p]]);
        odd += symmetricTimes(a.val[q], x[a.col[q]]);
    }
    if (k < count) {
        const std::uint32_t p = row.at(k);
        even += symmetricTimes(a.val[p], x[a.col[p]]);
    }
    return even + odd;
}

template <class S>
void multiplyPlain(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* y, std::uint32_t first,
                   std::uint32_t end) {
    for (std::uint32_t i = first; i < end; ++i) {
        y[i] = rowSum(a, x, wholeRow(a, i));
    }
}

template <class S>
void smoothPlain(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                 std::uint32_t first, std::uint32_t end, bool forward) {
    for (std::uint32_t k = first; k < end; ++k) {
        const std::uint32_t i = forward ? k : end - 1 - (k - first);
        x[i] = symmetricTimes(dinv[i], b[i] - rowSum(a, x, offDiagonal(a, i)));
    }
}

template <class S, class Rows>
void forwardPlain(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                  std::uint32_t first, std::uint32_t end, Rows before) {
    for (std::uint32_t i = first; i < end; ++i) {
        x[i] = symmetricTimes(dinv[i], b[i] - rowSum(a, x, before(i)));
    }
}

template <class S, class Rows>
void residualPlain(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* r, std::uint32_t first,
                   std::uint32_t end, Rows after) {
    for (std::uint32_t i = first; i < end; ++i) {
        r[i] = Vec3T<S>{} - rowSum(a, x, after(i));
    }
}

// ---- float, SSE2: one block at a time, the two partials in two registers ----

const __m128 kKeepXyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));

/// A v for a symmetric block (its rows are its columns): (row0 v.x + row1 v.y) + row2 v.z; the fourth lane
/// is left as it falls (the callers clear it).
inline __m128 blockTimes(const Mat3T<float>& m, __m128 v) {
    __m128 r = _mm_mul_ps(_mm_loadu_ps(&m.m[0]), _mm_shuffle_ps(v, v, 0x00));
    r = _mm_add_ps(r, _mm_mul_ps(_mm_loadu_ps(&m.m[3]), _mm_shuffle_ps(v, v, 0x55)));
    return _mm_add_ps(r, _mm_mul_ps(lastRow(m), _mm_shuffle_ps(v, v, 0xaa)));
}

template <class Row>
inline __m128 rowSumSse2(const BlockMatrix<float>& a, const Vec3T<float>* x, const Row& row) {
    __m128 even = _mm_setzero_ps(), odd = _mm_setzero_ps();
    const std::uint32_t count = row.count();
    std::uint32_t k = 0;
    for (; k + 1 < count; k += 2) {
        const std::uint32_t p = row.at(k), q = row.at(k + 1);
        even = _mm_add_ps(even, blockTimes(a.val[p], x[a.col[p]].simd()));
        odd = _mm_add_ps(odd, blockTimes(a.val[q], x[a.col[q]].simd()));
    }
    if (k < count) {
        const std::uint32_t p = row.at(k);
        even = _mm_add_ps(even, blockTimes(a.val[p], x[a.col[p]].simd()));
    }
    return _mm_add_ps(even, odd);
}

void multiplySse2(const BlockMatrix<float>& a, const Vec3T<float>* x, Vec3T<float>* y, std::uint32_t first,
                  std::uint32_t end) {
    for (std::uint32_t i = first; i < end; ++i) {
        y[i] = Vec3T<float>(_mm_and_ps(rowSumSse2(a, x, wholeRow(a, i)), kKeepXyz));
    }
}

void smoothSse2(const BlockMatrix<float>& a, const Mat3T<float>* dinv, const Vec3T<float>* b, Vec3T<float>* x,
                std::uint32_t first, std::uint32_t end, bool forward) {
    for (std::uint32_t k = first; k < end; ++k) {
        const std::uint32_t i = forward ? k : end - 1 - (k - first);
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumSse2(a, x, offDiagonal(a, i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

template <class Rows>
void forwardSse2(const BlockMatrix<float>& a, const Mat3T<float>* dinv, const Vec3T<float>* b,
                 Vec3T<float>* x, std::uint32_t first, std::uint32_t end, Rows before) {
    for (std::uint32_t i = first; i < end; ++i) {
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumSse2(a, x, before(i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

template <class Rows>
void residualSse2(const BlockMatrix<float>& a, const Vec3T<float>* x, Vec3T<float>* r, std::uint32_t first,
                  std::uint32_t end, Rows after) {
    for (std::uint32_t i = first; i < end; ++i) {
        r[i] = Vec3T<float>(_mm_and_ps(_mm_sub_ps(_mm_setzero_ps(), rowSumSse2(a, x, after(i))), kKeepXyz));
    }
}

// ---- float, AVX2: a pair of blocks at a time, the two partials in the halves of one register ----

#define TUMBLE_AVX2 __attribute__((target("avx2")))

/// Two 16-byte halves in one register: lo in lanes 0-3, hi in lanes 4-7.
TUMBLE_AVX2 inline __m256 halves(__m128 lo, __m128 hi) {
    return _mm256_insertf128_ps(_mm256_castps128_ps256(lo), hi, 1);
}

/// blockTimes of two blocks at once: p with the low half of v, q with the high half.
TUMBLE_AVX2 inline __m256 pairTimes(const Mat3T<float>& p, const Mat3T<float>& q, __m256 v) {
    const __m256 row0 = halves(_mm_loadu_ps(&p.m[0]), _mm_loadu_ps(&q.m[0]));
    const __m256 row1 = halves(_mm_loadu_ps(&p.m[3]), _mm_loadu_ps(&q.m[3]));
    const __m256 row2 = _mm256_permute_ps(halves(_mm_loadu_ps(&p.m[5]), _mm_loadu_ps(&q.m[5])), 0x39);
    __m256 r = _mm256_mul_ps(row0, _mm256_permute_ps(v, 0x00));
    r = _mm256_add_ps(r, _mm256_mul_ps(row1, _mm256_permute_ps(v, 0x55)));
    return _mm256_add_ps(r, _mm256_mul_ps(row2, _mm256_permute_ps(v, 0xaa)));
}

template <class Row>
TUMBLE_AVX2 inline __m128 rowSumAvx2(const BlockMatrix<float>& a, const Vec3T<float>* x, const Row& row) {
    __m256 both = _mm256_setzero_ps();
    const std::uint32_t count = row.count();
    std::uint32_t k = 0;
    for (; k + 1 < count; k += 2) {
        const std::uint32_t p = row.at(k), q = row.at(k + 1);
        both = _mm256_add_ps(both,
                             pairTimes(a.val[p], a.val[q], halves(x[a.col[p]].simd(), x[a.col[q]].simd())));
    }
    __m128 even = _mm256_castps256_ps128(both);
    const __m128 odd = _mm256_extractf128_ps(both, 1);
    if (k < count) {
        const std::uint32_t p = row.at(k);
        even = _mm_add_ps(even, blockTimes(a.val[p], x[a.col[p]].simd()));
    }
    return _mm_add_ps(even, odd);
}

TUMBLE_AVX2 void multiplyAvx2(const BlockMatrix<float>& a, const Vec3T<float>* x, Vec3T<float>* y,
                              std::uint32_t first, std::uint32_t end) {
    for (std::uint32_t i = first; i < end; ++i) {
        y[i] = Vec3T<float>(_mm_and_ps(rowSumAvx2(a, x, wholeRow(a, i)), kKeepXyz));
    }
}

TUMBLE_AVX2 void smoothAvx2(const BlockMatrix<float>& a, const Mat3T<float>* dinv, const Vec3T<float>* b,
                            Vec3T<float>* x, std::uint32_t first, std::uint32_t end, bool forward) {
    for (std::uint32_t k = first; k < end; ++k) {
        const std::uint32_t i = forward ? k : end - 1 - (k - first);
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumAvx2(a, x, offDiagonal(a, i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

template <class Rows>
TUMBLE_AVX2 void forwardAvx2(const BlockMatrix<float>& a, const Mat3T<float>* dinv, const Vec3T<float>* b,
                             Vec3T<float>* x, std::uint32_t first, std::uint32_t end, Rows before) {
    for (std::uint32_t i = first; i < end; ++i) {
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumAvx2(a, x, before(i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

template <class Rows>
TUMBLE_AVX2 void residualAvx2(const BlockMatrix<float>& a, const Vec3T<float>* x, Vec3T<float>* r,
                              std::uint32_t first, std::uint32_t end, Rows after) {
    for (std::uint32_t i = first; i < end; ++i) {
        r[i] = Vec3T<float>(_mm_and_ps(_mm_sub_ps(_mm_setzero_ps(), rowSumAvx2(a, x, after(i))), kKeepXyz));
    }
}

#undef TUMBLE_AVX2

bool useAvx2() {
    return activeSimd() == Simd::Avx2;
}

} // namespace

template <class S>
void multiplyRows(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* y, std::uint32_t first,
                  std::uint32_t end) {
    if constexpr (std::is_same_v<S, float>) {
        useAvx2() ? multiplyAvx2(a, x, y, first, end) : multiplySse2(a, x, y, first, end);
    } else {
        multiplyPlain(a, x, y, first, end);
    }
}

template <class S>
void smoothRows(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                std::uint32_t first, std::uint32_t end, bool forward) {
    if constexpr (std::is_same_v<S, float>) {
        useAvx2() ? smoothAvx2(a, dinv, b, x, first, end, forward)
                  : smoothSse2(a, dinv, b, x, first, end, forward);
    } else {
        smoothPlain(a, dinv, b, x, first, end, forward);
    }
}

namespace {

template <class S, class Rows>
void forwardWith(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                 std::uint32_t first, std::uint32_t end, Rows before) {
    if constexpr (std::is_same_v<S, float>) {
        useAvx2() ? forwardAvx2(a, dinv, b, x, first, end, before)
                  : forwardSse2(a, dinv, b, x, first, end, before);
    } else {
        forwardPlain(a, dinv, b, x, first, end, before);
    }
}

template <class S, class Rows>
void residualWith(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* r, std::uint32_t first,
                  std::uint32_t end, Rows after) {
    if constexpr (std::is_same_v<S, float>) {
        useAvx2() ? residualAvx2(a, x, r, first, end, after) : residualSse2(a, x, r, first, end, after);
    } else {
        residualPlain(a, x, r, first, end, after);
    }
}

} // namespace

template <class S>
void forwardRowsFromZero(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                         std::uint32_t first, std::uint32_t end, const SweepOrder* order) {
    if (order) {
        assert(order->split.size() == a.n && order->items.size() == a.col.size() - a.n);
        forwardWith(a, dinv, b, x, first, end, ListedBefore{a.rowStart.data(), *order});
    } else {
        forwardWith(a, dinv, b, x, first, end, BeforeBlocks<S>{a});
    }
}

template <class S>
void residualAfterForward(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* r, std::uint32_t first,
                          std::uint32_t end, const SweepOrder* order) {
    if (order) {
        assert(order->split.size() == a.n && order->items.size() == a.col.size() - a.n);
        residualWith(a, x, r, first, end, ListedAfter{a.rowStart.data(), *order});
    } else {
        residualWith(a, x, r, first, end, AfterBlocks<S>{a});
    }
}

template void multiplyRows(const BlockMatrix<float>&, const Vec3T<float>*, Vec3T<float>*, std::uint32_t,
                           std::uint32_t);
template void multiplyRows(const BlockMatrix<double>&, const Vec3T<double>*, Vec3T<double>*, std::uint32_t,
                           std::uint32_t);
template void smoothRows(const BlockMatrix<float>&, const Mat3T<float>*, const Vec3T<float>*, Vec3T<float>*,
                         std::uint32_t, std::uint32_t, bool);
template void smoothRows(const BlockMatrix<double>&, const Mat3T<double>*, const Vec3T<double>*,
                         Vec3T<double>*, std::uint32_t, std::uint32_t, bool);
template void forwardRowsFromZero(const BlockMatrix<float>&, const Mat3T<float>*, const Vec3T<float>*,
                                  Vec3T<float>*, std::uint32_t, std::uint32_t, const SweepOrder*);
template void forwardRowsFromZero(const BlockMatrix<double>&, const Mat3T<double>*, const Vec3T<double>*,
                                  Vec3T<double>*, std::uint32_t, std::uint32_t, const SweepOrder*);
template void residualAfterForward(const BlockMatrix<float>&, const Vec3T<float>*, Vec3T<float>*,
                                   std::uint32_t, std::uint32_t, const SweepOrder*);
template void residualAfterForward(const BlockMatrix<double>&, const Vec3T<double>*, Vec3T<double>*,
                                   std::uint32_t, std::uint32_t, const SweepOrder*);

} // namespace tumble::kernels
