#include "systems/cloth_untangle.h"

#include <algorithm>
#include <cmath>

namespace tumble {

namespace {

constexpr double kMaxRatio = 3.0; ///< the clamp on (g . E) / (n . E): see the header

/// Where the edge e0-e1 passes through the triangle c0 c1 c2: the edge parameter s, the triangle's
/// weights b and its unit normal n. False when it does not (or lies in the triangle's plane).
struct Piercing {
    std::uint32_t e[2];
    std::uint32_t c[3];
    double s = 0.0;
    double b[3] = {};
    Vec3 point, normal;
};

bool pierce(const std::vector<Vec3>& x, std::uint32_t e0, std::uint32_t e1, const Triangle& t,
            Piercing& out) {
    const Vec3& a = x[t[0]];
    const Vec3 n = cross(x[t[1]] - a, x[t[2]] - a);
    const double area2 = length(n);
    if (!(area2 > 0.0)) {
        return false;
    }
    // a point exactly in the plane counts as on its positive side (a consistent tie-break: a vertex that
    // lies in another sheet's plane is then cut off on one side of it only, not both)
    const double d0 = dot(n, x[e0] - a), d1 = dot(n, x[e1] - a);
    if ((d0 >= 0.0) == (d1 >= 0.0)) {
        return false;
    }
    const double s = d0 / (d0 - d1);
    const Vec3 p = x[e0] + (x[e1] - x[e0]) * s;
    // the weights of p by the areas of the sub-triangles it makes, signed along n
    double b[3];
    for (int k = 0; k < 3; ++k) {
        b[k] = dot(n, cross(x[t[(k + 1) % 3]] - p, x[t[(k + 2) % 3]] - p)) / (area2 * area2);
        if (b[k] < 0.0) {
            return false;
        }
    }
    out.e[0] = e0;
    out.e[1] = e1;
    out.s = s;
    for (int k = 0; k < 3; ++k) {
        out.c[k] = t[k];
        out.b[k] = b[k];
    }
    out.point = p;
    out.normal = n * (1.0 / area2);
    return true;
}

/// Adds the gradient g of the length at one end of a segment, spread over the edge's and the triangle's
/// corners.
void spread(const std::vector<Vec3>& x, const Piercing& p, const Vec3& g, std::vector<Vec3>& grad) {
    const Vec3 e = x[p.e[1]] - x[p.e[0]];
    const double across = dot(p.normal, e);
    double ratio = dot(g, e) / across;
    if (!std::isfinite(ratio)) {
        return;
    }
    ratio = std::clamp(ratio, -kMaxRatio, kMaxRatio);
    const Vec3 onTriangle = p.normal * ratio;
    const Vec3 onEdge = g - onTriangle;
    grad[p.e[0]] += onEdge * (1.0 - p.s);
    grad[p.e[1]] += onEdge * p.s;
    for (int k = 0; k < 3; ++k) {
        grad[p.c[k]] += onTriangle * p.b[k];
    }
}

} // namespace

double contourGradient(const std::vector<Vec3>& x, const std::vector<Triangle>& tris,
                       const std::vector<std::array<std::uint32_t, 2>>& pairs, std::vector<Vec3>& grad) {
    double total = 0.0;
    for (const auto& [i, j] : pairs) {
        const Triangle& a = tris[i];
        const Triangle& b = tris[j];
        // the segment's ends: the edges of each triangle that pass through the other
        Piercing ends[2];
        int count = 0;
        for (int side = 0; side < 2 && count <= 2; ++side) {
            const Triangle& edges = side == 0 ? a : b;
            const Triangle& other = side == 0 ? b : a;
            for (int k = 0; k < 3 && count <= 2; ++k) {
                Piercing p;
                if (pierce(x, edges[k], edges[(k + 1) % 3], other, p)) {
                    if (count < 2) {
                        ends[count] = p;
                    }
                    ++count;
                }
            }
        }
        if (count != 2) {
            continue;
        }
        const Vec3 d = ends[1].point - ends[0].point;
        const double len = length(d);
        if (!(len > 0.0)) {
            continue;
        }
        total += len;
        const Vec3 u = d * (1.0 / len);
        spread(x, ends[0], -u, grad);
        spread(x, ends[1], u, grad);
    }
    return total;
}

} // namespace tumble

namespace tumble {

void VertexGraph::build(std::size_t vertices, const std::vector<Triangle>& tris) {
    std::vector<std::array<std::uint32_t, 2>> edges;
    edges.reserve(tris.size() * 6);
    for (const Triangle& t : tris) {
        for (int k = 0; k < 3; ++k) {
            edges.push_back({t[k], t[(k + 1) % 3]});
            edges.push_back({t[(k + 1) % 3], t[k]});
        }
    }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    start.assign(vertices + 1, 0);
    for (const auto& e : edges) {
        ++start[e[0] + 1];
    }
    for (std::size_t v = 0; v < vertices; ++v) {
        start[v + 1] += start[v];
    }
    next.resize(edges.size());
    for (std::size_t k = 0; k < edges.size(); ++k) {
        next[k] = edges[k][1]; // sorted by their first vertex: each vertex's neighbours are contiguous
    }
}

void chooseRegions(const std::vector<Vec3>& x, const std::vector<Triangle>& tris, const VertexGraph& graph,
                   const std::vector<std::array<std::uint32_t, 2>>& pairs,
                   const std::vector<std::uint8_t>& held, RegionChoice& out) {
    const std::uint32_t n = std::uint32_t(x.size());
    constexpr std::uint32_t kNone = ~0u;
    // the cut edges, and the triangle each passes through
    out.cutList.clear();
    for (const auto& [i, j] : pairs) {
        for (int side = 0; side < 2; ++side) {
            const Triangle& edges = tris[side == 0 ? i : j];
            const std::uint32_t through = side == 0 ? j : i;
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t u = edges[k], v = edges[(k + 1) % 3];
                Piercing p;
                if (pierce(x, u, v, tris[through], p)) {
                    out.cutList.push_back({std::min(u, v), std::max(u, v), through});
                }
            }
        }
    }
    out.cuts.clear();
    for (const auto& c : out.cutList) {
        out.cuts.push_back({c.a, c.b});
    }
    std::sort(out.cuts.begin(), out.cuts.end());
    auto isCut = [&](std::uint32_t u, std::uint32_t v) {
        return std::binary_search(out.cuts.begin(), out.cuts.end(),
                                  std::array{std::min(u, v), std::max(u, v)});
    };
    // the regions: joined by the edges that are not cut; a region with a held mass counts as endless
    const std::uint32_t endless = n + 1;
    out.region.assign(n, kNone);
    out.size.clear();
    for (std::uint32_t seed = 0; seed < n; ++seed) {
        if (out.region[seed] != kNone) {
            continue;
        }
        const std::uint32_t id = std::uint32_t(out.size.size());
        std::uint32_t size = 0;
        out.queue.assign(1, seed);
        out.region[seed] = id;
        for (std::size_t q = 0; q < out.queue.size(); ++q) {
            const std::uint32_t u = out.queue[q];
            size = held[u] ? endless : std::min(endless, size + 1);
            for (std::uint32_t k = graph.start[u]; k < graph.start[u + 1]; ++k) {
                const std::uint32_t v = graph.next[k];
                if (out.region[v] == kNone && (out.cuts.empty() || !isCut(u, v))) {
                    out.region[v] = id;
                    out.queue.push_back(v);
                }
            }
        }
        out.size.push_back(size);
    }
    // each cut edge nominates the smaller region either side of it, to pass back through its triangle
    const std::size_t regions = out.size.size();
    out.sum.assign(regions, Vec3{});
    out.votes.assign(regions, 0);
    out.candidate.assign(regions, 0);
    out.across.clear();
    for (const auto& c : out.cutList) {
        const std::uint32_t ra = out.region[c.a], rb = out.region[c.b];
        if (ra == rb) {
            continue;
        }
        const bool first = out.size[ra] < out.size[rb] || (out.size[ra] == out.size[rb] && ra > rb);
        const std::uint32_t r = first ? ra : rb;
        if (out.size[r] >= endless) {
            continue;
        }
        const Triangle& t = tris[c.t];
        const Vec3 normal = cross(x[t[1]] - x[t[0]], x[t[2]] - x[t[0]]);
        const double len = length(normal);
        if (!(len > 0.0)) {
            continue;
        }
        const double side = dot(normal, x[first ? c.a : c.b] - x[t[0]]);
        // a point exactly in the plane counts as on its positive side, as in `pierce`
        out.sum[r] += normal * ((side >= 0.0 ? -1.0 : 1.0) / len);
        ++out.votes[r];
        out.candidate[r] = 1;
        for (std::uint32_t k : t) {
            if (out.region[k] != r) {
                out.across.push_back({r, out.region[k]});
                out.across.push_back({out.region[k], r});
            }
        }
    }
    std::sort(out.across.begin(), out.across.end());
    // the smallest first; one that would pass through an accepted one (or it through it) waits
    out.order.clear();
    for (std::uint32_t r = 0; r < regions; ++r) {
        if (out.candidate[r]) {
            out.order.push_back(r);
        }
    }
    std::sort(out.order.begin(), out.order.end(), [&](std::uint32_t a, std::uint32_t b) {
        return std::pair{out.size[a], a} < std::pair{out.size[b], b};
    });
    out.accepted.assign(regions, 0);
    out.chosen = 0;
    for (std::uint32_t r : out.order) {
        const auto lo = std::lower_bound(out.across.begin(), out.across.end(), std::array{r, 0u});
        bool conflict = false;
        for (auto it = lo; it != out.across.end() && (*it)[0] == r; ++it) {
            conflict = conflict || out.accepted[(*it)[1]];
        }
        // the cuts must agree on the way back: directions that nearly cancel (a region cut off across a
        // curved wall, the cuts' normals facing apart) give none, and contour minimisation is left to it
        if (!conflict && length(out.sum[r]) >= 0.5 * double(out.votes[r])) {
            out.accepted[r] = 1;
            ++out.chosen;
        }
    }
    out.direction.assign(n, Vec3{});
    for (std::uint32_t v = 0; v < n; ++v) {
        const std::uint32_t r = out.region[v];
        if (out.accepted[r] && !held[v]) {
            out.direction[v] = out.sum[r] * (1.0 / length(out.sum[r]));
        }
    }
}

} // namespace tumble
