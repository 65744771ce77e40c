#include "systems/cloth_collision.h"

#include "components/spring_network.h"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace tumble {

namespace {

constexpr int kProximityPasses = 4;
constexpr double kSettled = 0.99; ///< a pair pushed from closer than this fraction of the thickness counts
constexpr int kContinuousPasses = 4;
constexpr double kGapFraction = 0.1; ///< a crossing is stopped this fraction of the thickness short

/// One side of a contact: the masses of a network it involves.
struct Patch {
    SpringNetwork* net = nullptr;
    std::uint32_t idx[3] = {0, 0, 0};
    std::uint32_t count = 0;
};

/// Four points (or fewer) of one or two networks whose weighted sum q = sum w_k x_k is the separation of
/// a contact: point minus closest triangle point, or edge point minus edge point.
struct Stencil {
    SpringNetwork* net[4];
    std::uint32_t idx[4];
    double w[4];

    Vec3 sum(const std::vector<Vec3> SpringNetwork::*field) const {
        Vec3 q;
        for (int k = 0; k < 4; ++k) {
            q += (net[k]->*field)[idx[k]] * w[k];
        }
        return q;
    }
    double inverseMass() const {
        double m = 0.0;
        for (int k = 0; k < 4; ++k) {
            if (!net[k]->pinned[idx[k]]) {
                m += w[k] * w[k] * net[k]->invMass[idx[k]];
            }
        }
        return m;
    }
    /// Changes q by dq (in field x or v), sharing it by inverse mass and weight.
    void apply(std::vector<Vec3> SpringNetwork::*field, const Vec3& dq) const {
        // the free points must carry a fair share of the contact: a point at the very end of an edge whose
        // others are pinned would otherwise be thrown by dq divided by its tiny weight
        double all = 0.0;
        for (int k = 0; k < 4; ++k) {
            all += net[k]->invMass[idx[k]];
        }
        const double m = inverseMass();
        if (m <= 1e-6 * all) {
            return;
        }
        const Vec3 j = dq * (1.0 / m);
        for (int k = 0; k < 4; ++k) {
            if (!net[k]->pinned[idx[k]]) {
                (net[k]->*field)[idx[k]] += j * (w[k] * net[k]->invMass[idx[k]]);
            }
        }
    }
};

struct Mesh {
    SpringNetwork* net;
    ClothCollision* cc;
};

struct VertexTriangle {
    std::uint32_t pm, p, tm, t; ///< mesh and mass of the point; mesh and triangle
    bool operator<(const VertexTriangle& o) const { return std::tie(pm, p, tm, t) < std::tie(o.pm, o.p, o.tm, o.t); }
    bool operator==(const VertexTriangle& o) const { return std::tie(pm, p, tm, t) == std::tie(o.pm, o.p, o.tm, o.t); }
};

struct EdgeEdge {
    std::uint32_t am, a0, a1, bm, b0, b1; ///< mesh and (sorted) masses of each edge
    auto key() const { return std::tie(am, a0, a1, bm, b0, b1); }
    bool operator<(const EdgeEdge& o) const { return key() < o.key(); }
    bool operator==(const EdgeEdge& o) const { return key() == o.key(); }
};

/// Closest points of segments p0-p1 and q0-q1 (Ericson, Real-Time Collision Detection, 5.1.9).
double segmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, double& s, double& t) {
    const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
    const double a = dot(d1, d1), e = dot(d2, d2), f = dot(d2, r);
    const double eps = 1e-24;
    if (a <= eps && e <= eps) {
        s = t = 0.0;
        return length(p0 - q0);
    }
    if (a <= eps) {
        s = 0.0;
        t = std::clamp(f / e, 0.0, 1.0);
    } else {
        const double c = dot(d1, r);
        if (e <= eps) {
            t = 0.0;
            s = std::clamp(-c / a, 0.0, 1.0);
        } else {
            const double b = dot(d1, d2), denom = a * e - b * b;
            s = denom > eps ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
            t = (b * s + f) / e;
            if (t < 0.0) {
                t = 0.0;
                s = std::clamp(-c / a, 0.0, 1.0);
            } else if (t > 1.0) {
                t = 1.0;
                s = std::clamp((b - c) / a, 0.0, 1.0);
            }
        }
    }
    return length((p0 + d1 * s) - (q0 + d2 * t));
}

/// The roots in [0, 1] of c0 + c1 t + c2 t^2 + c3 t^3, ascending (bisection on monotone pieces).
int cubicRoots(const double c[4], double roots[3]) {
    auto f = [&](double t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; };
    const double scale = std::abs(c[0]) + std::abs(c[1]) + std::abs(c[2]) + std::abs(c[3]);
    if (scale == 0.0) {
        roots[0] = 0.0; // coplanar throughout: the proximity test at t = 0 decides
        return 1;
    }
    // split [0, 1] where the derivative c1 + 2 c2 t + 3 c3 t^2 vanishes
    double cuts[4] = {0.0, 1.0, 1.0, 1.0};
    int n = 1;
    const double a = 3.0 * c[3], b = 2.0 * c[2], cc = c[1];
    if (std::abs(a) > 1e-30 * scale) {
        const double disc = b * b - 4.0 * a * cc;
        if (disc >= 0.0) {
            const double sq = std::sqrt(disc);
            for (double r : {(-b - sq) / (2.0 * a), (-b + sq) / (2.0 * a)}) {
                if (r > 0.0 && r < 1.0) {
                    cuts[n++] = r;
                }
            }
        }
    } else if (std::abs(b) > 1e-30 * scale) {
        const double r = -cc / b;
        if (r > 0.0 && r < 1.0) {
            cuts[n++] = r;
        }
    }
    cuts[n++] = 1.0;
    // at most four: sorted by hand (std::sort here trips g++'s -Warray-bounds at -O2)
    for (int i = 1; i < n; ++i) {
        for (int j = i; j > 0 && cuts[j] < cuts[j - 1]; --j) {
            std::swap(cuts[j], cuts[j - 1]);
        }
    }
    int found = 0;
    for (int k = 0; k + 1 < n && found < 3; ++k) {
        double lo = cuts[k], hi = cuts[k + 1];
        double flo = f(lo), fhi = f(hi);
        if (flo == 0.0) {
            if (found == 0 || roots[found - 1] != lo) {
                roots[found++] = lo;
            }
            continue;
        }
        if ((flo < 0.0) == (fhi < 0.0)) {
            if (fhi == 0.0 && found < 3) {
                roots[found++] = hi;
            }
            continue;
        }
        for (int it = 0; it < 50; ++it) {
            const double mid = 0.5 * (lo + hi), fm = f(mid);
            if ((fm < 0.0) == (flo < 0.0)) {
                lo = mid;
                flo = fm;
            } else {
                hi = mid;
            }
        }
        roots[found++] = 0.5 * (lo + hi);
    }
    return found;
}

/// The coplanarity cubic of four moving points (x, displacement d over the step): (x1 - x0) . ((x2 - x0)
/// x (x3 - x0)) at time t in [0, 1].
void coplanarity(const Vec3 x[4], const Vec3 d[4], double c[4]) {
    const Vec3 A = x[1] - x[0], B = x[2] - x[0], C = x[3] - x[0];
    const Vec3 dA = d[1] - d[0], dB = d[2] - d[0], dC = d[3] - d[0];
    const Vec3 ab = cross(A, B), ab1 = cross(A, dB) + cross(dA, B), ab2 = cross(dA, dB);
    c[0] = dot(C, ab);
    c[1] = dot(dC, ab) + dot(C, ab1);
    c[2] = dot(dC, ab1) + dot(C, ab2);
    c[3] = dot(dC, ab2);
}

class Solver {
public:
    /// The pairs go into scratch kept from step to step (no allocation a step once it has grown).
    Solver(std::vector<Mesh>& meshes, std::vector<std::array<std::uint32_t, 2>>& pairs,
           std::vector<VertexTriangle>& vt, std::vector<EdgeEdge>& ee)
        : m_meshes(meshes), m_pairs(pairs), m_vt(vt), m_ee(ee) {
        m_vt.clear();
        m_ee.clear();
    }

    void gather() {
        for (std::uint32_t m = 0; m < m_meshes.size(); ++m) {
            m_pairs.clear();
            m_meshes[m].cc->tree.selfPairs(m_pairs);
            // triangles that share a corner are not skipped: their other vertices and edges may still
            // be a pair that only they report (the spring test leaves out what they hold in common)
            for (const auto& [i, j] : m_pairs) {
                addTrianglePair(m, i, m, j);
            }
            for (std::uint32_t o = m + 1; o < m_meshes.size(); ++o) {
                m_pairs.clear();
                m_meshes[m].cc->tree.pairsWith(m_meshes[o].cc->tree, m_pairs);
                for (const auto& [i, j] : m_pairs) {
                    addTrianglePair(m, i, o, j);
                }
            }
        }
        // the passes go through the pairs one after another, each seeing the last one's corrections, so
        // their order matters: in index order (grouped by point, then by edge) they settle where the
        // hierarchy's order left the pile demo with 14 crossed pairs of triangles
        std::sort(m_vt.begin(), m_vt.end());
        std::sort(m_ee.begin(), m_ee.end());
    }

    /// One pass of proximity repulsion; the number of pairs pushed apart.
    int proximity() {
        int pushed = 0;
        for (const VertexTriangle& c : m_vt) {
            Stencil s;
            Vec3 n;
            const double d = vtEnd(c, s, n);
            if (d < thickness(c.pm, c.tm)) {
                // pushed to the side it started on: back across the triangle if it went through
                const double depth = orient(s, n) ? thickness(c.pm, c.tm) + d : thickness(c.pm, c.tm) - d;
                respond(s, n, depth, friction(c.pm, c.tm));
                pushed += d < kSettled * thickness(c.pm, c.tm);
            }
        }
        for (const EdgeEdge& c : m_ee) {
            Stencil s;
            Vec3 n;
            const double d = eeEnd(c, s, n);
            if (d < thickness(c.am, c.bm)) {
                const double depth = orient(s, n) ? thickness(c.am, c.bm) + d : thickness(c.am, c.bm) - d;
                respond(s, n, depth, friction(c.am, c.bm));
                pushed += d < kSettled * thickness(c.am, c.bm);
            }
        }
        return pushed;
    }

    /// One pass of continuous tests; the number of crossings stopped.
    int continuous() {
        int stopped = 0;
        for (const VertexTriangle& c : m_vt) {
            const SpringNetwork& p = *m_meshes[c.pm].net;
            const SpringNetwork& t = *m_meshes[c.tm].net;
            const auto& tri = t.triangles[c.t];
            SpringNetwork* nets[4] = {m_meshes[c.pm].net, m_meshes[c.tm].net, m_meshes[c.tm].net, m_meshes[c.tm].net};
            const std::uint32_t idx[4] = {c.p, tri[0], tri[1], tri[2]};
            stopped += crossing(nets, idx, true, thickness(c.pm, c.tm));
            (void)p;
        }
        for (const EdgeEdge& c : m_ee) {
            SpringNetwork* nets[4] = {m_meshes[c.am].net, m_meshes[c.am].net, m_meshes[c.bm].net, m_meshes[c.bm].net};
            const std::uint32_t idx[4] = {c.a0, c.a1, c.b0, c.b1};
            stopped += crossing(nets, idx, false, thickness(c.am, c.bm));
        }
        return stopped;
    }

    std::size_t vtCount() const { return m_vt.size(); }
    std::size_t eeCount() const { return m_ee.size(); }

private:
    /// Masses i and j of one mesh are the same or corners of one triangle: their own springs keep them
    /// apart. (Any spring would leave out pairs two cells apart, which a tight fold brings together.)
    bool near(std::uint32_t m, std::uint32_t i, std::uint32_t j) const {
        if (i == j) {
            return true;
        }
        const ClothCollision& cc = *m_meshes[m].cc;
        const auto& list = cc.linked[i];
        return std::binary_search(list.begin(), list.end(), j);
    }

    /// Does the swept, inflated box of these masses overlap the box?
    bool sweptOverlaps(std::uint32_t m, std::initializer_list<std::uint32_t> masses, const Aabb& box) const {
        const Mesh& mesh = m_meshes[m];
        Aabb b;
        for (std::uint32_t i : masses) {
            b.add(mesh.net->x[i]);
            b.add(mesh.cc->previous[i]);
        }
        b.inflate(mesh.net->thickness);
        return b.overlaps(box);
    }

    /// The vertex-triangle and edge-edge pairs of two triangles, each pair once over the whole query: a
    /// vertex is taken only from the first triangle that holds it, an edge only from the first that has it
    /// (their boxes hold the vertex's and the edge's, so the query reports those triangles' pairs too).
    void addTrianglePair(std::uint32_t ma, std::uint32_t ta, std::uint32_t mb, std::uint32_t tb) {
        const Triangle& a = m_meshes[ma].net->triangles[ta];
        const Triangle& b = m_meshes[mb].net->triangles[tb];
        const ClothCollision& ca = *m_meshes[ma].cc;
        const ClothCollision& cb = *m_meshes[mb].cc;
        const bool same = ma == mb;
        // within one cloth, a mass that shares a triangle with a corner of the other (or an edge whose end
        // does with an end of the other edge) is its neighbour on the surface: left to the springs
        for (std::uint32_t p : a) {
            if (ca.vertexOwner[p] == ta && !(same && (near(ma, p, b[0]) || near(ma, p, b[1]) || near(ma, p, b[2]))) &&
                sweptOverlaps(ma, {p}, cb.boxes[tb])) {
                m_vt.push_back({ma, p, mb, tb});
            }
        }
        for (std::uint32_t p : b) {
            if (cb.vertexOwner[p] == tb && !(same && (near(ma, p, a[0]) || near(ma, p, a[1]) || near(ma, p, a[2]))) &&
                sweptOverlaps(mb, {p}, ca.boxes[ta])) {
                m_vt.push_back({mb, p, ma, ta});
            }
        }
        for (int i = 0; i < 3; ++i) {
            if (!(ca.edgeOwned[ta] & (1u << i))) {
                continue;
            }
            const std::uint32_t a0 = std::min(a[i], a[(i + 1) % 3]), a1 = std::max(a[i], a[(i + 1) % 3]);
            Aabb edgeA;
            for (std::uint32_t k : {a0, a1}) {
                edgeA.add(m_meshes[ma].net->x[k]);
                edgeA.add(ca.previous[k]);
            }
            edgeA.inflate(m_meshes[ma].net->thickness);
            for (int j = 0; j < 3; ++j) {
                if (!(cb.edgeOwned[tb] & (1u << j))) {
                    continue;
                }
                const std::uint32_t b0 = std::min(b[j], b[(j + 1) % 3]), b1 = std::max(b[j], b[(j + 1) % 3]);
                if (same && (near(ma, a0, b0) || near(ma, a0, b1) || near(ma, a1, b0) || near(ma, a1, b1))) {
                    continue;
                }
                if (sweptOverlaps(mb, {b0, b1}, edgeA)) {
                    m_ee.push_back({ma, a0, a1, mb, b0, b1});
                }
            }
        }
    }

    double thickness(std::uint32_t a, std::uint32_t b) const {
        return std::max(m_meshes[a].net->thickness, m_meshes[b].net->thickness);
    }
    double friction(std::uint32_t a, std::uint32_t b) const {
        return std::sqrt(m_meshes[a].net->friction * m_meshes[b].net->friction);
    }

    /// Vertex-triangle distance at the end of the step: the stencil, and the normal from the triangle to
    /// the point (on the side the point was on when the step began).
    double vtEnd(const VertexTriangle& c, Stencil& s, Vec3& n) const {
        SpringNetwork* pn = m_meshes[c.pm].net;
        SpringNetwork* tn = m_meshes[c.tm].net;
        const auto& tri = tn->triangles[c.t];
        double w[3];
        const Vec3& p = pn->x[c.p];
        const double d = pointTriangleDistance(p, tn->x[tri[0]], tn->x[tri[1]], tn->x[tri[2]], w);
        s = {{pn, tn, tn, tn}, {c.p, tri[0], tri[1], tri[2]}, {1.0, -w[0], -w[1], -w[2]}};
        const Vec3 q = s.sum(&SpringNetwork::x);
        n = d > 1e-12 ? q * (1.0 / d) : faceNormal(*tn, tri, *m_meshes[c.pm].cc, c.p, *m_meshes[c.tm].cc, *pn);
        return d;
    }

    double eeEnd(const EdgeEdge& c, Stencil& s, Vec3& n) const {
        SpringNetwork* an = m_meshes[c.am].net;
        SpringNetwork* bn = m_meshes[c.bm].net;
        double u = 0.0, v = 0.0;
        const double d = segmentDistance(an->x[c.a0], an->x[c.a1], bn->x[c.b0], bn->x[c.b1], u, v);
        s = {{an, an, bn, bn}, {c.a0, c.a1, c.b0, c.b1}, {1.0 - u, u, -(1.0 - v), -v}};
        const Vec3 q = s.sum(&SpringNetwork::x);
        if (d > 1e-12) {
            n = q * (1.0 / d);
        } else {
            n = cross(an->x[c.a1] - an->x[c.a0], bn->x[c.b1] - bn->x[c.b0]);
            const double len = length(n);
            n = len > 0.0 ? n * (1.0 / len) : Vec3{0.0, 1.0, 0.0};
        }
        return d;
    }

    /// The triangle's unit normal, turned towards where the point was at the start of the step.
    static Vec3 faceNormal(const SpringNetwork& tn, const Triangle& tri, const ClothCollision& pc, std::uint32_t p,
                           const ClothCollision& tc, const SpringNetwork&) {
        Vec3 n = cross(tn.x[tri[1]] - tn.x[tri[0]], tn.x[tri[2]] - tn.x[tri[0]]);
        n = n * (1.0 / std::max(length(n), 1e-300));
        if (dot(pc.previous[p] - tc.previous[tri[0]], n) < 0.0) {
            n = -n;
        }
        return n;
    }

    /// Turns n towards the side the pair began the step on; true when it ends on the other side (so the
    /// push must also undo the crossing).
    bool orient(const Stencil& s, Vec3& n) const {
        Vec3 start;
        for (int k = 0; k < 4; ++k) {
            start += ownerOf(s.net[k])->previous[s.idx[k]] * s.w[k];
        }
        if (dot(start, n) < 0.0) {
            n = -n;
            return true;
        }
        return false;
    }

    /// Pushes a contact apart by `depth` along n, removes its approach speed and applies friction.
    void respond(const Stencil& s, const Vec3& n, double depth, double mu) const {
        s.apply(&SpringNetwork::x, n * depth);
        const Vec3 vr = s.sum(&SpringNetwork::v);
        const double vn = dot(vr, n);
        if (vn >= 0.0) {
            return;
        }
        Vec3 dv = n * -vn;
        const Vec3 vt = vr - n * vn;
        const double speed = length(vt);
        if (speed > 0.0) {
            dv -= vt * (std::min(speed, mu * -vn) / speed);
        }
        s.apply(&SpringNetwork::v, dv);
    }

    /// Continuous test of four moving points (vertex-triangle: point, then the triangle; edge-edge: the two
    /// edges) over the step; stops the first crossing. Returns 1 if it stopped one.
    int crossing(SpringNetwork* const nets[4], const std::uint32_t idx[4], bool vertexTriangle, double h) const {
        Vec3 x0[4], d[4];
        for (int k = 0; k < 4; ++k) {
            const ClothCollision& cc = *ownerOf(nets[k]);
            x0[k] = cc.previous[idx[k]];
            d[k] = nets[k]->x[idx[k]] - x0[k];
        }
        // no crossing is possible when the pair starts farther apart than its points can move
        {
            double start;
            if (vertexTriangle) {
                double b[3];
                start = pointTriangleDistance(x0[0], x0[1], x0[2], x0[3], b);
            } else {
                double u = 0.0, v = 0.0;
                start = segmentDistance(x0[0], x0[1], x0[2], x0[3], u, v);
            }
            double reachA = 0.0, reachB = 0.0;
            for (int k = 0; k < 4; ++k) {
                (vertexTriangle ? (k == 0) : (k < 2) ? true : false) ? reachA = std::max(reachA, length(d[k]))
                                                                      : reachB = std::max(reachB, length(d[k]));
            }
            if (start > reachA + reachB) {
                return 0;
            }
        }
        double c[4], roots[3];
        coplanarity(x0, d, c);
        const int n = cubicRoots(c, roots);
        for (int r = 0; r < n; ++r) {
            const double t = roots[r];
            Vec3 xt[4];
            for (int k = 0; k < 4; ++k) {
                xt[k] = x0[k] + d[k] * t;
            }
            double w[4];
            double dist;
            Vec3 normal;
            if (vertexTriangle) {
                double b[3];
                dist = pointTriangleDistance(xt[0], xt[1], xt[2], xt[3], b);
                w[0] = 1.0;
                w[1] = -b[0];
                w[2] = -b[1];
                w[3] = -b[2];
                normal = cross(xt[2] - xt[1], xt[3] - xt[1]);
            } else {
                double u = 0.0, v = 0.0;
                dist = segmentDistance(xt[0], xt[1], xt[2], xt[3], u, v);
                w[0] = 1.0 - u;
                w[1] = u;
                w[2] = -(1.0 - v);
                w[3] = -v;
                normal = cross(xt[1] - xt[0], xt[3] - xt[2]);
            }
            if (dist > 1e-3 * h) {
                continue; // coplanar, but apart
            }
            const double len = length(normal);
            if (len <= 1e-300) {
                continue;
            }
            normal = normal * (1.0 / len);
            Stencil s{{nets[0], nets[1], nets[2], nets[3]}, {idx[0], idx[1], idx[2], idx[3]}, {w[0], w[1], w[2], w[3]}};
            Vec3 q0;
            for (int k = 0; k < 4; ++k) {
                q0 += x0[k] * w[k];
            }
            if (dot(q0, normal) < 0.0) {
                normal = -normal; // towards the side the pair started on
            }
            const double end = dot(s.sum(&SpringNetwork::x), normal);
            const double gap = kGapFraction * h;
            if (end >= gap) {
                return 0;
            }
            // stop the crossing: the end separation back to the gap, and the approach speed gone
            s.apply(&SpringNetwork::x, normal * (gap - end));
            const double vn = dot(s.sum(&SpringNetwork::v), normal);
            if (vn < 0.0) {
                s.apply(&SpringNetwork::v, normal * -vn);
            }
            return 1;
        }
        return 0;
    }

    const ClothCollision* ownerOf(const SpringNetwork* net) const {
        for (const Mesh& m : m_meshes) {
            if (m.net == net) {
                return m.cc;
            }
        }
        return nullptr;
    }

    std::vector<Mesh>& m_meshes;
    std::vector<std::array<std::uint32_t, 2>>& m_pairs;
    std::vector<VertexTriangle>& m_vt;
    std::vector<EdgeEdge>& m_ee;
};

/// What one step of the system leaves for the next to reuse: the lists it fills.
struct ClothScratch {
    std::vector<Mesh> meshes;
    std::vector<std::array<std::uint32_t, 2>> pairs;
    std::vector<VertexTriangle> vt;
    std::vector<EdgeEdge> ee;
};

} // namespace

double pointTriangleDistance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, double w[3]) {
    // Ericson, Real-Time Collision Detection, 5.1.5, with the barycentric weights of the closest point
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    auto done = [&](double u, double v, double x) {
        w[0] = u;
        w[1] = v;
        w[2] = x;
        return length(p - (a * u + b * v + c * x));
    };
    if (d1 <= 0.0 && d2 <= 0.0) {
        return done(1, 0, 0);
    }
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        return done(0, 1, 0);
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        return done(1 - v, v, 0);
    }
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        return done(0, 0, 1);
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double x = d2 / (d2 - d6);
        return done(1 - x, 0, x);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double x = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return done(0, 1 - x, x);
    }
    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, x = vc * denom;
    return done(1 - v - x, v, x);
}

namespace {

/// Does segment pq meet triangle abc (boundaries included)?
bool segmentMeetsTriangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 n = cross(b - a, c - a);
    const double dp = dot(p - a, n), dq = dot(q - a, n);
    if ((dp > 0.0 && dq > 0.0) || (dp < 0.0 && dq < 0.0) || dp == dq) {
        return false; // both on one side, or parallel (coplanar contact is not looked for)
    }
    const Vec3 x = p + (q - p) * (dp / (dp - dq));
    // inside: on the inner side of every edge
    const double e0 = dot(cross(b - a, x - a), n), e1 = dot(cross(c - b, x - b), n),
                 e2 = dot(cross(a - c, x - c), n);
    return (e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0) || (e0 <= 0.0 && e1 <= 0.0 && e2 <= 0.0);
}

} // namespace

bool trianglesIntersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                        const Vec3& b2) {
    const Vec3 a[3] = {a0, a1, a2}, b[3] = {b0, b1, b2};
    for (int i = 0; i < 3; ++i) {
        if (segmentMeetsTriangle(a[i], a[(i + 1) % 3], b0, b1, b2) ||
            segmentMeetsTriangle(b[i], b[(i + 1) % 3], a0, a1, a2)) {
            return true;
        }
    }
    return false;
}

void collideCloth(World& world, const StepContext& ctx) {
    ClothScratch* kept = world.tryResource<ClothScratch>();
    ClothScratch& scratch = kept ? *kept : world.setResource<ClothScratch>();
    std::vector<Mesh>& meshes = scratch.meshes;
    meshes.clear();
    world.view<SpringNetwork>().each([&](Entity e, SpringNetwork& net) {
        if (!net.selfCollision || net.frozen || net.triangles.empty()) {
            return;
        }
        ClothCollision* cc = world.tryGet<ClothCollision>(e);
        if (!cc) {
            // the first step: where the masses were before it, from their velocities
            ClothCollision fresh;
            fresh.previous.resize(net.x.size());
            for (std::size_t i = 0; i < net.x.size(); ++i) {
                fresh.previous[i] = net.x[i] - net.v[i] * ctx.dt;
            }
            world.commands().emplace(e, std::move(fresh));
            return; // from the next step on (the component arrives at the end of this phase)
        }
        meshes.push_back({&net, cc});
    });
    if (meshes.empty()) {
        return;
    }
    // refit (or build) each mesh's tree over its swept, inflated triangles
    for (Mesh& m : meshes) {
        ClothCollision& cc = *m.cc;
        if (cc.previous.size() != m.net->x.size()) {
            cc.previous = m.net->x;
        }
        if (cc.vertexOwner.size() != m.net->x.size() || cc.edgeOwned.size() != m.net->triangles.size()) {
            // the first triangle of each vertex and of each edge: the one that answers for it in queries
            const auto& tris = m.net->triangles;
            cc.vertexOwner.assign(m.net->x.size(), ~0u);
            cc.edgeOwned.assign(tris.size(), 0);
            std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t, int>> edges;
            for (std::uint32_t t = 0; t < tris.size(); ++t) {
                for (int k = 0; k < 3; ++k) {
                    cc.vertexOwner[tris[t][k]] = std::min(cc.vertexOwner[tris[t][k]], t);
                    const std::uint32_t u = tris[t][k], v = tris[t][(k + 1) % 3];
                    edges.emplace_back(std::min(u, v), std::max(u, v), t, k);
                }
            }
            std::sort(edges.begin(), edges.end());
            for (std::size_t e = 0; e < edges.size(); ++e) {
                const auto& [u, v, t, k] = edges[e];
                if (e == 0 || std::get<0>(edges[e - 1]) != u || std::get<1>(edges[e - 1]) != v) {
                    cc.edgeOwned[t] = std::uint8_t(cc.edgeOwned[t] | (1u << k));
                }
            }
        }
        if (cc.linked.size() != m.net->x.size()) {
            cc.linked.assign(m.net->x.size(), {});
            for (const Triangle& t : m.net->triangles) {
                for (int a = 0; a < 3; ++a) {
                    for (int b = 0; b < 3; ++b) {
                        if (a != b) {
                            cc.linked[t[a]].push_back(t[b]);
                        }
                    }
                }
            }
            for (auto& list : cc.linked) {
                std::sort(list.begin(), list.end());
                list.erase(std::unique(list.begin(), list.end()), list.end());
            }
        }
        cc.boxes.resize(m.net->triangles.size());
        std::vector<Vec3>& sweep = cc.previous; // box over previous and current: previous + (x - previous)
        for (std::size_t t = 0; t < m.net->triangles.size(); ++t) {
            Aabb b = triangleBox(m.net->triangles[t], m.net->x, {}, 0.0);
            b.add(triangleBox(m.net->triangles[t], sweep, {}, 0.0));
            b.inflate(m.net->thickness);
            cc.boxes[t] = b;
        }
        if (cc.tree.empty()) {
            cc.tree.build(cc.boxes);
        } else if (!cc.tree.refit(cc.boxes)) {
            cc.tree.build(cc.boxes);
            ++cc.rebuilds;
        }
    }
    Solver solver(meshes, scratch.pairs, scratch.vt, scratch.ee);
    solver.gather();
    // pushing one pair apart can press another together: a few passes of each; the crossings stopped
    // keep only a small gap, so the repulsion passes come again after them
    auto repel = [&] {
        for (int pass = 0; pass < kProximityPasses; ++pass) {
            if (solver.proximity() == 0) {
                break;
            }
        }
    };
    repel();
    for (int pass = 0; pass < kContinuousPasses; ++pass) {
        if (solver.continuous() == 0) {
            break;
        }
    }
    repel();
    for (Mesh& m : meshes) {
        m.cc->previous = m.net->x;
    }
}

void registerClothCollisionSystem(Catalog& catalog) {
    catalog.addSystem(Phase::Fixed, "cloth_collision", collideCloth);
}

} // namespace tumble
