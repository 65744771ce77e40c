#include "systems/bvh.h"

#include <algorithm>

namespace tumble {

Aabb triangleBox(const Triangle& t, const std::vector<Vec3>& x, const std::vector<Vec3>& sweep,
                 double inflate) {
    Aabb b;
    for (std::uint32_t i : t) {
        b.add(x[i]);
        if (!sweep.empty()) {
            b.add(x[i] + sweep[i]);
        }
    }
    b.inflate(inflate);
    return b;
}

void Bvh::build(const std::vector<Aabb>& boxes) {
    m_boxes = boxes;
    m_nodes.clear();
    m_order.resize(boxes.size());
    m_centres.resize(boxes.size());
    for (std::uint32_t i = 0; i < boxes.size(); ++i) {
        m_order[i] = i;
        m_centres[i] = (boxes[i].lo + boxes[i].hi) * 0.5;
    }
    if (boxes.empty()) {
        return;
    }
    m_nodes.reserve(2 * boxes.size());
    buildNode(boxes, 0, std::uint32_t(boxes.size()));
    m_builtArea = 0.0;
    for (const Node& n : m_nodes) {
        m_builtArea += n.box.area();
    }
}

std::int32_t Bvh::buildNode(const std::vector<Aabb>& boxes, std::uint32_t first, std::uint32_t count) {
    const auto index = std::int32_t(m_nodes.size());
    m_nodes.emplace_back();
    Aabb box, centres;
    for (std::uint32_t k = first; k < first + count; ++k) {
        box.add(boxes[m_order[k]]);
        centres.add(m_centres[m_order[k]]);
    }
    m_nodes[std::size_t(index)].box = box;
    if (count <= 2) {
        m_nodes[std::size_t(index)].first = first;
        m_nodes[std::size_t(index)].count = count;
        return index;
    }
    // split at the median along the longest axis of the centres
    const Vec3 d = centres.hi - centres.lo;
    const int axis = d.x >= d.y && d.x >= d.z ? 0 : d.y >= d.z ? 1 : 2;
    auto key = [&](std::uint32_t t) {
        const Vec3& c = m_centres[t];
        return axis == 0 ? c.x : axis == 1 ? c.y : c.z;
    };
    const std::uint32_t half = count / 2;
    std::nth_element(
        m_order.begin() + first, m_order.begin() + first + half, m_order.begin() + first + count,
        [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b) || (key(a) == key(b) && a < b); });
    const std::int32_t left = buildNode(boxes, first, half);
    const std::int32_t right = buildNode(boxes, first + half, count - half);
    m_nodes[std::size_t(index)].left = left;
    m_nodes[std::size_t(index)].right = right;
    return index;
}

bool Bvh::refit(const std::vector<Aabb>& boxes) {
    m_boxes = boxes;
    // children come after their parents: one backward pass sees every child before its parent
    double area = 0.0;
    for (std::size_t k = m_nodes.size(); k-- > 0;) {
        Node& n = m_nodes[k];
        if (n.left < 0) {
            Aabb b;
            for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
                b.add(boxes[m_order[i]]);
            }
            n.box = b;
        } else {
            n.box = m_nodes[std::size_t(n.left)].box;
            n.box.add(m_nodes[std::size_t(n.right)].box);
        }
        area += n.box.area();
    }
    return area <= 2.0 * m_builtArea;
}

void Bvh::selfPairs(std::vector<std::array<std::uint32_t, 2>>& out) const {
    if (!m_nodes.empty()) {
        descend(0, 0, *this, true, out);
    }
}

void Bvh::pairsWith(const Bvh& other, std::vector<std::array<std::uint32_t, 2>>& out) const {
    if (!m_nodes.empty() && !other.m_nodes.empty()) {
        descend(0, 0, other, false, out);
    }
}

void Bvh::overlapping(const Aabb& box, std::vector<std::uint32_t>& out) const {
    if (m_nodes.empty()) {
        return;
    }
    // the tree splits at the median, so its depth is about log2 of its size: a stack of 128 holds any tree
    // that fits in memory (each node on it has its parent's sibling below it, at most one per level)
    std::array<std::int32_t, 128> stack;
    std::size_t top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& n = m_nodes[std::size_t(stack[--top])];
        if (!n.box.overlaps(box)) {
            continue;
        }
        if (n.left < 0) {
            for (std::uint32_t i = n.first; i < n.first + n.count; ++i) {
                if (m_boxes[m_order[i]].overlaps(box)) {
                    out.push_back(m_order[i]);
                }
            }
            continue;
        }
        // the right child below the left on the stack: the left is opened first
        stack[top++] = n.right;
        stack[top++] = n.left;
    }
}

void Bvh::descend(std::int32_t a, std::int32_t b, const Bvh& other, bool self,
                  std::vector<std::array<std::uint32_t, 2>>& out) const {
    const Node& na = m_nodes[std::size_t(a)];
    const Node& nb = other.m_nodes[std::size_t(b)];
    if (!na.box.overlaps(nb.box)) {
        return;
    }
    const bool leafA = na.left < 0, leafB = nb.left < 0;
    if (leafA && leafB) {
        for (std::uint32_t i = na.first; i < na.first + na.count; ++i) {
            for (std::uint32_t j = nb.first; j < nb.first + nb.count; ++j) {
                const std::uint32_t ti = m_order[i], tj = other.m_order[j];
                if (!m_boxes[ti].overlaps(other.m_boxes[tj])) {
                    continue;
                }
                if (self) {
                    if (a == b && j <= i) {
                        continue; // the same leaf: each pair once, no triangle with itself
                    }
                    out.push_back({std::min(ti, tj), std::max(ti, tj)});
                } else {
                    out.push_back({ti, tj});
                }
            }
        }
        return;
    }
    if (self && a == b) {
        // a node against itself: each child against itself, and the two children against each other
        descend(na.left, na.left, other, true, out);
        descend(na.right, na.right, other, true, out);
        descend(na.left, na.right, other, true, out);
        return;
    }
    // open the larger box (or the one that is not a leaf)
    if (leafB || (!leafA && na.box.area() >= nb.box.area())) {
        descend(na.left, b, other, self, out);
        descend(na.right, b, other, self, out);
    } else {
        descend(a, nb.left, other, self, out);
        descend(a, nb.right, other, self, out);
    }
}

} // namespace tumble
