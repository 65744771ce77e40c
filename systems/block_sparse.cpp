#include "systems/block_sparse.h"

#include "systems/block_kernels.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <type_traits>

namespace tumble {

template <class S>
Mat3T<S> Mat3T<S>::inverse() const {
    const auto& a = m;
    Mat3T r;
    r.m[0] = a[4] * a[8] - a[5] * a[7];
    r.m[1] = a[2] * a[7] - a[1] * a[8];
    r.m[2] = a[1] * a[5] - a[2] * a[4];
    r.m[3] = a[5] * a[6] - a[3] * a[8];
    r.m[4] = a[0] * a[8] - a[2] * a[6];
    r.m[5] = a[2] * a[3] - a[0] * a[5];
    r.m[6] = a[3] * a[7] - a[4] * a[6];
    r.m[7] = a[1] * a[6] - a[0] * a[7];
    r.m[8] = a[0] * a[4] - a[1] * a[3];
    const S det = a[0] * r.m[0] + a[1] * r.m[3] + a[2] * r.m[6];
    if constexpr (std::is_same_v<S, float>) {
        if (!std::isnormal(det)) {
            // the determinant alone past float's range (a block's entries beyond about 7e12, a node of a
            // body kilometres across, or under about 1e-13): in double, whose range takes the cube (in
            // float the inverse came out zero, and the body never moved)
            return cast<double>().inverse().template cast<float>();
        }
    }
    const S inv = S(1) / det;
    for (S& x : r.m) {
        x *= inv;
    }
    return r;
}

template <class S>
BlockMatrix<S> BlockMatrix<S>::fromPairs(std::uint32_t n,
                                         std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs) {
    // both orientations and the diagonal, each row's columns sorted and unique: a deterministic pattern.
    // The pairs are bucketed by row (a counting sort) and only each row's few columns sorted: a sort of
    // every pair was a quarter of the first step of a 150 x 150 cloth (its hierarchy's patterns).
    for (const auto& [i, j] : pairs) {
        if (i >= n || j >= n) {
            throw std::out_of_range("block pattern: index beyond the matrix");
        }
    }
    if (pairs.size() > (0xffffffffu - std::size_t(n)) / 2) {
        throw std::length_error("block pattern: more blocks than 32-bit indices can count");
    }
    std::vector<std::uint32_t> start(std::size_t(n) + 2, 0);
    for (const auto& [i, j] : pairs) {
        ++start[std::size_t(i) + 2];
        ++start[std::size_t(j) + 2];
    }
    for (std::uint32_t i = 0; i < n; ++i) {
        start[std::size_t(i) + 2] += start[std::size_t(i) + 1] + 1; // + 1: the diagonal
    }
    // start[i + 1] is where row i's entries go; it advances as they are placed, ending at row i + 1's start
    std::vector<std::uint32_t> cols(start[std::size_t(n) + 1]);
    for (std::uint32_t i = 0; i < n; ++i) {
        cols[start[std::size_t(i) + 1]++] = i;
    }
    for (const auto& [i, j] : pairs) {
        cols[start[std::size_t(i) + 1]++] = j;
        cols[start[std::size_t(j) + 1]++] = i;
    }
    BlockMatrix a;
    a.n = n;
    a.rowStart.assign(std::size_t(n) + 1, 0);
    a.col.reserve(cols.size());
    a.diag.assign(n, 0);
    for (std::uint32_t i = 0; i < n; ++i) {
        const auto first = cols.begin() + start[i], last = cols.begin() + start[std::size_t(i) + 1];
        std::sort(first, last);
        for (auto it = first; it != last; ++it) {
            if (it != first && *it == *(it - 1)) {
                continue;
            }
            if (*it == i) {
                a.diag[i] = static_cast<std::uint32_t>(a.col.size());
            }
            a.col.push_back(*it);
        }
        a.rowStart[std::size_t(i) + 1] = static_cast<std::uint32_t>(a.col.size());
    }
    a.val.assign(a.col.size(), Mat3T<S>{});
    return a;
}

template <class S>
std::uint32_t BlockMatrix<S>::find(std::uint32_t i, std::uint32_t j) const {
    const auto first = col.begin() + rowStart[i], last = col.begin() + rowStart[std::size_t(i) + 1];
    const auto it = std::lower_bound(first, last, j);
    if (it == last || *it != j) {
        throw std::out_of_range("block pattern: no block at the requested position");
    }
    return static_cast<std::uint32_t>(it - col.begin());
}

template <class S>
void BlockMatrix<S>::setZero() {
    std::fill(val.begin(), val.end(), Mat3T<S>{});
    packed.clear();
}

template <class S>
void BlockMatrix<S>::multiply(const std::vector<Vec3T<S>>& x, std::vector<Vec3T<S>>& y) const {
    y.resize(n);
    kernels::multiplyRows(*this, x.data(), y.data(), 0, n);
}

template struct Mat3T<float>;
template struct Mat3T<double>;
template struct BlockMatrix<float>;
template struct BlockMatrix<double>;

} // namespace tumble
