#include "systems/ccd.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <vector>

namespace tumble {

namespace {

/// Boxes examined at most per query; past it the query answers "hit" at the earliest open box (safe: the
/// response then acts a little early). Most queries take a few dozen; random motions confined to one plane,
/// where one coordinate of F never excludes anything, reach the cap about once in 300.
constexpr int kMaxBoxes = 8192;
constexpr double kTimeTolerance = 1e-6; ///< of the step

/// A box of the parameter domain: time t, and the surface parameters u, v.
struct Box {
    double t0, t1, u0, u1, v0, v1;
};

/// The query in coordinates relative to the vertex's (or first edge point's) start, which keeps the
/// numbers small and the rounding error bound tight.
struct Query {
    Vec3 s[4]; ///< starts
    Vec3 d[4]; ///< displacements over the step
    bool vertexTriangle;
};

/// F at the box's eight corners; corner index bits: 4 = t1, 2 = u1, 1 = v1.
void cornerValues(const Query& q, const Box& b, Vec3 f[8]) {
    for (int it = 0; it < 2; ++it) {
        const double t = it ? b.t1 : b.t0;
        const Vec3 p0 = q.s[0] + q.d[0] * t, p1 = q.s[1] + q.d[1] * t;
        const Vec3 p2 = q.s[2] + q.d[2] * t, p3 = q.s[3] + q.d[3] * t;
        for (int iu = 0; iu < 2; ++iu) {
            const double u = iu ? b.u1 : b.u0;
            for (int iv = 0; iv < 2; ++iv) {
                const double v = iv ? b.v1 : b.v0;
                // vertex - (a + u (b - a) + v (c - a)); or (a0 + u (a1 - a0)) - (b0 + v (b1 - b0))
                f[it * 4 + iu * 2 + iv] = q.vertexTriangle ? p0 - p1 - (p2 - p1) * u - (p3 - p1) * v
                                                           : p0 + (p1 - p0) * u - p2 - (p3 - p2) * v;
            }
        }
    }
}

double coord(const Vec3& v, int c) {
    return c == 0 ? v.x : c == 1 ? v.y : v.z;
}

/// How much F changes along each parameter over the box: the largest corner-to-corner difference.
void spans(const Vec3 f[8], double out[3]) {
    out[0] = out[1] = out[2] = 0.0;
    for (int i = 0; i < 8; ++i) {
        for (int axis = 0; axis < 3; ++axis) {
            const int bit = 4 >> axis; // t, u, v
            if (i & bit) {
                continue;
            }
            const Vec3 diff = f[i | bit] - f[i];
            out[axis] = std::max({out[axis], std::abs(diff.x), std::abs(diff.y), std::abs(diff.z)});
        }
    }
}

CcdResult search(const Query& q, double distance) {
    // every corner value is a sum of a few products of coordinates no larger than m: its rounding error is
    // a small multiple of DBL_EPSILON * m (the bound below is generous)
    double m = 0.0;
    for (int k = 0; k < 4; ++k) {
        const Vec3 e = q.s[k] + q.d[k];
        m = std::max({m, std::abs(q.s[k].x), std::abs(q.s[k].y), std::abs(q.s[k].z), std::abs(e.x),
                      std::abs(e.y), std::abs(e.z)});
    }
    const double reach = distance + 128.0 * DBL_EPSILON * m;
    // a box whose F varies less than this is a contact: a millionth of the query's size, or a tenth of
    // the distance asked for
    const double tolerance = std::max(1e-6 * m, 0.1 * distance);
    if (m == 0.0) {
        return {true, 0.0, false}; // every point at one place: in contact from the start
    }

    // depth first, the earlier half in time first; once a contact is found, only boxes that start before
    // it are still worth opening, and the earliest found is the answer
    thread_local std::vector<Box> open;
    open.clear();
    open.push_back({0.0, 1.0, 0.0, 1.0, 0.0, 1.0});
    CcdResult best;
    int examined = 0;
    while (!open.empty()) {
        Box b = open.back();
        open.pop_back();
        // once a contact is known, a box matters only before it: cut to end there (less a millionth of the
        // step, so that along a line of contacts, parallel edges say, the boxes beside the one found are
        // cut clear of the line and excluded rather than each opened down to the tolerance)
        if (best.hit) {
            b.t1 = std::min(b.t1, best.toi - kTimeTolerance);
            if (b.t1 <= b.t0) {
                continue;
            }
        }
        if (++examined > kMaxBoxes) {
            // out of patience: the earliest box still open is where a contact may begin
            double earliest = b.t0;
            for (const Box& o : open) {
                earliest = std::min(earliest, o.t0);
            }
            return {true, best.hit ? std::min(best.toi, earliest) : earliest, true};
        }
        Vec3 f[8];
        cornerValues(q, b, f);
        double width = 0.0;
        bool excluded = false;
        for (int c = 0; c < 3 && !excluded; ++c) {
            double lo = coord(f[0], c), hi = lo;
            for (int i = 1; i < 8; ++i) {
                lo = std::min(lo, coord(f[i], c));
                hi = std::max(hi, coord(f[i], c));
            }
            excluded = lo > reach || hi < -reach;
            width = std::max(width, hi - lo);
        }
        if (excluded) {
            continue;
        }
        if (width <= tolerance) {
            best = {true, b.t0, false};
            continue;
        }
        // split the parameter along which F varies most
        double s[3];
        spans(f, s);
        const int axis = s[0] >= s[1] && s[0] >= s[2] ? 0 : s[1] >= s[2] ? 1 : 2;
        Box lo = b, hi = b;
        if (axis == 0) {
            lo.t1 = hi.t0 = 0.5 * (b.t0 + b.t1);
        } else if (axis == 1) {
            lo.u1 = hi.u0 = 0.5 * (b.u0 + b.u1);
        } else {
            lo.v1 = hi.v0 = 0.5 * (b.v0 + b.v1);
        }
        // the later (or second) half goes on the stack first, so the earlier one is opened next; a
        // triangle's points have u + v <= 1
        for (const Box& child : {hi, lo}) {
            if (!(q.vertexTriangle && child.u0 + child.v0 > 1.0)) {
                open.push_back(child);
            }
        }
    }
    return best;
}

Query makeQuery(const Vec3 start[4], const Vec3 end[4], bool vertexTriangle) {
    Query q;
    q.vertexTriangle = vertexTriangle;
    const Vec3 origin = start[0];
    for (int k = 0; k < 4; ++k) {
        q.s[k] = start[k] - origin;
        q.d[k] = (end[k] - origin) - q.s[k];
    }
    return q;
}

} // namespace

CcdResult vertexTriangleCcd(const Vec3 start[4], const Vec3 end[4], double distance) {
    return search(makeQuery(start, end, true), distance);
}

CcdResult edgeEdgeCcd(const Vec3 start[4], const Vec3 end[4], double distance) {
    return search(makeQuery(start, end, false), distance);
}

} // namespace tumble
