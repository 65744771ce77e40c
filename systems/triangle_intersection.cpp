// The exact triangle-triangle test behind the contact audit. CGAL's kernel with exact predicates decides
// every case (touching, coplanar overlap, an edge grazing a corner) with filtered floating point that
// falls back to exact arithmetic when rounding could change the answer; a test of our own in doubles
// would be wrong exactly in the near-degenerate cases an audit exists to catch. Compiled alone, with
// -frounding-math as CGAL's interval filters need, so that the rest of the build keeps its own flags.

#include "systems/cloth_collision.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/intersections.h>

namespace tumble {

bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                        const Vec3& b2) {
    using K = CGAL::Exact_predicates_inexact_constructions_kernel;
    const auto point = [](const Vec3& p) { return K::Point_3(p.x, p.y, p.z); };
    const K::Triangle_3 a(point(a0), point(a1), point(a2)), b(point(b0), point(b1), point(b2));
    // a triangle whose corners are collinear is a segment (or a point) to CGAL's test: asked as such
    const auto asObject = [&](const K::Triangle_3& t, auto&& f) {
        if (!t.is_degenerate()) {
            return f(t);
        }
        K::Point_3 lo = t[0], hi = t[0];
        for (int k = 1; k < 3; ++k) {
            if (t[k] < lo) {
                lo = t[k];
            }
            if (hi < t[k]) {
                hi = t[k];
            }
        }
        if (lo == hi) {
            return f(lo);
        }
        return f(K::Segment_3(lo, hi));
    };
    return asObject(a, [&](const auto& ga) {
        return asObject(b, [&](const auto& gb) { return CGAL::do_intersect(ga, gb); });
    });
}

} // namespace tumble
