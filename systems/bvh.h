#pragma once
// An axis-aligned bounding-box hierarchy over a triangle mesh whose vertices move: built once top-down
// (median split along the longest axis of the centroids' bounds, two triangles at most a leaf), then
// refitted bottom-up every step, and rebuilt when refitting has loosened it (the sum of the nodes' box
// surface areas grown past twice what it was at the last build). Queries find the pairs of triangles
// whose boxes overlap: within one mesh (self) or between two meshes.
//
// Written here because none of the packages Tumble builds on has one over deforming triangles (Bullet's
// btDbvt is over its own collision objects; Eigen has a BVH module only in unsupported/).

#include "engine/math.h"

#include <array>
#include <cstdint>
#include <vector>

namespace tumble {

/// An axis-aligned box.
struct Aabb {
    Vec3 lo{1e300, 1e300, 1e300};
    Vec3 hi{-1e300, -1e300, -1e300};

    void add(const Vec3& p) {
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
    }
    void add(const Aabb& b) {
        add(b.lo);
        add(b.hi);
    }
    void inflate(double r) {
        lo -= Vec3{r, r, r};
        hi += Vec3{r, r, r};
    }
    bool overlaps(const Aabb& b) const {
        return lo.x <= b.hi.x && b.lo.x <= hi.x && lo.y <= b.hi.y && b.lo.y <= hi.y && lo.z <= b.hi.z &&
               b.lo.z <= hi.z;
    }
    double area() const {
        const Vec3 d = hi - lo;
        return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
    }
};

using Triangle = std::array<std::uint32_t, 3>;

/// A triangle's box: its corners now and after moving by `sweep` (per vertex, may be empty), inflated.
Aabb triangleBox(const Triangle& t, const std::vector<Vec3>& x, const std::vector<Vec3>& sweep,
                 double inflate);

/// The hierarchy; see the header comment.
class Bvh {
public:
    /// Builds the tree over the triangles' boxes.
    void build(const std::vector<Aabb>& boxes);
    /// New leaf boxes (same triangles, same order); false when the tree has loosened enough to rebuild.
    bool refit(const std::vector<Aabb>& boxes);

    /// Pairs (i < j) of triangles of this mesh whose boxes overlap.
    void selfPairs(std::vector<std::array<std::uint32_t, 2>>& out) const;
    /// Pairs (i in this, j in other) whose boxes overlap.
    void pairsWith(const Bvh& other, std::vector<std::array<std::uint32_t, 2>>& out) const;
    /// The triangles whose boxes overlap `box` (appended to out, in the tree's order).
    void overlapping(const Aabb& box, std::vector<std::uint32_t>& out) const;

    bool empty() const { return m_nodes.empty(); }
    std::size_t nodeCount() const { return m_nodes.size(); }

private:
    struct Node {
        Aabb box;
        std::int32_t left = -1; ///< child nodes, or -1 for a leaf
        std::int32_t right = -1;
        std::uint32_t first = 0; ///< leaf: its triangles, m_order[first .. first + count)
        std::uint32_t count = 0;
    };

    std::int32_t buildNode(const std::vector<Aabb>& boxes, std::uint32_t first, std::uint32_t count);
    void descend(std::int32_t a, std::int32_t b, const Bvh& other, bool self,
                 std::vector<std::array<std::uint32_t, 2>>& out) const;

    std::vector<Node> m_nodes; ///< m_nodes[0] is the root; children after their parent
    std::vector<std::uint32_t> m_order;
    std::vector<Aabb> m_boxes;   ///< the triangles' boxes, as last given
    std::vector<Vec3> m_centres; ///< scratch for building
    double m_builtArea = 0.0;
};

} // namespace tumble
