#pragma once
// The tests' own judge of cloth contact, written apart from the code under test: an orientation-sign test
// of triangle-triangle intersection (two triangles meet when an edge of one meets the other, coplanar
// cases included; the signs exact, by GMP rationals where doubles cannot decide: a sheet lying flat is
// coplanar to the last bit, and long double signs there were noise that saw 172 crossings in a flat cloth), a
// sort-and-sweep broad phase, and the depth of a mass inside the analytic colliders the test scenes use.
// tests/cloth_contact_test.cpp checks it against hand-made cases and against CGAL.

#include "engine/math.h"

#include <gmp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace tumble::test {

/// An exact rational, for the few orientations that floating point cannot decide.
class Rational {
public:
    Rational() { mpq_init(m_q); }
    explicit Rational(double d) : Rational() { mpq_set_d(m_q, d); }
    ~Rational() { mpq_clear(m_q); }
    Rational(const Rational& o) : Rational() { mpq_set(m_q, o.m_q); }
    Rational& operator=(const Rational& o) {
        mpq_set(m_q, o.m_q);
        return *this;
    }
    friend Rational operator-(const Rational& a, const Rational& b) {
        Rational r;
        mpq_sub(r.m_q, a.m_q, b.m_q);
        return r;
    }
    friend Rational operator+(const Rational& a, const Rational& b) {
        Rational r;
        mpq_add(r.m_q, a.m_q, b.m_q);
        return r;
    }
    friend Rational operator*(const Rational& a, const Rational& b) {
        Rational r;
        mpq_mul(r.m_q, a.m_q, b.m_q);
        return r;
    }
    int sign() const { return mpq_sgn(m_q); }

private:
    mpq_t m_q;
};

/// Sign of the volume of (b - a, c - a, d - a): exact. Doubles decide when the result is clear of their
/// rounding error (Shewchuk's bound for this expression), exact rationals otherwise.
inline int orient3(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
    const double bx = b.x - a.x, by = b.y - a.y, bz = b.z - a.z;
    const double cx = c.x - a.x, cy = c.y - a.y, cz = c.z - a.z;
    const double dx = d.x - a.x, dy = d.y - a.y, dz = d.z - a.z;
    const double det = bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx);
    const double permanent = std::abs(bx) * (std::abs(cy * dz) + std::abs(cz * dy)) +
                             std::abs(by) * (std::abs(cx * dz) + std::abs(cz * dx)) +
                             std::abs(bz) * (std::abs(cx * dy) + std::abs(cy * dx));
    const double eps = std::numeric_limits<double>::epsilon();
    if (std::abs(det) > (8.0 * eps + 64.0 * eps * eps) * permanent) {
        return (det > 0) - (det < 0);
    }
    // every product has a difference that is exactly zero (a - b rounds to zero only when a == b): a flat
    // sheet, exactly coplanar
    if (permanent == 0.0) {
        return 0;
    }
    const Rational ax(a.x), ay(a.y), az(a.z);
    const Rational Bx = Rational(b.x) - ax, By = Rational(b.y) - ay, Bz = Rational(b.z) - az;
    const Rational Cx = Rational(c.x) - ax, Cy = Rational(c.y) - ay, Cz = Rational(c.z) - az;
    const Rational Dx = Rational(d.x) - ax, Dy = Rational(d.y) - ay, Dz = Rational(d.z) - az;
    const Rational e = Bx * (Cy * Dz - Cz * Dy) - By * (Cx * Dz - Cz * Dx) + Bz * (Cx * Dy - Cy * Dx);
    return e.sign();
}

/// Sign of the area of (b - a, c - a) in 2D: exact, as orient3.
inline int orient2(double ax, double ay, double bx, double by, double cx, double cy) {
    const double det = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    const double permanent = std::abs((bx - ax) * (cy - ay)) + std::abs((by - ay) * (cx - ax));
    const double eps = std::numeric_limits<double>::epsilon();
    if (std::abs(det) > (4.0 * eps + 32.0 * eps * eps) * permanent) {
        return (det > 0) - (det < 0);
    }
    if (permanent == 0.0) {
        return 0;
    }
    const Rational e = (Rational(bx) - Rational(ax)) * (Rational(cy) - Rational(ay)) -
                       (Rational(by) - Rational(ay)) * (Rational(cx) - Rational(ax));
    return e.sign();
}

/// Do segments pq and rs of a plane meet (touching counts)?
inline bool segmentsMeet2(const double p[2], const double q[2], const double r[2], const double s[2]) {
    const int o1 = orient2(p[0], p[1], q[0], q[1], r[0], r[1]),
              o2 = orient2(p[0], p[1], q[0], q[1], s[0], s[1]);
    const int o3 = orient2(r[0], r[1], s[0], s[1], p[0], p[1]),
              o4 = orient2(r[0], r[1], s[0], s[1], q[0], q[1]);
    if (o1 * o2 < 0 && o3 * o4 < 0) {
        return true;
    }
    auto on = [](const double a[2], const double b[2], const double c[2]) {
        return std::min(a[0], b[0]) <= c[0] && c[0] <= std::max(a[0], b[0]) && std::min(a[1], b[1]) <= c[1] &&
               c[1] <= std::max(a[1], b[1]);
    };
    return (o1 == 0 && on(p, q, r)) || (o2 == 0 && on(p, q, s)) || (o3 == 0 && on(r, s, p)) ||
           (o4 == 0 && on(r, s, q));
}

/// Does segment pq meet triangle abc (boundaries included, coplanar cases too)?
inline bool segmentMeetsTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
    const int sp = orient3(a, b, c, p), sq = orient3(a, b, c, q);
    if (sp * sq > 0) {
        return false;
    }
    if (sp != 0 || sq != 0) {
        // the line crosses the plane: inside when it passes on the same side of all three edges
        const int e0 = orient3(p, q, a, b), e1 = orient3(p, q, b, c), e2 = orient3(p, q, c, a);
        return (e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0);
    }
    // all in one plane: drop the axis the plane faces most, then test in 2D
    const Vec3 n = cross(b - a, c - a);
    const int drop = std::abs(n.x) >= std::abs(n.y) && std::abs(n.x) >= std::abs(n.z) ? 0
                     : std::abs(n.y) >= std::abs(n.z)                                 ? 1
                                                                                      : 2;
    auto flat = [drop](const Vec3& v, double out[2]) {
        const double c3[3] = {v.x, v.y, v.z};
        int k = 0;
        for (int i = 0; i < 3; ++i) {
            if (i != drop) {
                out[k++] = c3[i];
            }
        }
    };
    double P[2], Q[2], T[3][2];
    flat(p, P);
    flat(q, Q);
    flat(a, T[0]);
    flat(b, T[1]);
    flat(c, T[2]);
    for (int i = 0; i < 3; ++i) {
        if (segmentsMeet2(P, Q, T[i], T[(i + 1) % 3])) {
            return true;
        }
    }
    // wholly inside: p on the inner side of every edge
    const int o0 = orient2(T[0][0], T[0][1], T[1][0], T[1][1], P[0], P[1]);
    const int o1 = orient2(T[1][0], T[1][1], T[2][0], T[2][1], P[0], P[1]);
    const int o2 = orient2(T[2][0], T[2][1], T[0][0], T[0][1], P[0], P[1]);
    return (o0 >= 0 && o1 >= 0 && o2 >= 0) || (o0 <= 0 && o1 <= 0 && o2 <= 0);
}

/// Do the triangles share a point? Two triangles meet exactly when an edge of one meets the other.
inline bool referenceTrianglesMeet(const Vec3 a[3], const Vec3 b[3]) {
    for (int i = 0; i < 3; ++i) {
        if (segmentMeetsTriangle(a[i], a[(i + 1) % 3], b[0], b[1], b[2]) ||
            segmentMeetsTriangle(b[i], b[(i + 1) % 3], a[0], a[1], a[2])) {
            return true;
        }
    }
    return false;
}

/// A cloth's triangles in the world, for the checks.
struct Surface {
    const std::vector<Vec3>* x;
    const std::vector<std::array<std::uint32_t, 3>>* triangles;
};

/// Intersecting pairs of triangles that share no vertex, over all the surfaces (within and between them):
/// boxes sorted along x and swept, then the reference test.
inline int countCrossings(const std::vector<Surface>& surfaces) {
    struct Item {
        double lo[3], hi[3];
        std::uint32_t surface, tri;
    };
    std::vector<Item> items;
    for (std::uint32_t s = 0; s < surfaces.size(); ++s) {
        const auto& x = *surfaces[s].x;
        for (std::uint32_t t = 0; t < surfaces[s].triangles->size(); ++t) {
            Item it{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}, s, t};
            for (std::uint32_t k : (*surfaces[s].triangles)[t]) {
                const double c[3] = {x[k].x, x[k].y, x[k].z};
                for (int a = 0; a < 3; ++a) {
                    it.lo[a] = std::min(it.lo[a], c[a]);
                    it.hi[a] = std::max(it.hi[a], c[a]);
                }
            }
            items.push_back(it);
        }
    }
    std::sort(items.begin(), items.end(), [](const Item& a, const Item& b) { return a.lo[0] < b.lo[0]; });
    int crossings = 0;
    for (std::size_t i = 0; i < items.size(); ++i) {
        for (std::size_t j = i + 1; j < items.size() && items[j].lo[0] <= items[i].hi[0]; ++j) {
            const Item& A = items[i];
            const Item& B = items[j];
            if (A.lo[1] > B.hi[1] || B.lo[1] > A.hi[1] || A.lo[2] > B.hi[2] || B.lo[2] > A.hi[2]) {
                continue;
            }
            const auto& ta = (*surfaces[A.surface].triangles)[A.tri];
            const auto& tb = (*surfaces[B.surface].triangles)[B.tri];
            if (A.surface == B.surface) {
                bool share = false;
                for (std::uint32_t k : ta) {
                    share = share || k == tb[0] || k == tb[1] || k == tb[2];
                }
                if (share) {
                    continue;
                }
            }
            const auto& xa = *surfaces[A.surface].x;
            const auto& xb = *surfaces[B.surface].x;
            const Vec3 pa[3] = {xa[ta[0]], xa[ta[1]], xa[ta[2]]};
            const Vec3 pb[3] = {xb[tb[0]], xb[tb[1]], xb[tb[2]]};
            crossings += referenceTrianglesMeet(pa, pb);
        }
    }
    return crossings;
}

} // namespace tumble::test
