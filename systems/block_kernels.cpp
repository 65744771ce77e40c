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

/// Calls row(i) for the rows of two ranges in turn: the k-th of one, then the k-th of the other
/// (forwardRowPairFromZero).
template <class RowFn>
inline void inTurn(RowRange one, RowRange other, RowFn row) {
    const std::uint32_t rows = std::max(one.size(), other.size());
    for (std::uint32_t k = 0; k < rows; ++k) {
        if (k < one.size()) {
            row(one.first + k);
        }
        if (k < other.size()) {
            row(other.first + k);
        }
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
void forwardPlain(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x, RowRange one,
                  RowRange other, Rows before) {
    inTurn(one, other,
           [&](std::uint32_t i) { x[i] = symmetricTimes(dinv[i], b[i] - rowSum(a, x, before(i))); });
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

/// Blocks as stored: nine floats each.
struct FullBlocks {
    const Mat3T<float>* val;
    __m128 times(std::uint32_t k, __m128 v) const { return blockTimes(val[k], v); }
    const float* at(std::uint32_t k) const { return val[k].m.data(); }
};

/// Blocks from their upper triangles (BlockMatrix::packed, six floats each): row0 = (a00 a01 a02) is the
/// first four floats, row1 = (a01 a11 a12) and row2 = (a02 a12 a22) are shuffled from the first four and
/// the four from the third. The same numbers in lanes 0-2 as FullBlocks, so the same bits.
struct PackedBlocks {
    const float* sym;
    static __m128 row1(__m128 t0, __m128 t1) { return _mm_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 1)); }
    static __m128 row2(__m128 t1) { return _mm_shuffle_ps(t1, t1, _MM_SHUFFLE(0, 3, 2, 0)); }
    __m128 times(std::uint32_t k, __m128 v) const {
        const float* s = sym + 6 * std::size_t(k);
        const __m128 t0 = _mm_loadu_ps(s), t1 = _mm_loadu_ps(s + 2);
        __m128 r = _mm_mul_ps(t0, _mm_shuffle_ps(v, v, 0x00));
        r = _mm_add_ps(r, _mm_mul_ps(row1(t0, t1), _mm_shuffle_ps(v, v, 0x55)));
        return _mm_add_ps(r, _mm_mul_ps(row2(t1), _mm_shuffle_ps(v, v, 0xaa)));
    }
};

template <class Blocks, class Row>
inline __m128 rowSumSse2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x,
                         const Row& row) {
    __m128 even = _mm_setzero_ps(), odd = _mm_setzero_ps();
    const std::uint32_t count = row.count();
    std::uint32_t k = 0;
    for (; k + 1 < count; k += 2) {
        const std::uint32_t p = row.at(k), q = row.at(k + 1);
        even = _mm_add_ps(even, blocks.times(p, x[a.col[p]].simd()));
        odd = _mm_add_ps(odd, blocks.times(q, x[a.col[q]].simd()));
    }
    if (k < count) {
        const std::uint32_t p = row.at(k);
        even = _mm_add_ps(even, blocks.times(p, x[a.col[p]].simd()));
    }
    return _mm_add_ps(even, odd);
}

template <class Blocks>
void multiplySse2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x, Vec3T<float>* y,
                  std::uint32_t first, std::uint32_t end) {
    for (std::uint32_t i = first; i < end; ++i) {
        y[i] = Vec3T<float>(_mm_and_ps(rowSumSse2(a, blocks, x, wholeRow(a, i)), kKeepXyz));
    }
}

template <class Blocks>
void smoothSse2(const BlockMatrix<float>& a, const Blocks& blocks, const Mat3T<float>* dinv,
                const Vec3T<float>* b, Vec3T<float>* x, std::uint32_t first, std::uint32_t end,
                bool forward) {
    for (std::uint32_t k = first; k < end; ++k) {
        const std::uint32_t i = forward ? k : end - 1 - (k - first);
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumSse2(a, blocks, x, offDiagonal(a, i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

template <class Blocks, class Rows>
void forwardSse2(const BlockMatrix<float>& a, const Blocks& blocks, const Mat3T<float>* dinv,
                 const Vec3T<float>* b, Vec3T<float>* x, RowRange one, RowRange other, Rows before) {
    inTurn(one, other, [&](std::uint32_t i) {
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumSse2(a, blocks, x, before(i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    });
}

template <class Blocks, class Rows>
void residualSse2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x, Vec3T<float>* r,
                  std::uint32_t first, std::uint32_t end, Rows after) {
    for (std::uint32_t i = first; i < end; ++i) {
        r[i] = Vec3T<float>(
            _mm_and_ps(_mm_sub_ps(_mm_setzero_ps(), rowSumSse2(a, blocks, x, after(i))), kKeepXyz));
    }
}

// ---- float, AVX2: a pair of blocks at a time, the two partials in the halves of one register ----

#define TUMBLE_AVX2 __attribute__((target("avx2")))

/// Two 16-byte halves in one register: lo in lanes 0-3, hi in lanes 4-7.
TUMBLE_AVX2 inline __m256 halves(__m128 lo, __m128 hi) {
    return _mm256_insertf128_ps(_mm256_castps128_ps256(lo), hi, 1);
}

/// (row0 v.x + row1 v.y) + row2 v.z for two blocks at once, their rows given: p's in the low halves, with
/// the low half of v, q's in the high halves.
TUMBLE_AVX2 inline __m256 pairRowsTimes(__m256 row0, __m256 row1, __m256 row2, __m256 v) {
    __m256 r = _mm256_mul_ps(row0, _mm256_permute_ps(v, 0x00));
    r = _mm256_add_ps(r, _mm256_mul_ps(row1, _mm256_permute_ps(v, 0x55)));
    return _mm256_add_ps(r, _mm256_mul_ps(row2, _mm256_permute_ps(v, 0xaa)));
}

/// blockTimes of two blocks at once: p with the low half of v, q with the high half.
TUMBLE_AVX2 inline __m256 pairTimes(const FullBlocks& blocks, std::uint32_t p, std::uint32_t q, __m256 v) {
    const float* a = blocks.at(p);
    const float* b = blocks.at(q);
    return pairRowsTimes(halves(_mm_loadu_ps(a), _mm_loadu_ps(b)),
                         halves(_mm_loadu_ps(a + 3), _mm_loadu_ps(b + 3)),
                         _mm256_permute_ps(halves(_mm_loadu_ps(a + 5), _mm_loadu_ps(b + 5)), 0x39), v);
}

/// The same from the upper triangles: PackedBlocks' shuffles, lane by lane in each half.
TUMBLE_AVX2 inline __m256 pairTimes(const PackedBlocks& blocks, std::uint32_t p, std::uint32_t q, __m256 v) {
    const float* a = blocks.sym + 6 * std::size_t(p);
    const float* b = blocks.sym + 6 * std::size_t(q);
    const __m256 t0 = halves(_mm_loadu_ps(a), _mm_loadu_ps(b));
    const __m256 t1 = halves(_mm_loadu_ps(a + 2), _mm_loadu_ps(b + 2));
    return pairRowsTimes(t0, _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 1)),
                         _mm256_shuffle_ps(t1, t1, _MM_SHUFFLE(0, 3, 2, 0)), v);
}

template <class Blocks, class Row>
TUMBLE_AVX2 inline __m128 rowSumAvx2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x,
                                     const Row& row) {
    __m256 both = _mm256_setzero_ps();
    const std::uint32_t count = row.count();
    std::uint32_t k = 0;
    for (; k + 1 < count; k += 2) {
        const std::uint32_t p = row.at(k), q = row.at(k + 1);
        both = _mm256_add_ps(both, pairTimes(blocks, p, q, halves(x[a.col[p]].simd(), x[a.col[q]].simd())));
    }
    __m128 even = _mm256_castps256_ps128(both);
    const __m128 odd = _mm256_extractf128_ps(both, 1);
    if (k < count) {
        const std::uint32_t p = row.at(k);
        even = _mm_add_ps(even, blocks.times(p, x[a.col[p]].simd()));
    }
    return _mm_add_ps(even, odd);
}

template <class Blocks>
TUMBLE_AVX2 void multiplyAvx2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x,
                              Vec3T<float>* y, std::uint32_t first, std::uint32_t end) {
    for (std::uint32_t i = first; i < end; ++i) {
        y[i] = Vec3T<float>(_mm_and_ps(rowSumAvx2(a, blocks, x, wholeRow(a, i)), kKeepXyz));
    }
}

/// One row of a sweep: x_i = D_i^-1 (b_i - the sum over the blocks `row` gives).
template <class Blocks, class Row>
TUMBLE_AVX2 inline void sweepRowAvx2(const BlockMatrix<float>& a, const Blocks& blocks,
                                     const Mat3T<float>* dinv, const Vec3T<float>* b, Vec3T<float>* x,
                                     std::uint32_t i, const Row& row) {
    const __m128 s = _mm_sub_ps(b[i].simd(), rowSumAvx2(a, blocks, x, row));
    x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
}

template <class Blocks>
TUMBLE_AVX2 void smoothAvx2(const BlockMatrix<float>& a, const Blocks& blocks, const Mat3T<float>* dinv,
                            const Vec3T<float>* b, Vec3T<float>* x, std::uint32_t first, std::uint32_t end,
                            bool forward) {
    for (std::uint32_t k = first; k < end; ++k) {
        const std::uint32_t i = forward ? k : end - 1 - (k - first);
        const __m128 s = _mm_sub_ps(b[i].simd(), rowSumAvx2(a, blocks, x, offDiagonal(a, i)));
        x[i] = Vec3T<float>(_mm_and_ps(blockTimes(dinv[i], s), kKeepXyz));
    }
}

// inTurn's loop written out: a lambda would not take the AVX2 target
template <class Blocks, class Rows>
TUMBLE_AVX2 void forwardAvx2(const BlockMatrix<float>& a, const Blocks& blocks, const Mat3T<float>* dinv,
                             const Vec3T<float>* b, Vec3T<float>* x, RowRange one, RowRange other,
                             Rows before) {
    const std::uint32_t rows = std::max(one.size(), other.size());
    for (std::uint32_t k = 0; k < rows; ++k) {
        if (k < one.size()) {
            sweepRowAvx2(a, blocks, dinv, b, x, one.first + k, before(one.first + k));
        }
        if (k < other.size()) {
            sweepRowAvx2(a, blocks, dinv, b, x, other.first + k, before(other.first + k));
        }
    }
}

template <class Blocks, class Rows>
TUMBLE_AVX2 void residualAvx2(const BlockMatrix<float>& a, const Blocks& blocks, const Vec3T<float>* x,
                              Vec3T<float>* r, std::uint32_t first, std::uint32_t end, Rows after) {
    for (std::uint32_t i = first; i < end; ++i) {
        r[i] = Vec3T<float>(
            _mm_and_ps(_mm_sub_ps(_mm_setzero_ps(), rowSumAvx2(a, blocks, x, after(i))), kKeepXyz));
    }
}

#undef TUMBLE_AVX2

bool useAvx2() {
    return activeSimd() == Simd::Avx2;
}

/// Calls f with the float matrix's blocks: its upper triangles where it was packed, else as stored.
template <class F>
void withBlocks(const BlockMatrix<float>& a, F&& f) {
    if (a.isPacked()) {
        f(PackedBlocks{a.packed.data()});
    } else {
        f(FullBlocks{a.val.data()});
    }
}

} // namespace

template <class S>
void multiplyRows(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* y, std::uint32_t first,
                  std::uint32_t end) {
    if constexpr (std::is_same_v<S, float>) {
        withBlocks(a, [&](const auto& blocks) {
            useAvx2() ? multiplyAvx2(a, blocks, x, y, first, end) : multiplySse2(a, blocks, x, y, first, end);
        });
    } else {
        multiplyPlain(a, x, y, first, end);
    }
}

template <class S>
void smoothRows(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                std::uint32_t first, std::uint32_t end, bool forward) {
    if constexpr (std::is_same_v<S, float>) {
        withBlocks(a, [&](const auto& blocks) {
            useAvx2() ? smoothAvx2(a, blocks, dinv, b, x, first, end, forward)
                      : smoothSse2(a, blocks, dinv, b, x, first, end, forward);
        });
    } else {
        smoothPlain(a, dinv, b, x, first, end, forward);
    }
}

namespace {

template <class S, class Rows>
void forwardWith(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x, RowRange one,
                 RowRange other, Rows before) {
    if constexpr (std::is_same_v<S, float>) {
        withBlocks(a, [&](const auto& blocks) {
            useAvx2() ? forwardAvx2(a, blocks, dinv, b, x, one, other, before)
                      : forwardSse2(a, blocks, dinv, b, x, one, other, before);
        });
    } else {
        forwardPlain(a, dinv, b, x, one, other, before);
    }
}

template <class S, class Rows>
void residualWith(const BlockMatrix<S>& a, const Vec3T<S>* x, Vec3T<S>* r, std::uint32_t first,
                  std::uint32_t end, Rows after) {
    if constexpr (std::is_same_v<S, float>) {
        withBlocks(a, [&](const auto& blocks) {
            useAvx2() ? residualAvx2(a, blocks, x, r, first, end, after)
                      : residualSse2(a, blocks, x, r, first, end, after);
        });
    } else {
        residualPlain(a, x, r, first, end, after);
    }
}

} // namespace

template <class S>
void forwardRowPairFromZero(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                            RowRange one, RowRange other, const SweepOrder* order) {
    assert(one.first <= one.end && other.first <= other.end && one.end <= a.n && other.end <= a.n);
    if (order) {
        assert(order->split.size() == a.n && order->items.size() == a.col.size() - a.n);
        forwardWith(a, dinv, b, x, one, other, ListedBefore{a.rowStart.data(), *order});
    } else {
        forwardWith(a, dinv, b, x, one, other, BeforeBlocks<S>{a});
    }
}

template <class S>
void forwardRowsFromZero(const BlockMatrix<S>& a, const Mat3T<S>* dinv, const Vec3T<S>* b, Vec3T<S>* x,
                         std::uint32_t first, std::uint32_t end, const SweepOrder* order) {
    forwardRowPairFromZero(a, dinv, b, x, {first, end}, {end, end}, order);
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
template void forwardRowPairFromZero(const BlockMatrix<float>&, const Mat3T<float>*, const Vec3T<float>*,
                                     Vec3T<float>*, RowRange, RowRange, const SweepOrder*);
template void forwardRowPairFromZero(const BlockMatrix<double>&, const Mat3T<double>*, const Vec3T<double>*,
                                     Vec3T<double>*, RowRange, RowRange, const SweepOrder*);
template void forwardRowsFromZero(const BlockMatrix<float>&, const Mat3T<float>*, const Vec3T<float>*,
                                  Vec3T<float>*, std::uint32_t, std::uint32_t, const SweepOrder*);
template void forwardRowsFromZero(const BlockMatrix<double>&, const Mat3T<double>*, const Vec3T<double>*,
                                  Vec3T<double>*, std::uint32_t, std::uint32_t, const SweepOrder*);
template void residualAfterForward(const BlockMatrix<float>&, const Vec3T<float>*, Vec3T<float>*,
                                   std::uint32_t, std::uint32_t, const SweepOrder*);
template void residualAfterForward(const BlockMatrix<double>&, const Vec3T<double>*, Vec3T<double>*,
                                   std::uint32_t, std::uint32_t, const SweepOrder*);

} // namespace tumble::kernels
