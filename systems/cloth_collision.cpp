#include "systems/cloth_collision.h"

#include "components/rigid_body.h"
#include "components/spring_network.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/run_report.h"
#include "systems/ccd.h"
#include "systems/cloth_untangle.h"
#include "systems/collision_system.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <tuple>

namespace tumble {

namespace {

constexpr int kProximityPasses = 3;
constexpr double kSettled = 0.99; ///< a pair pushed from closer than this fraction of the thickness counts
constexpr int kContinuousPasses = 4;
constexpr double kGapFraction = 0.1; ///< a stopped contact is left this fraction of the thickness apart
/// the continuous tests look for approaches closer than this fraction of the thickness
constexpr double kDetectFraction = 0.05;
/// A mass may move this many of its thicknesses from where its candidate pairs were gathered before they
/// are gathered again (the boxes are inflated to match: a larger margin gathers less often, with more pairs;
/// physics p99 of the pile demo 7.4 ms a frame at a half, 8.4 at three quarters, 10.9 at one)
constexpr double kDriftFraction = 0.5;
constexpr double kRestingFraction = 1.25; ///< a mass this close to a collider (in thicknesses) rests on it
constexpr int kProjectionRounds = 6;
constexpr int kProjectionIterations = 64;
constexpr int kZoneRounds = 8;
constexpr int kFreezeRounds = 16;
constexpr double kMaxAmplification = 4.0; ///< a contact may move no point more than this times its own change
constexpr int kUntangleIterations = 4;    ///< rounds of untangling a step while a cloth is tangled
constexpr double kUntangleStep = 0.25;    ///< the most one of them moves a mass, in its cloth's edge lengths
constexpr std::uint64_t kTangledPatience = 120; ///< steps tangled before a cloth is said to be stuck

/// A self-colliding network in this step's flat arrays.
struct Mesh {
    Entity entity;
    SpringNetwork* net = nullptr;
    ClothCollision* cc = nullptr;
    const Name* name = nullptr;
    std::uint32_t vertexOffset = 0;
    std::uint32_t triangleOffset = 0;
};

struct VertexTriangle {
    std::uint32_t p, t;     ///< vertex and triangle, global
    bool restClose = false; ///< closer than the thickness at rest: kept from crossing, not repelled
    auto key() const { return std::tie(p, t); }
    bool operator<(const VertexTriangle& o) const { return key() < o.key(); }
};

struct EdgeEdge {
    std::uint32_t a0, a1, b0, b1; ///< the two edges' vertices, global, each edge sorted
    bool restClose = false;       ///< as VertexTriangle::restClose
    auto key() const { return std::tie(a0, a1, b0, b1); }
    bool operator<(const EdgeEdge& o) const { return key() < o.key(); }
};

/// Up to four vertices whose weighted sum q = sum w_k x_k is the separation of a contact: a point minus
/// the closest point of a triangle, or a point of one edge minus the closest point of the other.
struct Stencil {
    std::uint32_t i[4];
    double w[4];
};

/// A contact kept by the inelastic projection: q . n must stay at least `gap`.
struct Constraint {
    Stencil s;
    Vec3 n;
    double gap;
};

} // namespace

/// The candidates one chunk of a parallel gathering found, and its query scratch.
struct Found {
    std::vector<VertexTriangle> vt;
    std::vector<EdgeEdge> ee;
    std::vector<std::uint32_t> near;
};

/// The per-step arrays, kept from step to step so that a step allocates nothing once they have grown.
struct ClothScratch {
    std::vector<Mesh> meshes;
    std::vector<Entity> layout;       ///< the meshes the global arrays were laid out for
    std::vector<std::uint32_t> sizes; ///< and their vertex and triangle counts
    // per vertex
    /// start, current, candidate (as the step left it), velocity, where its pairs were last gathered
    std::vector<Vec3> x0, x, xc, v, xg;
    /// how far a mass may move from where it is now while the candidate pairs hold: its margin
    /// (kDriftFraction of its thickness) plus how far it already is from where its pairs were gathered
    std::vector<double> allow;
    std::vector<std::uint64_t> gatheredAt; ///< the step its pairs were last gathered in
    std::vector<double> w;                 ///< inverse mass for contacts: 0 when pinned
    std::vector<Vec3> seat;                ///< the outward normal of the collider a mass rests on
    std::vector<std::uint8_t> seated;      ///< 1 when the mass rests on a collider
    std::vector<std::uint32_t> meshOf;
    std::vector<std::uint32_t> vertexOwner; ///< the first triangle that holds the vertex
    std::vector<std::uint32_t> parent;      ///< impact zones: union-find
    // per triangle
    std::vector<Triangle> tris;
    std::vector<std::uint8_t> edgeOwned; ///< bit k: the first triangle with edge k
    std::vector<Aabb> boxes;             ///< swept, inflated by the thickness
    std::vector<Aabb> vertexBoxes;       ///< per vertex, the same
    Bvh tree;
    // per step
    std::vector<std::array<std::uint32_t, 2>> pairs;
    std::vector<std::uint32_t> stale, near; ///< masses whose pairs are gathered again; a query's triangles
    std::vector<std::uint8_t> staleMark, triangleMark;
    std::uint64_t step = 0;
    std::vector<VertexTriangle> vt;
    std::vector<EdgeEdge> ee;
    std::vector<Constraint> constraints;
    std::vector<Constraint> hits;                 ///< contacts found by a collecting pass
    std::vector<std::uint32_t> nearVt, nearEe;    ///< candidates within twice the thickness (proximity)
    std::vector<std::uint8_t> moved, movedBefore; ///< per vertex: moved during this continuous pass, the last
    std::vector<std::uint8_t> touched; ///< per vertex: x written by a response in this continuous pass
    std::vector<Found> chunkFound;     ///< per chunk of a parallel gathering (engine/parallel.h)
    std::vector<std::uint8_t> maybe;   ///< per candidate of a continuous pass: detected ahead within reach
    bool testAll = true;               ///< the next continuous pass tests every candidate
    std::vector<std::uint32_t> members;
    std::vector<std::uint8_t> joined; ///< per vertex: in an impact zone
    /// pairs within one cloth closer than its thickness at rest
    std::vector<VertexTriangle> restVertexTriangle;
    std::vector<EdgeEdge> restEdgeEdge;
    /// the primitive pairs of triangles that share a vertex: their boxes always overlap, so they are listed
    /// once with the layout and measured at each gathering rather than found in the tree
    std::vector<VertexTriangle> ringVt;
    std::vector<EdgeEdge> ringEe;
    std::vector<double> spacing; ///< per mesh: its mean edge length at rest
    // tangles (cloth that is crossed already, untangled: systems/cloth_untangle.h)
    bool startChecked = false; ///< this layout's first step has been looked at for crossings
    std::vector<std::array<std::uint32_t, 2>> tangled; ///< crossed pairs of triangles, sorted, as last found
    std::vector<std::array<std::uint32_t, 2>> found;   ///< a search for them in progress
    std::vector<std::uint8_t> flagged; ///< per vertex: a corner of a tangled triangle this step
    /// per vertex: moved back through the cloth by the untangling this step
    std::vector<std::uint8_t> pushed;
    std::vector<std::uint8_t> held; ///< per vertex: pinned, or resting on a collider (not to be moved)
    bool anyFlagged = false;
    VertexGraph graph; ///< the meshes' edges, for the regions
    RegionChoice choice;
    std::vector<Vec3> grad;       ///< per vertex: the contour length's gradient
    std::vector<Aabb> crossBoxes; ///< per triangle, unswept, for the search
    Bvh crossTree;
    std::uint64_t tangledSteps = 0; ///< steps in a row that began tangled
    bool kinematic = false;         ///< a pinned (or anchored) mass moved during this step
};

namespace {

/// A rotation by the vector a (angle |a| about a / |a|) applied to r (Rodrigues).
Vec3 rotateBy(const Vec3& a, const Vec3& r) {
    const double angle = length(a);
    if (angle < 1e-300) {
        return r;
    }
    const Vec3 k = a * (1.0 / angle);
    const double c = std::cos(angle), s = std::sin(angle);
    return r * c + cross(k, r) * s + k * (dot(k, r) * (1.0 - c));
}

bool shareVertex(const Triangle& a, const Triangle& b) {
    for (std::uint32_t i : a) {
        if (i == b[0] || i == b[1] || i == b[2]) {
            return true;
        }
    }
    return false;
}

/// Does the untangling answer for a pair of primitives, each side of which has a corner of a tangled
/// triangle (flagged) or a mass of a region moved back through the cloth (pushed), or neither? Between two
/// tangled parts, and between a region moving back and a tangled part (the triangles it passes through).
/// A region moving back keeps its contacts with everything else, its own masses and other cloths included.
bool untangledPair(bool flaggedA, bool pushedA, bool flaggedB, bool pushedB) {
    return (flaggedA || pushedA) && (flaggedB || pushedB) && (flaggedA || flaggedB);
}

/// A crossed pair of triangles the untangling answers for (see untangledPair), not a failure of contact.
bool excused(const ClothScratch& s, const std::array<std::uint32_t, 2>& pair) {
    bool flagged[2] = {false, false}, pushed[2] = {false, false};
    for (int k = 0; k < 2; ++k) {
        for (std::uint32_t v : s.tris[pair[k]]) {
            flagged[k] = flagged[k] || s.flagged[v];
            pushed[k] = pushed[k] || s.pushed[v];
        }
    }
    return untangledPair(flagged[0], pushed[0], flagged[1], pushed[1]);
}

/// The pairs of triangles that share no vertex and intersect at positions x (an exact test: CGAL's
/// predicates), sorted, into out; with `excusedOnly`, those the untangling answers for alone (the others
/// are left out before the exact test).
void findCrossings(ClothScratch& s, const std::vector<Vec3>& x,
                   std::vector<std::array<std::uint32_t, 2>>& out, bool excusedOnly = false) {
    s.crossBoxes.resize(s.tris.size());
    for (std::size_t t = 0; t < s.tris.size(); ++t) {
        Aabb b;
        for (std::uint32_t k : s.tris[t]) {
            b.add(x[k]);
        }
        s.crossBoxes[t] = b;
    }
    if (s.crossTree.empty() || !s.crossTree.refit(s.crossBoxes)) {
        s.crossTree.build(s.crossBoxes);
    }
    out.clear();
    s.crossTree.selfPairs(out);
    std::erase_if(out, [&](const std::array<std::uint32_t, 2>& p) {
        const Triangle& a = s.tris[p[0]];
        const Triangle& b = s.tris[p[1]];
        return shareVertex(a, b) || (excusedOnly && !excused(s, p)) ||
               !trianglesIntersect(x[a[0]], x[a[1]], x[a[2]], x[b[0]], x[b[1]], x[b[2]]);
    });
    std::sort(out.begin(), out.end());
}

/// Calls onVertexTriangle(p, t) and onEdgeEdge(EdgeEdge) for the primitive pairs of triangles ta and tb
/// that the rule (cloth_collision.h) makes candidates, such that over all pairs of triangles each
/// primitive pair comes once: a vertex is answered for by its first triangle (vertexOwner) and an edge by
/// its first (edgeOwned), so (vertex, triangle) comes from (its owner, triangle) and (edge, edge) from
/// (owner, owner).
template <class OnVertexTriangle, class OnEdgeEdge>
void forEachPrimitivePair(const ClothScratch& s, std::uint32_t ta, std::uint32_t tb,
                          OnVertexTriangle&& onVertexTriangle, OnEdgeEdge&& onEdgeEdge) {
    for (const auto& [from, to] : {std::pair{ta, tb}, std::pair{tb, ta}}) {
        const Triangle& b = s.tris[to];
        for (std::uint32_t p : s.tris[from]) {
            if (s.vertexOwner[p] == from && p != b[0] && p != b[1] && p != b[2]) {
                onVertexTriangle(p, to);
            }
        }
    }
    const Triangle& a = s.tris[ta];
    const Triangle& b = s.tris[tb];
    for (int i = 0; i < 3; ++i) {
        if (!(s.edgeOwned[ta] & (1u << i))) {
            continue;
        }
        const std::uint32_t a0 = std::min(a[i], a[(i + 1) % 3]), a1 = std::max(a[i], a[(i + 1) % 3]);
        for (int j = 0; j < 3; ++j) {
            if (!(s.edgeOwned[tb] & (1u << j))) {
                continue;
            }
            const std::uint32_t b0 = std::min(b[j], b[(j + 1) % 3]), b1 = std::max(b[j], b[(j + 1) % 3]);
            if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1) {
                continue;
            }
            // ordered by the lower edge first
            onEdgeEdge(std::tie(a0, a1) < std::tie(b0, b1) ? EdgeEdge{a0, a1, b0, b1}
                                                           : EdgeEdge{b0, b1, a0, a1});
        }
    }
}

class Contact {
public:
    Contact(ClothScratch& s, const StepContext& ctx) : m_s(s), m_ctx(ctx) {}

    // ---- stencils -------------------------------------------------------------------------------------

    /// Changes q of the stencil by dq in `field`, shared by inverse mass and weight. A mass resting on a
    /// collider takes no share that would push it into the collider (it is of infinite mass that way, free
    /// along the surface). False when the free points carry too small a share to move it: a free corner of
    /// small weight beside held ones would be thrown by dq divided by its weight (one such push sent a
    /// mass 3 m). Left to the zones.
    bool apply(std::vector<Vec3>& field, const Stencil& st, const Vec3& dq) const {
        double inv[4];
        double m = 0.0;
        const double size = length(dq);
        for (int k = 0; k < 4; ++k) {
            const std::uint32_t i = st.i[k];
            inv[k] = m_s.w[i];
            if (inv[k] > 0.0 && m_s.seated[i] &&
                dot(dq, m_s.seat[i]) * st.w[k] < -0.1 * size * std::abs(st.w[k])) {
                inv[k] = 0.0;
            }
            m += st.w[k] * st.w[k] * inv[k];
        }
        if (!(m > 0.0)) {
            return false;
        }
        // how far the most moved point goes, per unit of dq
        double amplification = 0.0;
        for (int k = 0; k < 4; ++k) {
            amplification = std::max(amplification, std::abs(st.w[k]) * inv[k] / m);
        }
        if (amplification > kMaxAmplification) {
            return false;
        }
        const Vec3 j = dq * (1.0 / m);
        for (int k = 0; k < 4; ++k) {
            field[st.i[k]] += j * (st.w[k] * inv[k]);
            if (&field == &m_s.x) {
                if (inv[k] > 0.0) {
                    m_s.moved[st.i[k]] = 1;
                }
                // written, if only by adding zero (which can turn -0 into +0): a continuous pass's
                // detection run ahead no longer holds for this mass's pairs
                if (!m_s.touched.empty()) {
                    m_s.touched[st.i[k]] = 1;
                }
            }
        }
        return true;
    }

    Vec3 sum(const std::vector<Vec3>& field, const Stencil& st) const {
        Vec3 q;
        for (int k = 0; k < 4; ++k) {
            q += field[st.i[k]] * st.w[k];
        }
        return q;
    }

    /// The distance kept between two masses' surfaces: half of each one's thickness (each sheet is as
    /// thick on either side of its mid-surface), so a cloth keeps its own thickness from itself.
    double thickness(std::uint32_t a, std::uint32_t b) const {
        return 0.5 * (mesh(a).net->thickness + mesh(b).net->thickness);
    }
    double friction(std::uint32_t a, std::uint32_t b) const {
        return std::sqrt(mesh(a).net->friction * mesh(b).net->friction);
    }
    const Mesh& mesh(std::uint32_t vertex) const { return m_s.meshes[m_s.meshOf[vertex]]; }

    // ---- refit and pairs ------------------------------------------------------------------------------

    /// Boxes swept from the start of the step to now, inflated by half the thickness and the distance the
    /// mass may still move (so that two primitives whose boxes do not overlap stay a thickness apart for as
    /// long as the candidates are kept); the tree refitted.
    void refit() {
        m_s.vertexBoxes.resize(m_s.x.size());
        for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
            Aabb b;
            b.add(m_s.x0[i]);
            b.add(m_s.x[i]);
            b.inflate(0.5 * mesh(i).net->thickness + m_s.allow[i]);
            m_s.vertexBoxes[i] = b;
        }
        for (std::size_t t = 0; t < m_s.tris.size(); ++t) {
            Aabb b = m_s.vertexBoxes[m_s.tris[t][0]];
            b.add(m_s.vertexBoxes[m_s.tris[t][1]]);
            b.add(m_s.vertexBoxes[m_s.tris[t][2]]);
            m_s.boxes[t] = b;
        }
        if (m_s.tree.empty() || !m_s.tree.refit(m_s.boxes)) {
            m_s.tree.build(m_s.boxes);
        }
    }

    /// The candidate pairs of the rule in the header, each once: every mass's pairs gathered afresh.
    void gather() {
        m_s.vt.clear();
        m_s.ee.clear();
        m_s.pairs.clear();
        m_s.tree.selfPairs(m_s.pairs);
        // the pairs of triangles in chunks on the pool's threads, each chunk's candidates appended in
        // chunk order: the list of a serial pass, in its order
        forChunksInOrder(m_s.pairs.size(), [&](std::size_t first, std::size_t end, Found& out) {
            for (std::size_t k = first; k < end; ++k) {
                const auto& [i, j] = m_s.pairs[k];
                if (!shareVertex(m_s.tris[i], m_s.tris[j])) {
                    addTrianglePair(i, j, false, out);
                }
            }
        });
        addRingPairs(false);
        // in the tree's order (fixed by the tree, so the same every run): sorting them into index order cost
        // a tenth of the pile demo's whole run, and the fail-safe no longer depends on the order to settle
    }

    /// The pairs of the stale masses (m_s.staleMark) gathered again, the others kept: the pairs with a stale
    /// mass in them are dropped, then every triangle with a stale corner is looked up in the tree and, of
    /// the primitive pairs of each pair of triangles found, those with a stale mass are added. (Each
    /// primitive pair comes from one pair of triangles, as in `gather`, the one of its vertex's or first
    /// edge's owning triangle: a pair with a stale mass has a stale corner in one of those two triangles.)
    void gatherAround() {
        const auto& stale = m_s.staleMark;
        std::erase_if(m_s.vt, [&](const VertexTriangle& c) {
            const Triangle& t = m_s.tris[c.t];
            return stale[c.p] || stale[t[0]] || stale[t[1]] || stale[t[2]];
        });
        std::erase_if(m_s.ee, [&](const EdgeEdge& c) {
            return stale[c.a0] || stale[c.a1] || stale[c.b0] || stale[c.b1];
        });
        auto& marked = m_s.triangleMark;
        marked.resize(m_s.tris.size());
        for (std::size_t t = 0; t < m_s.tris.size(); ++t) {
            const Triangle& tri = m_s.tris[t];
            marked[t] = stale[tri[0]] || stale[tri[1]] || stale[tri[2]];
        }
        forChunksInOrder(m_s.tris.size(), [&](std::size_t first, std::size_t end, Found& out) {
            for (std::size_t ta = first; ta < end; ++ta) {
                if (!marked[ta]) {
                    continue;
                }
                out.near.clear();
                m_s.tree.overlapping(m_s.boxes[ta], out.near);
                for (std::uint32_t tb : out.near) {
                    // a pair of two marked triangles is found from both: taken from the lower
                    if (tb != ta && !(marked[tb] && tb < ta) && !shareVertex(m_s.tris[ta], m_s.tris[tb])) {
                        addTrianglePair(std::uint32_t(ta), tb, true, out);
                    }
                }
            }
        });
        addRingPairs(true);
    }

    /// Runs body(first, end, found) over chunks of [0, n) on the pool's threads, each chunk collecting its
    /// candidates in its own lists, then appends the lists to m_s.vt and m_s.ee in chunk order.
    template <class Body>
    void forChunksInOrder(std::size_t n, Body&& body) {
        constexpr std::size_t kGrain = 512;
        const std::size_t chunks = WorkerPool::chunkCount(n, kGrain);
        if (m_s.chunkFound.size() < chunks) {
            m_s.chunkFound.resize(chunks);
        }
        poolOr(m_ctx.pool).forChunks(n, kGrain, [&](std::size_t c, std::size_t first, std::size_t end) {
            Found& out = m_s.chunkFound[c];
            out.vt.clear();
            out.ee.clear();
            body(first, end, out);
        });
        for (std::size_t c = 0; c < chunks; ++c) {
            m_s.vt.insert(m_s.vt.end(), m_s.chunkFound[c].vt.begin(), m_s.chunkFound[c].vt.end());
            m_s.ee.insert(m_s.ee.end(), m_s.chunkFound[c].ee.begin(), m_s.chunkFound[c].ee.end());
        }
    }

    /// The masses that have moved farther than their margin from where their pairs were gathered, at either
    /// end of the step (where the step began is covered by the boxes swept over the step when they were
    /// gathered in this one), into m_s.stale and m_s.staleMark; their count.
    /// Boxes of two primitives a distance D apart overlap while D is at most half of each one's thickness
    /// plus how far each may move (`refit`), so primitives left out stay a thickness apart, and `farApart`
    /// keeps the same bound for the pairs it leaves out. (A mass pressed into a layer by its springs moves
    /// farther than its margin every step before the contacts put it back: only its own pairs are gathered
    /// again.) The drift is measured as a distance, not per axis, so that `farApart` can count on it in any
    /// direction.
    std::size_t findStale() {
        m_s.stale.clear();
        m_s.staleMark.assign(m_s.x.size(), 0);
        const bool fresh = m_s.xg.size() != m_s.x.size();
        for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
            bool moved = fresh;
            if (!moved) {
                const double margin = kDriftFraction * mesh(i).net->thickness;
                const Vec3 d = m_s.x[i] - m_s.xg[i];
                const Vec3 d0 = m_s.x0[i] - m_s.xg[i];
                moved = dot(d, d) > margin * margin ||
                        (m_s.gatheredAt[i] != m_s.step && dot(d0, d0) > margin * margin);
            }
            if (moved) {
                m_s.stale.push_back(i);
                m_s.staleMark[i] = 1;
            }
        }
        return m_s.stale.size();
    }

    /// Gathers again when the candidates no longer cover where the masses are: every pair when many masses
    /// have moved out of their margins (or the layout is new), else the pairs of those masses alone.
    void refreshCandidates() {
        if (findStale() == 0) {
            return;
        }
        const bool all = m_s.xg.size() != m_s.x.size() || 16 * m_s.stale.size() > m_s.x.size();
        if (all) {
            m_s.xg = m_s.x;
            m_s.gatheredAt.assign(m_s.x.size(), m_s.step);
        } else {
            for (std::uint32_t i : m_s.stale) {
                m_s.xg[i] = m_s.x[i];
                m_s.gatheredAt[i] = m_s.step;
            }
        }
        m_s.allow.resize(m_s.x.size());
        for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
            m_s.allow[i] = kDriftFraction * mesh(i).net->thickness + length(m_s.x[i] - m_s.xg[i]);
        }
        {
            ProfileStage stage(m_ctx.profiler, "cloth_collision.refit");
            refit();
        }
        ProfileStage stage(m_ctx.profiler, "cloth_collision.pairs");
        if (all) {
            gather();
            m_s.testAll = true;
        } else {
            gatherAround();
            // the pairs new to the list have a stale mass: the next continuous pass tests them
            for (std::uint32_t i : m_s.stale) {
                m_s.moved[i] = 1;
            }
        }
    }

    // ---- proximity ------------------------------------------------------------------------------------

    /// One pass of proximity repulsion; the number of pairs pushed from well inside the thickness.
    /// The first pass looks at every candidate and keeps those within twice the thickness; the later
    /// passes look at those alone (a pair farther apart is not pushed within the thickness by one pass).
    int proximity(bool first) {
        int pushed = 0;
        if (first) {
            m_s.nearVt.clear();
            m_s.nearEe.clear();
        }
        const std::size_t vtCount = first ? m_s.vt.size() : m_s.nearVt.size();
        for (std::size_t k = 0; k < vtCount; ++k) {
            const VertexTriangle& c = first ? m_s.vt[k] : m_s.vt[m_s.nearVt[k]];
            const Triangle& tri = m_s.tris[c.t];
            if (c.restClose || tangledPair(c.p, tri)) {
                continue;
            }
            double b[3];
            const double d =
                pointTriangleDistance(m_s.x[c.p], m_s.x[tri[0]], m_s.x[tri[1]], m_s.x[tri[2]], b);
            const double h = thickness(c.p, tri[0]);
            if (first && d < 2.0 * h) {
                m_s.nearVt.push_back(std::uint32_t(k));
            }
            if (d >= h) {
                continue;
            }
            const Stencil st{{c.p, tri[0], tri[1], tri[2]}, {1.0, -b[0], -b[1], -b[2]}};
            Vec3 n = d > 1e-12 * h ? sum(m_s.x, st) * (1.0 / d) : triangleNormal(tri);
            pushed += repel(st, n, d, h, friction(c.p, tri[0]));
        }
        const std::size_t eeCount = first ? m_s.ee.size() : m_s.nearEe.size();
        for (std::size_t k = 0; k < eeCount; ++k) {
            const EdgeEdge& c = first ? m_s.ee[k] : m_s.ee[m_s.nearEe[k]];
            if (c.restClose || tangledPair(c)) {
                continue;
            }
            double u = 0.0, v = 0.0;
            const double d = segmentDistance(m_s.x[c.a0], m_s.x[c.a1], m_s.x[c.b0], m_s.x[c.b1], u, v);
            const double h = thickness(c.a0, c.b0);
            if (first && d < 2.0 * h) {
                m_s.nearEe.push_back(std::uint32_t(k));
            }
            if (d >= h) {
                continue;
            }
            const Stencil st{{c.a0, c.a1, c.b0, c.b1}, {1.0 - u, u, -(1.0 - v), -v}};
            Vec3 n = d > 1e-12 * h ? sum(m_s.x, st) * (1.0 / d) : edgeNormal(c.a0, c.a1, c.b0, c.b1);
            pushed += repel(st, n, d, h, friction(c.a0, c.b0));
        }
        return pushed;
    }

    // ---- continuous -----------------------------------------------------------------------------------

    /// Runs the continuous test on every candidate; with `respond`, stops each contact as it is found
    /// (Gauss-Seidel), otherwise collects the contacts in m_s.hits. Returns the number found.
    /// A candidate none of whose masses has moved since the last pass tested it is not tested again (its
    /// motion over the step is the same): after the first pass of a step (or of a new list), a pass costs
    /// in proportion to what the pass before it moved. The contacts the last pass found are tested again
    /// whether or not they moved.
    int continuous(bool respond) {
        const bool all = m_s.testAll;
        m_s.testAll = false;
        m_s.movedBefore.swap(m_s.moved);
        std::fill(m_s.moved.begin(), m_s.moved.end(), std::uint8_t{0});
        for (const Constraint& c : m_s.hits) {
            for (std::uint32_t i : c.s.i) {
                m_s.movedBefore[i] = 1;
            }
        }
        m_s.hits.clear();
        const auto& mv = m_s.movedBefore;
        // which candidates this pass tests (fixed for the pass: the marks and flags it reads do not change)
        const std::size_t vtCount = m_s.vt.size(), count = vtCount + m_s.ee.size();
        auto candidate = [&](std::size_t k, std::array<std::uint32_t, 4>& idx) {
            if (k < vtCount) {
                const VertexTriangle& c = m_s.vt[k];
                const Triangle& tri = m_s.tris[c.t];
                idx = {c.p, tri[0], tri[1], tri[2]};
                return (all || mv[c.p] || mv[tri[0]] || mv[tri[1]] || mv[tri[2]]) && !tangledPair(c.p, tri);
            }
            const EdgeEdge& c = m_s.ee[k - vtCount];
            idx = {c.a0, c.a1, c.b0, c.b1};
            return (all || mv[c.a0] || mv[c.a1] || mv[c.b0] || mv[c.b1]) && !tangledPair(c);
        };
        // Gauss-Seidel, with the detection run ahead on the pool's threads: first every candidate's
        // `detect` against where the pass begins, at once; then, in candidate order, a candidate whose masses
        // no response of this pass has moved keeps that answer (it would read the same positions), and
        // the rest are tested again as they come. Exactly the serial pass's work, and so its bits.
        m_s.maybe.assign(count, 0);
        m_s.touched.assign(m_s.x.size(), 0);
        poolOr(m_ctx.pool).forEach(count, 256, [&](std::size_t k) {
            std::array<std::uint32_t, 4> idx;
            Vec3 s[4], e[4];
            double h = 0.0;
            CcdResult r;
            m_s.maybe[k] = candidate(k, idx) && detect(idx, k < vtCount, s, e, h, r);
        });
        int found = 0;
        for (std::size_t k = 0; k < count; ++k) {
            std::array<std::uint32_t, 4> idx;
            if (!candidate(k, idx)) {
                continue;
            }
            const auto& t = m_s.touched;
            if (m_s.maybe[k] || t[idx[0]] || t[idx[1]] || t[idx[2]] || t[idx[3]]) {
                found += test(idx, k < vtCount, respond);
            }
        }
        return found;
    }

    /// The next continuous pass tests every candidate (the masses have all moved: a new step).
    void testEverything() { m_s.testAll = true; }

    // ---- tangles --------------------------------------------------------------------------------------

    /// A pair the untangling answers for (`untangledPair`): out of the proximity and continuous tests
    /// meanwhile (they would keep it crossed: they keep each pair on the side it began the step on).
    bool tangledPair(std::uint32_t p, const Triangle& t) const {
        if (!m_s.anyFlagged) {
            return false;
        }
        const auto& f = m_s.flagged;
        const auto& r = m_s.pushed;
        return untangledPair(f[p], r[p], f[t[0]] || f[t[1]] || f[t[2]], r[t[0]] || r[t[1]] || r[t[2]]);
    }
    bool tangledPair(const EdgeEdge& c) const {
        if (!m_s.anyFlagged) {
            return false;
        }
        const auto& f = m_s.flagged;
        const auto& r = m_s.pushed;
        return untangledPair(f[c.a0] || f[c.a1], r[c.a0] || r[c.a1], f[c.b0] || f[c.b1], r[c.b0] || r[c.b1]);
    }

    /// Flags the corners of the tangled triangles.
    void flag(const std::vector<std::array<std::uint32_t, 2>>& pairs) {
        for (const auto& pair : pairs) {
            for (std::uint32_t t : pair) {
                for (std::uint32_t k : m_s.tris[t]) {
                    m_s.flagged[k] = 1;
                }
            }
            m_s.anyFlagged = true;
        }
    }

    /// A few rounds of untangling (systems/cloth_untangle.h), each moving a free mass at most kUntangleStep
    /// of its cloth's edge length: the regions that global intersection analysis finds on the wrong side
    /// of the cloth move back through it, and where it finds none (a contour that cuts nothing off), the
    /// contour's length is descended. Between rounds the crossed pairs are looked for again, so the
    /// contour is followed as it moves across the mesh.
    void untangle() {
        if (m_s.tangled.empty()) {
            return;
        }
        for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
            m_s.held[i] = m_s.w[i] <= 0.0 || m_s.seated[i];
        }
        flag(m_s.tangled);
        for (int it = 0; it < kUntangleIterations; ++it) {
            // the crossings where the masses are now (the integrator has moved them since the list was made),
            // those of the tangled parts only: a pair the integrator crossed elsewhere is for the contact
            // tests to stop, not to untangle
            findCrossings(m_s, m_s.x, m_s.found, true);
            if (m_s.found.empty()) {
                break;
            }
            flag(m_s.found);
            chooseRegions(m_s.x, m_s.tris, m_s.graph, m_s.found, m_s.held, m_s.choice);
            if (m_s.choice.chosen > 0) {
                for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
                    const Vec3& d = m_s.choice.direction[i];
                    if (!(d == Vec3{})) {
                        m_s.x[i] += d * (kUntangleStep * m_s.spacing[m_s.meshOf[i]]);
                        m_s.moved[i] = 1;
                        m_s.pushed[i] = 1;
                    }
                }
            } else {
                std::fill(m_s.grad.begin(), m_s.grad.end(), Vec3{});
                if (!(contourGradient(m_s.x, m_s.tris, m_s.found, m_s.grad) > 0.0)) {
                    break;
                }
                for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
                    const double g = length(m_s.grad[i]);
                    if (m_s.held[i] || !(g > 0.0)) {
                        continue;
                    }
                    const double step = kUntangleStep * m_s.spacing[m_s.meshOf[i]];
                    m_s.x[i] -= m_s.grad[i] * (step / std::max(g, 1.0));
                    m_s.moved[i] = 1;
                }
            }
        }
    }

    /// Inelastic projection (Harmon et al. 2008) of the contacts in m_s.hits together with those of earlier
    /// rounds: Gauss-Seidel over the constraints q . n >= gap until none is violated by more than a hundredth
    /// of its gap, then the approach speed of each removed.
    void project() {
        m_s.constraints.insert(m_s.constraints.end(), m_s.hits.begin(), m_s.hits.end());
        for (int it = 0; it < kProjectionIterations; ++it) {
            double worst = 0.0;
            for (const Constraint& c : m_s.constraints) {
                const double violation = c.gap - dot(sum(m_s.x, c.s), c.n);
                if (violation > 0.0 && apply(m_s.x, c.s, c.n * violation)) {
                    worst = std::max(worst, violation / c.gap);
                }
            }
            if (worst < 0.01) {
                break;
            }
        }
        for (const Constraint& c : m_s.constraints) {
            const double vn = dot(sum(m_s.v, c.s), c.n);
            if (vn < 0.0) {
                apply(m_s.v, c.s, c.n * -vn);
            }
        }
    }

    /// One round of rigid impact zones (Provot 1997; Bridson et al. 2002): the masses of the contacts in
    /// m_s.hits join zones (with those of earlier rounds), and every zone moves rigidly from where it began.
    void zones() {
        auto find = [&](std::uint32_t i) {
            while (m_s.parent[i] != i) {
                m_s.parent[i] = m_s.parent[m_s.parent[i]];
                i = m_s.parent[i];
            }
            return i;
        };
        for (const Constraint& c : m_s.hits) {
            for (int k = 0; k < 4; ++k) {
                m_s.joined[c.s.i[k]] = 1;
                const std::uint32_t a = find(c.s.i[0]), b = find(c.s.i[k]);
                if (a != b) {
                    m_s.parent[std::max(a, b)] = std::min(a, b);
                }
            }
        }
        // members grouped by zone (root), in index order
        const std::uint32_t n = std::uint32_t(m_s.x.size());
        m_s.members.clear();
        for (std::uint32_t i = 0; i < n; ++i) {
            if (m_s.joined[i]) {
                m_s.members.push_back(i);
            }
        }
        std::sort(m_s.members.begin(), m_s.members.end(), [&](std::uint32_t a, std::uint32_t b) {
            return std::pair{find(a), a} < std::pair{find(b), b};
        });
        for (std::size_t first = 0; first < m_s.members.size();) {
            std::size_t last = first;
            while (last < m_s.members.size() && find(m_s.members[last]) == find(m_s.members[first])) {
                ++last;
            }
            if (last - first > 1) {
                moveRigidly(first, last);
            }
            first = last;
        }
    }

    /// The masses of the contacts just found back where the step began, at rest (a frozen part of the cloth
    /// crosses nothing it did not cross then; what now meets it is frozen in the next round).
    void freeze() {
        for (const Constraint& c : m_s.hits) {
            for (std::uint32_t i : c.s.i) {
                if (!mesh(i).net->pinned[i - mesh(i).vertexOffset]) {
                    m_s.x[i] = m_s.x0[i];
                    m_s.v[i] = Vec3{};
                    m_s.moved[i] = 1;
                }
            }
        }
    }

    /// Every free mass back where the step began, at rest: the state the step started from had no
    /// crossing, so neither has this one.
    void holdStill() {
        for (std::uint32_t i = 0; i < m_s.x.size(); ++i) {
            if (!mesh(i).net->pinned[i - mesh(i).vertexOffset]) {
                m_s.x[i] = m_s.x0[i];
                m_s.v[i] = Vec3{};
                m_s.moved[i] = 1;
            }
        }
    }

private:
    Vec3 triangleNormal(const Triangle& tri) const {
        const Vec3 n = cross(m_s.x[tri[1]] - m_s.x[tri[0]], m_s.x[tri[2]] - m_s.x[tri[0]]);
        const double len = length(n);
        return len > 0.0 ? n * (1.0 / len) : Vec3{0.0, 1.0, 0.0};
    }
    Vec3 edgeNormal(std::uint32_t a0, std::uint32_t a1, std::uint32_t b0, std::uint32_t b1) const {
        const Vec3 n = cross(m_s.x[a1] - m_s.x[a0], m_s.x[b1] - m_s.x[b0]);
        const double len = length(n);
        return len > 0.0 ? n * (1.0 / len) : Vec3{0.0, 1.0, 0.0};
    }

    /// Pushes a pair at distance d (normal n from the second primitive to the first) out to h, on the side
    /// it began the step on; removes its approach speed and slows its sliding (Coulomb).
    int repel(const Stencil& st, Vec3 n, double d, double h, double mu) {
        double depth = h - d;
        if (dot(sum(m_s.x0, st), n) < 0.0) {
            n = -n; // it began on the other side: back across, then out
            depth = h + d;
        }
        if (!apply(m_s.x, st, n * depth)) {
            return 0;
        }
        const Vec3 vr = sum(m_s.v, st);
        const double vn = dot(vr, n);
        if (vn < 0.0) {
            Vec3 dv = n * -vn;
            const Vec3 vt = vr - n * vn;
            const double speed = length(vt);
            if (speed > 0.0) {
                dv -= vt * (std::min(speed, mu * -vn) / speed);
            }
            apply(m_s.v, st, dv);
        }
        return d < kSettled * h ? 1 : 0;
    }

    /// The continuous test of one candidate over the step; 1 if it found a contact.
    int test(const std::array<std::uint32_t, 4>& idx, bool vertexTriangle, bool respond) {
        Vec3 s[4], e[4];
        double h = 0.0;
        CcdResult r;
        if (!detect(idx, vertexTriangle, s, e, h, r)) {
            return 0;
        }
        return respondTo(idx, vertexTriangle, respond, s, e, h, r);
    }

    /// The part of `test` that only reads where the pair's masses begin and end the step (x0, x): whether
    /// their paths come within reach (r), with the paths (s, e) and the thickness (h). False means `test`
    /// returns 0 and changes nothing, which lets threads run it for many candidates at once.
    bool detect(const std::array<std::uint32_t, 4>& idx, bool vertexTriangle, Vec3 s[4], Vec3 e[4], double& h,
                CcdResult& r) const {
        h = thickness(idx[0], idx[2]);
        double reach = kDetectFraction * h;
        Aabb a, b;
        for (int k = 0; k < 4; ++k) {
            s[k] = m_s.x0[idx[k]];
            e[k] = m_s.x[idx[k]];
            Aabb& side = (vertexTriangle ? k == 0 : k < 2) ? a : b;
            side.add(s[k]);
            side.add(e[k]);
        }
        a.inflate(reach);
        if (!a.overlaps(b)) {
            return false;
        }
        // the distance of the pair moves no faster than its points move relative to each other: with M
        // the largest such motion over the step, it is at least max(d0 - M t, d1 - M (1 - t)) at time t,
        // so never below (d0 + d1 - M) / 2. Most candidates (resting layers, neighbours in a sheet) end
        // here, before the inclusion search
        {
            const double motion = relativeMotion(s, e, vertexTriangle);
            // moving together (or not at all), the pair keeps its distance: nothing can cross in this step,
            // however close it began (a pair frozen where it began touching would otherwise be found again
            // and again)
            if (!(motion > 0.0)) {
                return false;
            }
            const double d0 = distance(s, vertexTriangle);
            if (d0 - motion > reach) {
                return false;
            }
            // a pair that begins closer than the reach is in contact from the start; what matters is whether
            // it comes closer still: half as close as it began (touching, whether it passes through)
            reach = std::min(reach, 0.5 * d0);
            if (0.5 * (d0 + distance(e, vertexTriangle) - motion) > reach) {
                return false;
            }
        }
        r = vertexTriangle ? vertexTriangleCcd(s, e, reach) : edgeEdgeCcd(s, e, reach);
        return r.hit;
    }

    /// The rest of `test` for a pair `detect` found within reach: the contact, stopped (respond) or kept.
    int respondTo(const std::array<std::uint32_t, 4>& idx, bool vertexTriangle, bool respond, const Vec3 s[4],
                  const Vec3 e[4], double h, const CcdResult& r) {
        // the stencil where they touch: the closest points at the time of contact
        Vec3 xt[4];
        for (int k = 0; k < 4; ++k) {
            xt[k] = s[k] + (e[k] - s[k]) * r.toi;
        }
        Stencil st{{idx[0], idx[1], idx[2], idx[3]}, {}};
        if (vertexTriangle) {
            double bw[3];
            pointTriangleDistance(xt[0], xt[1], xt[2], xt[3], bw);
            st.w[0] = 1.0;
            st.w[1] = -bw[0];
            st.w[2] = -bw[1];
            st.w[3] = -bw[2];
        } else {
            double u = 0.0, v = 0.0;
            segmentDistance(xt[0], xt[1], xt[2], xt[3], u, v);
            st.w[0] = 1.0 - u;
            st.w[1] = u;
            st.w[2] = -(1.0 - v);
            st.w[3] = -v;
        }
        Vec3 n;
        double gap;
        contactNormal(st, r.toi, vertexTriangle, n, gap);
        const double end = dot(sum(m_s.x, st), n);
        // it came close within the step, but ends apart on its own side
        if (end >= gap - 1e-9 * h && !r.capped) {
            return 0;
        }
        if (!respond) {
            m_s.hits.push_back({st, n, gap});
            return 1;
        }
        // stop it: the end separation back to the gap, the approach speed gone
        if (!apply(m_s.x, st, n * (gap - end))) {
            m_s.hits.push_back({st, n, gap}); // nothing here can move it: for the zones
            return 1;
        }
        const double vn = dot(sum(m_s.v, st), n);
        if (vn < 0.0) {
            apply(m_s.v, st, n * -vn);
        }
        return 1;
    }

    /// The most the pair's points move relative to each other over the step (a bound on how fast its
    /// distance can change).
    static double relativeMotion(const Vec3 s[4], const Vec3 e[4], bool vertexTriangle) {
        const Vec3 base = e[0] - s[0];
        if (vertexTriangle) {
            double motion = 0.0;
            for (int k = 1; k < 4; ++k) {
                motion = std::max(motion, length((e[k] - s[k]) - base));
            }
            return motion;
        }
        // two edges: the first edge's own stretch, plus the second edge's motion relative to it
        double second = 0.0;
        for (int k = 2; k < 4; ++k) {
            second = std::max(second, length((e[k] - s[k]) - base));
        }
        return length((e[1] - s[1]) - base) + second;
    }

    static double distance(const Vec3 x[4], bool vertexTriangle) {
        if (vertexTriangle) {
            double b[3];
            return pointTriangleDistance(x[0], x[1], x[2], x[3], b);
        }
        double u = 0.0, v = 0.0;
        return segmentDistance(x[0], x[1], x[2], x[3], u, v);
    }

    /// The direction a contact must keep (from the second primitive to the first where they met, at time
    /// toi of the step) and its gap.
    void contactNormal(const Stencil& st, double toi, bool vertexTriangle, Vec3& n, double& gap) const {
        const double h = thickness(st.i[0], st.i[2]);
        gap = kGapFraction * h;
        Vec3 q;
        for (int k = 0; k < 4; ++k) {
            q += (m_s.x0[st.i[k]] + (m_s.x[st.i[k]] - m_s.x0[st.i[k]]) * toi) * st.w[k];
        }
        const double d = length(q);
        if (d > 1e-6 * h) {
            n = q * (1.0 / d);
            return;
        }
        // they touch: the surfaces' own normal, turned towards the side they began on
        n = vertexTriangle ? triangleNormal({st.i[1], st.i[2], st.i[3]})
                           : edgeNormal(st.i[0], st.i[1], st.i[2], st.i[3]);
        const Vec3 q0 = sum(m_s.x0, st);
        if (dot(q0, n) < 0.0) {
            n = -n;
        }
    }

    /// Moves the zone m_s.members[first, last) rigidly from where it began (Provot 1997), keeping the linear
    /// and angular momentum of its members' motion over the step; a zone with a member of infinite mass
    /// stays where it began.
    void moveRigidly(std::size_t first, std::size_t last) {
        const double dt = m_ctx.dt;
        bool anchored = false;
        double mass = 0.0;
        Vec3 centre, momentum;
        for (std::size_t k = first; k < last; ++k) {
            const std::uint32_t i = m_s.members[k];
            if (m_s.w[i] <= 0.0 || m_s.seated[i]) {
                anchored = true;
                continue;
            }
            const double m = 1.0 / m_s.w[i];
            mass += m;
            centre += m_s.x0[i] * m;
            momentum += (m_s.xc[i] - m_s.x0[i]) * (m / dt);
        }
        if (anchored || mass <= 0.0) {
            for (std::size_t k = first; k < last; ++k) {
                const std::uint32_t i = m_s.members[k];
                const Mesh& me = mesh(i);
                if (!me.net->pinned[i - me.vertexOffset]) {
                    m_s.x[i] = m_s.x0[i];
                    m_s.v[i] = Vec3{};
                    m_s.moved[i] = 1;
                }
            }
            return;
        }
        centre = centre * (1.0 / mass);
        const Vec3 vc = momentum * (1.0 / mass);
        Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
        Eigen::Vector3d angular = Eigen::Vector3d::Zero();
        for (std::size_t k = first; k < last; ++k) {
            const std::uint32_t i = m_s.members[k];
            const double m = 1.0 / m_s.w[i];
            const Vec3 r = m_s.x0[i] - centre;
            const Vec3 l = cross(r, (m_s.xc[i] - m_s.x0[i]) * (1.0 / dt) - vc) * m;
            const Eigen::Vector3d re(r.x, r.y, r.z);
            angular += Eigen::Vector3d(l.x, l.y, l.z);
            inertia += m * (re.squaredNorm() * Eigen::Matrix3d::Identity() - re * re.transpose());
        }
        // the least-squares, least-norm solution: a zone whose masses lie on a line has no inertia about
        // it, and turns about it not at all
        const Eigen::Vector3d w = inertia.completeOrthogonalDecomposition().solve(angular);
        const Vec3 omega = w.allFinite() ? Vec3{w.x(), w.y(), w.z()} : Vec3{};
        for (std::size_t k = first; k < last; ++k) {
            const std::uint32_t i = m_s.members[k];
            const Vec3 r = rotateBy(omega * dt, m_s.x0[i] - centre);
            m_s.x[i] = centre + vc * dt + r;
            m_s.moved[i] = 1;
            m_s.v[i] = vc + cross(omega, r);
        }
    }

    /// The primitive pairs of two triangles that are candidates (with `staleOnly`, those with a stale mass).
    void addTrianglePair(std::uint32_t ta, std::uint32_t tb, bool staleOnly, Found& out) const {
        forEachPrimitivePair(
            m_s, ta, tb,
            [&](std::uint32_t p, std::uint32_t t) {
                considerVertexTriangle({p, t}, staleOnly, out.vt);
            },
            [&](const EdgeEdge& c) { considerEdgeEdge(c, staleOnly, out.ee); });
    }

    /// The primitive pairs of triangles that share a vertex (listed with the layout, m_s.ringVt and ringEe)
    /// that are candidates.
    void addRingPairs(bool staleOnly) {
        for (const VertexTriangle& c : m_s.ringVt) {
            considerVertexTriangle(c, staleOnly, m_s.vt);
        }
        for (const EdgeEdge& c : m_s.ringEe) {
            considerEdgeEdge(c, staleOnly, m_s.ee);
        }
    }

    /// Adds the pair to the candidates (out) unless it is far apart (or, with `staleOnly`, has no stale
    /// mass). Reads the step's state only, so threads may run it for different pairs at once.
    void considerVertexTriangle(VertexTriangle c, bool staleOnly, std::vector<VertexTriangle>& out) const {
        const Triangle& b = m_s.tris[c.t];
        const auto& stale = m_s.staleMark;
        if ((staleOnly && !(stale[c.p] || stale[b[0]] || stale[b[1]] || stale[b[2]])) ||
            !m_s.vertexBoxes[c.p].overlaps(m_s.boxes[c.t]) || farApart({c.p, b[0], b[1], b[2]}, true)) {
            return;
        }
        c.restClose = restClose(c.p, c.t);
        out.push_back(c);
    }
    void considerEdgeEdge(EdgeEdge c, bool staleOnly, std::vector<EdgeEdge>& out) const {
        const auto& stale = m_s.staleMark;
        if ((staleOnly && !(stale[c.a0] || stale[c.a1] || stale[c.b0] || stale[c.b1])) ||
            !sweptOverlap({c.a0, c.a1}, {c.b0, c.b1}) || farApart({c.a0, c.a1, c.b0, c.b1}, false)) {
            return;
        }
        c.restClose = restClose(c.a0, c.a1, c.b0, c.b1);
        out.push_back(c);
    }

    /// A pair that cannot come within its thickness in this step, nor while the list is kept: left out of
    /// it. While the list is kept every mass stays within m_s.allow of where it is now (`findStale`), so the
    /// pair's distance stays above d1 less the drift (the most either side may move, summed). Over the rest
    /// of this step, from where it began to wherever within the drift of here it ends, the distance stays
    /// above (d0 + d1 - M) / 2 less the drift (M the most its points move relative to each other, as in
    /// `test`: the distance is at least max(d0 - M t, d1 - M (1 - t)) at time t, and moving the ends by the
    /// drift moves each point of the path at most that), which must exceed the reach of the continuous
    /// tests. Most pairs of a sheet's neighbouring cells are a cell apart, far more than the thickness, and
    /// end here once per gathering rather than in every pass.
    bool farApart(const std::array<std::uint32_t, 4>& idx, bool vertexTriangle) const {
        const double h = thickness(idx[0], idx[2]);
        const int split = vertexTriangle ? 1 : 2;
        double driftA = 0.0, driftB = 0.0;
        for (int k = 0; k < 4; ++k) {
            double& side = k < split ? driftA : driftB;
            side = std::max(side, m_s.allow[idx[k]]);
        }
        const double drift = driftA + driftB;
        Vec3 s[4], e[4];
        for (int k = 0; k < 4; ++k) {
            s[k] = m_s.x0[idx[k]];
            e[k] = m_s.x[idx[k]];
        }
        const double d1 = distance(e, vertexTriangle);
        if (d1 - drift <= h) {
            return false;
        }
        return 0.5 * (distance(s, vertexTriangle) + d1 - relativeMotion(s, e, vertexTriangle)) - drift >
               kDetectFraction * h;
    }

    /// Do the edges' swept boxes (inflated as every box is) overlap?
    bool sweptOverlap(std::array<std::uint32_t, 2> ea, std::array<std::uint32_t, 2> eb) const {
        Aabb a = m_s.vertexBoxes[ea[0]], b = m_s.vertexBoxes[eb[0]];
        a.add(m_s.vertexBoxes[ea[1]]);
        b.add(m_s.vertexBoxes[eb[1]]);
        return a.overlaps(b);
    }

    /// Within one cloth, a pair closer than the thickness in the rest state is not repelled (the pairs
    /// listed when the layout was made; none in a sheet whose thickness is below 0.7 of its spacing).
    bool restClose(std::uint32_t p, std::uint32_t t) const {
        return !m_s.restVertexTriangle.empty() &&
               std::binary_search(m_s.restVertexTriangle.begin(), m_s.restVertexTriangle.end(),
                                  VertexTriangle{p, t});
    }
    bool restClose(std::uint32_t a0, std::uint32_t a1, std::uint32_t b0, std::uint32_t b1) const {
        return !m_s.restEdgeEdge.empty() &&
               std::binary_search(m_s.restEdgeEdge.begin(), m_s.restEdgeEdge.end(), EdgeEdge{a0, a1, b0, b1});
    }

    ClothScratch& m_s;
    const StepContext& m_ctx;
};

/// The pairs the rule leaves out: within one cloth, closer than its thickness in the rest state. Found once
/// per layout by a hierarchy over the rest positions.
void listRestPairs(ClothScratch& s) {
    s.restVertexTriangle.clear();
    s.restEdgeEdge.clear();
    std::vector<Vec3> rest(s.meshOf.size());
    for (const Mesh& m : s.meshes) {
        std::copy(m.cc->rest.begin(), m.cc->rest.end(), rest.begin() + m.vertexOffset);
    }
    std::vector<Aabb> boxes(s.tris.size());
    for (std::size_t t = 0; t < s.tris.size(); ++t) {
        for (std::uint32_t k : s.tris[t]) {
            boxes[t].add(rest[k]);
        }
        boxes[t].inflate(s.meshes[s.meshOf[s.tris[t][0]]].net->thickness);
    }
    Bvh tree;
    tree.build(boxes);
    std::vector<std::array<std::uint32_t, 2>> pairs;
    tree.selfPairs(pairs);
    for (const auto& [i, j] : pairs) {
        if (s.meshOf[s.tris[i][0]] != s.meshOf[s.tris[j][0]]) {
            continue;
        }
        const double h = s.meshes[s.meshOf[s.tris[i][0]]].net->thickness;
        for (const auto& [ta, tb] : {std::pair{i, j}, std::pair{j, i}}) {
            const Triangle& a = s.tris[ta];
            const Triangle& b = s.tris[tb];
            for (std::uint32_t p : a) {
                double w[3];
                if (p != b[0] && p != b[1] && p != b[2] &&
                    pointTriangleDistance(rest[p], rest[b[0]], rest[b[1]], rest[b[2]], w) < h) {
                    s.restVertexTriangle.push_back({p, tb});
                }
            }
        }
        const Triangle& a = s.tris[i];
        const Triangle& b = s.tris[j];
        for (int x = 0; x < 3; ++x) {
            const std::uint32_t a0 = std::min(a[x], a[(x + 1) % 3]), a1 = std::max(a[x], a[(x + 1) % 3]);
            for (int y = 0; y < 3; ++y) {
                const std::uint32_t b0 = std::min(b[y], b[(y + 1) % 3]), b1 = std::max(b[y], b[(y + 1) % 3]);
                double u = 0.0, v = 0.0;
                if (a0 != b0 && a0 != b1 && a1 != b0 && a1 != b1 &&
                    segmentDistance(rest[a0], rest[a1], rest[b0], rest[b1], u, v) < h) {
                    s.restEdgeEdge.push_back(std::tie(a0, a1) < std::tie(b0, b1) ? EdgeEdge{a0, a1, b0, b1}
                                                                                 : EdgeEdge{b0, b1, a0, a1});
                }
            }
        }
    }
    for (auto* list : {&s.restVertexTriangle}) {
        std::sort(list->begin(), list->end());
        list->erase(
            std::unique(list->begin(), list->end(), [](auto& x, auto& y) { return !(x < y) && !(y < x); }),
            list->end());
    }
    std::sort(s.restEdgeEdge.begin(), s.restEdgeEdge.end());
    s.restEdgeEdge.erase(std::unique(s.restEdgeEdge.begin(), s.restEdgeEdge.end(),
                                     [](auto& x, auto& y) { return !(x < y) && !(y < x); }),
                         s.restEdgeEdge.end());
}

/// The primitive pairs of every two triangles that share a vertex (s.ringVt, s.ringEe), in the order of
/// the pairs of triangles.
void listRingPairs(ClothScratch& s) {
    const auto vertices = std::uint32_t(s.meshOf.size());
    std::vector<std::uint32_t> start(vertices + 1, 0), around(3 * s.tris.size());
    for (const Triangle& t : s.tris) {
        for (std::uint32_t k : t) {
            ++start[k + 1];
        }
    }
    for (std::uint32_t i = 0; i < vertices; ++i) {
        start[i + 1] += start[i];
    }
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::uint32_t t = 0; t < s.tris.size(); ++t) {
        for (std::uint32_t k : s.tris[t]) {
            around[fill[k]++] = t;
        }
    }
    std::vector<std::array<std::uint32_t, 2>> pairs;
    for (std::uint32_t i = 0; i < vertices; ++i) {
        for (std::uint32_t a = start[i]; a < start[i + 1]; ++a) {
            for (std::uint32_t b = a + 1; b < start[i + 1]; ++b) {
                pairs.push_back({std::min(around[a], around[b]), std::max(around[a], around[b])});
            }
        }
    }
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    s.ringVt.clear();
    s.ringEe.clear();
    for (const auto& [ta, tb] : pairs) {
        forEachPrimitivePair(
            s, ta, tb,
            [&](std::uint32_t p, std::uint32_t t) {
                s.ringVt.push_back({p, t});
            },
            [&](const EdgeEdge& c) { s.ringEe.push_back(c); });
    }
}

/// The self-colliding networks of this step, and the flat arrays laid out for them.
bool prepare(World& world, ClothScratch& s) {
    s.meshes.clear();
    world.view<const Name, SpringNetwork, ClothCollision>().each([&](Entity e, const Name& name,
                                                                     SpringNetwork& net, ClothCollision& cc) {
        if (!net.selfCollision || net.frozen || net.triangles.empty() || cc.previous.size() != net.x.size()) {
            return;
        }
        s.meshes.push_back({e, &net, &cc, &name, 0, 0});
    });
    if (s.meshes.empty()) {
        return false;
    }
    // the layout: rebuilt only when the set of meshes changes
    std::uint32_t vertices = 0, triangles = 0;
    bool same = s.layout.size() == s.meshes.size();
    for (std::size_t k = 0; k < s.meshes.size(); ++k) {
        Mesh& m = s.meshes[k];
        m.vertexOffset = vertices;
        m.triangleOffset = triangles;
        vertices += std::uint32_t(m.net->x.size());
        triangles += std::uint32_t(m.net->triangles.size());
        same = same && s.layout[k] == m.entity && s.sizes[2 * k] == m.net->x.size() &&
               s.sizes[2 * k + 1] == m.net->triangles.size();
    }
    if (!same) {
        s.layout.clear();
        s.sizes.clear();
        for (const Mesh& m : s.meshes) {
            s.layout.push_back(m.entity);
            s.sizes.push_back(std::uint32_t(m.net->x.size()));
            s.sizes.push_back(std::uint32_t(m.net->triangles.size()));
        }
        s.tris.clear();
        s.meshOf.assign(vertices, 0);
        for (std::uint32_t mi = 0; mi < s.meshes.size(); ++mi) {
            const Mesh& m = s.meshes[mi];
            for (std::uint32_t i = 0; i < m.net->x.size(); ++i) {
                s.meshOf[m.vertexOffset + i] = mi;
            }
            for (const Triangle& t : m.net->triangles) {
                s.tris.push_back({t[0] + m.vertexOffset, t[1] + m.vertexOffset, t[2] + m.vertexOffset});
            }
        }
        // the first triangle of each vertex and of each edge answers for it in the pair queries
        s.vertexOwner.assign(vertices, ~0u);
        s.edgeOwned.assign(triangles, 0);
        std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t, int>> edges;
        for (std::uint32_t t = 0; t < triangles; ++t) {
            for (int k = 0; k < 3; ++k) {
                s.vertexOwner[s.tris[t][k]] = std::min(s.vertexOwner[s.tris[t][k]], t);
                const std::uint32_t u = s.tris[t][k], v = s.tris[t][(k + 1) % 3];
                edges.emplace_back(std::min(u, v), std::max(u, v), t, k);
            }
        }
        std::sort(edges.begin(), edges.end());
        for (std::size_t e = 0; e < edges.size(); ++e) {
            const auto& [u, v, t, k] = edges[e];
            if (e == 0 || std::get<0>(edges[e - 1]) != u || std::get<1>(edges[e - 1]) != v) {
                s.edgeOwned[t] = std::uint8_t(s.edgeOwned[t] | (1u << k));
            }
        }
        s.boxes.assign(triangles, Aabb{});
        s.tree = Bvh{};
        s.xg.clear(); // the candidates were of another layout
        s.startChecked = false;
        s.tangled.clear();
        s.crossTree = Bvh{};
        s.tangledSteps = 0;
        s.graph.build(vertices, s.tris);
        // each cloth's mean edge length at rest: the scale of the untangling's steps
        s.spacing.assign(s.meshes.size(), 0.0);
        for (std::uint32_t mi = 0; mi < s.meshes.size(); ++mi) {
            const Mesh& m = s.meshes[mi];
            double sum = 0.0;
            for (const Triangle& t : m.net->triangles) {
                for (int k = 0; k < 3; ++k) {
                    sum += length(m.cc->rest[t[k]] - m.cc->rest[t[(k + 1) % 3]]);
                }
            }
            s.spacing[mi] = sum / (3.0 * double(m.net->triangles.size()));
        }
        listRestPairs(s);
        listRingPairs(s);
    }
    s.x0.resize(vertices);
    s.x.resize(vertices);
    s.v.resize(vertices);
    s.w.resize(vertices);
    for (const Mesh& m : s.meshes) {
        std::copy(m.cc->previous.begin(), m.cc->previous.end(), s.x0.begin() + m.vertexOffset);
        std::copy(m.net->x.begin(), m.net->x.end(), s.x.begin() + m.vertexOffset);
        std::copy(m.net->v.begin(), m.net->v.end(), s.v.begin() + m.vertexOffset);
        for (std::size_t i = 0; i < m.net->x.size(); ++i) {
            s.w[m.vertexOffset + i] = m.net->pinned[i] ? 0.0 : m.net->invMass[i];
        }
    }
    s.xc = s.x;
    s.moved.assign(vertices, 0);
    s.movedBefore.assign(vertices, 0);
    s.seat.assign(vertices, Vec3{});
    s.seated.assign(vertices, 0);
    s.parent.resize(vertices);
    for (std::uint32_t i = 0; i < vertices; ++i) {
        s.parent[i] = i;
    }
    s.joined.assign(vertices, 0);
    s.constraints.clear();
    s.flagged.assign(vertices, 0);
    s.pushed.assign(vertices, 0);
    s.held.assign(vertices, 0);
    s.anyFlagged = false;
    s.grad.resize(vertices);
    s.kinematic = false;
    for (std::uint32_t i = 0; i < vertices; ++i) {
        s.kinematic = s.kinematic || (s.w[i] <= 0.0 && !(s.x[i] == s.x0[i]));
    }
    return true;
}

/// Masses resting on a collider (within kRestingFraction thicknesses of its surface) are seated on it: the
/// cloth's own contacts cannot push them into it. With pushOut, a mass inside a collider is put back out
/// to the thickness, its velocity into the surface removed, and seated. Returns how many were put back.
int holdOnColliders(World& world, ClothScratch& s, bool pushOut) {
    Pool<RigidBody>* bodies = world.findPool<RigidBody>();
    if (!bodies || bodies->size() == 0) {
        return 0;
    }
    int moved = 0;
    for (const Mesh& m : s.meshes) {
        const double h = m.net->thickness;
        for (std::uint32_t i = 0; i < m.net->x.size(); ++i) {
            const std::uint32_t g = m.vertexOffset + i;
            if (s.w[g] <= 0.0) {
                continue;
            }
            for (const RigidBody& body : bodies->values()) {
                Vec3 n;
                const double d = signedDistance(body, s.x[g], n);
                if (pushOut && d < 0.0) {
                    s.x[g] += n * (h - d);
                    s.moved[g] = 1;
                    const double vn = dot(s.v[g], n);
                    if (vn < 0.0) {
                        s.v[g] -= n * vn;
                    }
                    ++moved;
                }
                if (d < kRestingFraction * h) {
                    s.seat[g] = n;
                    s.seated[g] = 1;
                }
            }
        }
    }
    return moved;
}

/// A cloth's name and a triangle's index within it, for messages.
std::string triangleName(const ClothScratch& s, std::uint32_t t, const Mesh& from) {
    const Mesh& m = s.meshes[s.meshOf[s.tris[t][0]]];
    return "triangle " + std::to_string(t - m.triangleOffset) +
           (&m == &from ? std::string() : " of '" + m.name->value + "'");
}

/// The crossings just found (s.found) that the step is to answer for. A pair between two parts that were
/// being untangled (both triangles with a flagged corner) is excused: the contact tests were off for it.
/// Any other is a crossing the contact did not prevent (a pinned or anchored mass dragged the cloth
/// through, say): with `fail` (--check-contact) it fails the run, otherwise a note says it is being
/// untangled; once per cloth. At a layout's first step (`start`), a note names each cloth that begins
/// crossed.
void report(World& world, const StepContext& ctx, ClothScratch& s, bool fail, bool start) {
    RunReport& out = world.resource<RunReport>();
    for (const auto& [i, j] : s.found) {
        const Mesh& ma = s.meshes[s.meshOf[s.tris[i][0]]];
        // a failure per cloth, and a note per cloth: a note (a mass moved through by hand) does not use up
        // the failure a later crossing must report
        std::uint64_t& said = fail ? ma.cc->crossingsReported : ma.cc->crossingNotes;
        if (start || excused(s, {i, j}) || said++ > 0) {
            continue;
        }
        const Mesh& mb = s.meshes[s.meshOf[s.tris[j][0]]];
        std::string what = "entity '" + ma.name->value + "' passed through " +
                           (&ma == &mb ? std::string("itself") : "entity '" + mb.name->value + "'") +
                           " at frame " + std::to_string(ctx.frame) + " (t = " + std::to_string(ctx.time) +
                           " s): " + triangleName(s, i, ma) + " crosses " + triangleName(s, j, ma);
        if (fail) {
            out.failures.push_back(what + " (--check-contact). Remedy: a smaller dt, or a larger thickness; "
                                          "pinned or anchored masses that move push through what they meet");
        } else {
            out.notes.push_back(what + "; it is being untangled");
        }
    }
    if (!start) {
        return;
    }
    // one note per cloth that begins crossed
    for (const Mesh& m : s.meshes) {
        std::size_t count = 0;
        std::array<std::uint32_t, 2> example{};
        for (const auto& pair : s.found) {
            if (s.meshOf[s.tris[pair[0]][0]] == s.meshOf[m.vertexOffset]) {
                example = count++ == 0 ? pair : example;
            }
        }
        if (count > 0) {
            out.notes.push_back(
                "entity '" + m.name->value + "' starts with " + std::to_string(count) +
                " pairs of triangles crossed (its " + triangleName(s, example[0], m) + " through " +
                triangleName(s, example[1], m) +
                "): they are untangled over the next steps (the part on the wrong side passes back), "
                "with contact off between the crossed parts meanwhile");
        }
    }
}

} // namespace

double segmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1, double& s, double& t) {
    // Ericson, Real-Time Collision Detection, 5.1.9
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

ClothCandidates clothCandidates(World& world) {
    ClothCandidates out;
    const ClothScratch* s = world.tryResource<ClothScratch>();
    if (!s || s->xg.size() != s->x.size() || s->x.empty()) {
        return out;
    }
    out.triangles = s->tris;
    out.gathered = s->xg;
    for (std::uint32_t i = 0; i < s->x.size(); ++i) {
        const double h = s->meshes[s->meshOf[i]].net->thickness;
        out.thickness.push_back(h);
        out.margin.push_back(kDriftFraction * h);
    }
    for (const VertexTriangle& c : s->vt) {
        out.vertexTriangle.push_back({c.p, c.t});
    }
    for (const EdgeEdge& c : s->ee) {
        out.edgeEdge.push_back({c.a0, c.a1, c.b0, c.b1});
    }
    return out;
}

ClothCollision makeClothCollision(const std::vector<Vec3>& x) {
    ClothCollision cc;
    cc.rest = x;
    cc.previous = x;
    return cc;
}

namespace {

/// Runs the continuous test over every candidate until it finds nothing: while it finds contacts, first
/// inelastic projection (while the count falls, at most `projections` rounds), then rigid impact zones (at
/// most `zones` rounds), then freezing: the masses of each contact go back to where the step began
/// (kFreezeRounds), and past that every free mass does. Each round is bounded, so the whole is.
void failSafe(Contact& contact, ClothContactStats& stats, int projections, int zones) {
    int last = 0;
    for (int r = 0; r < projections + zones + kFreezeRounds; ++r) {
        contact.refreshCandidates();
        const int found = contact.continuous(false);
        if (found == 0) {
            return;
        }
        // projection while it makes progress; contacts it cannot move go on to the zones
        if (r > 0 && found >= last && r < projections) {
            projections = r;
        }
        last = found;
        if (r < projections) {
            ++stats.projectionRounds;
            contact.project();
        } else if (r < projections + zones) {
            ++stats.zoneRounds;
            contact.zones();
        } else {
            ++stats.freezeRounds;
            contact.freeze();
        }
    }
    contact.holdStill();
    stats.heldStill = true;
}

} // namespace

void collideCloth(World& world, const StepContext& ctx) {
    ClothScratch* kept = world.tryResource<ClothScratch>();
    ClothScratch& s = kept ? *kept : world.setResource<ClothScratch>();
    ClothContactStats* keptStats = world.tryResource<ClothContactStats>();
    ClothContactStats& stats = keptStats ? *keptStats : world.setResource<ClothContactStats>();
    if (!prepare(world, s)) {
        return;
    }
    Contact contact(s, ctx);
    // this step's figures from zero; the run's counts carried on
    ClothContactStats fresh;
    fresh.steps = stats.steps + 1;
    fresh.stepsWithZones = stats.stepsWithZones;
    fresh.stepsHeldStill = stats.stepsHeldStill;
    fresh.stepsTangled = stats.stepsTangled;
    stats = fresh;
    // tangles: looked for where the step begins at a layout's first step, and when asked (a mass moved by
    // hand); afterwards they are known from the end of the step before
    bool look = !s.startChecked;
    for (const Mesh& m : s.meshes) {
        look = look || m.cc->recheck;
        m.cc->recheck = false;
    }
    if (look) {
        ProfileStage stage(ctx.profiler, "cloth_collision.audit");
        findCrossings(s, s.x0, s.found);
        report(world, ctx, s, false, !s.startChecked);
        s.startChecked = true;
        s.tangled.swap(s.found);
    }
    ++s.step;
    holdOnColliders(world, s, false);
    if (!s.tangled.empty()) {
        ProfileStage stage(ctx.profiler, "cloth_collision.untangle");
        contact.untangle();
    }
    contact.refreshCandidates();
    contact.testEverything();
    stats.vertexTriangle = s.vt.size();
    stats.edgeEdge = s.ee.size();
    // pushing one pair apart can press another together: a few passes (a contact the continuous passes
    // stop is left a small gap apart; the next step's repulsion takes it back to the thickness)
    {
        ProfileStage stage(ctx.profiler, "cloth_collision.proximity");
        for (int pass = 0; pass < kProximityPasses && contact.proximity(pass == 0) > 0; ++pass) {
        }
    }
    // continuous passes until one finds nothing: that pass (over candidates still valid for where the
    // masses are) is the proof that the step crosses nothing
    bool clean = false;
    {
        ProfileStage stage(ctx.profiler, "cloth_collision.ccd");
        for (int pass = 0; pass < kContinuousPasses && !clean; ++pass) {
            contact.refreshCandidates();
            const int found = contact.continuous(true);
            stats.ccdContacts += found;
            clean = found == 0;
        }
    }
    // the fail-safe, when they did not settle
    if (!clean) {
        ProfileStage stage(ctx.profiler, "cloth_collision.zones");
        failSafe(contact, stats, kProjectionRounds, kZoneRounds);
    }
    // colliders put back what the cloth pushed into them (and seat it); if that makes a contact, the
    // fail-safe again, freezing at once: a frozen mass goes back to where it began, outside the collider
    if (holdOnColliders(world, s, true) > 0) {
        ProfileStage stage(ctx.profiler, "cloth_collision.zones");
        failSafe(contact, stats, 0, 0);
    }
    stats.stepsWithZones += stats.zoneRounds > 0;
    stats.stepsHeldStill += stats.heldStill;
    // back into the networks; the start of the next step is where this one ended
    for (const Mesh& m : s.meshes) {
        std::copy(s.x.begin() + m.vertexOffset,
                  s.x.begin() + m.vertexOffset + std::ptrdiff_t(m.net->x.size()), m.net->x.begin());
        std::copy(s.v.begin() + m.vertexOffset,
                  s.v.begin() + m.vertexOffset + std::ptrdiff_t(m.net->v.size()), m.net->v.begin());
        m.cc->previous = m.net->x;
    }
    // the audit: after a step that began tangled, after one that moved a pinned mass and was held still
    // (every cap reached: the free masses went back where they began, the pinned ones did not, and may
    // have passed through them; a step whose last continuous pass found nothing crossed nothing), and
    // after every step with --check-contact; what it finds is untangled from the next step on
    const RunChecks* checks = world.tryResource<RunChecks>();
    const bool checking = checks && checks->contact;
    if (checking || !s.tangled.empty() || (s.kinematic && stats.heldStill)) {
        ProfileStage stage(ctx.profiler, "cloth_collision.audit");
        findCrossings(s, s.x, s.found);
        report(world, ctx, s, checking, false);
        s.tangled.swap(s.found);
        stats.crossings = s.tangled.size();
    }
    stats.tangled = s.tangled.size();
    stats.stepsTangled += s.anyFlagged;
    s.tangledSteps = s.anyFlagged ? s.tangledSteps + 1 : 0;
    if (s.tangledSteps == kTangledPatience && !s.tangled.empty()) {
        world.resource<RunReport>().notes.push_back(
            "cloth contact: " + std::to_string(s.tangled.size()) +
            " pairs of triangles are still crossed after " + std::to_string(kTangledPatience) +
            " steps of untangling (entity '" + s.meshes[s.meshOf[s.tris[s.tangled[0][0]][0]]].name->value +
            "'): the cloth may be pinned or held through itself");
    }
    if (ctx.profiler) {
        ctx.profiler->count(ctx.profiler->counterSlot("cloth_collision.tangled_pairs"),
                            double(stats.tangled));
    }
}

} // namespace tumble
