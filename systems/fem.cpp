#include "systems/fem.h"

#include "engine/parallel.h"
#include "engine/profiler.h"
#include "systems/resting_contacts.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace tumble {

namespace {

using Matrix3 = Eigen::Matrix3d;

Eigen::Vector3d toEigen(const Vec3& v) {
    return {v.x, v.y, v.z};
}

Vec3 fromEigen(const Eigen::Vector3d& v) {
    return {v.x(), v.y(), v.z()};
}

/// Rest shape matrix of an element: the edges from corner 0, as columns.
Matrix3 edges(const std::vector<Vec3>& x, const std::array<std::uint32_t, 4>& t) {
    Matrix3 d;
    for (int c = 0; c < 3; ++c) {
        d.col(c) = toEigen(x[t[std::size_t(c) + 1]] - x[t[0]]);
    }
    return d;
}

/// "element 12 (nodes 3, 4, 9, 10)", numbered as the mesh's files number them, after "file:line: " for
/// a mesh read from files.
std::string elementName(const TetMesh& mesh, std::size_t e) {
    const auto& t = mesh.tets[e];
    const std::uint32_t base = mesh.firstNode;
    std::string where = mesh.file.empty() ? "" : mesh.file + ":" + std::to_string(mesh.lines[e]) + ": ";
    return where + "element " + std::to_string(e + base) + " (nodes " + std::to_string(t[0] + base) + ", " +
           std::to_string(t[1] + base) + ", " + std::to_string(t[2] + base) + ", " +
           std::to_string(t[3] + base) + ")";
}

/// The faces that belong to one element only, each turned so that its normal points away from the
/// element's fourth corner (out of the body).
std::vector<std::array<std::uint32_t, 3>> boundaryFaces(const TetMesh& mesh) {
    struct Face {
        std::array<std::uint32_t, 3> key, corners;
    };
    std::vector<Face> faces;
    faces.reserve(mesh.tets.size() * 4);
    for (const auto& t : mesh.tets) {
        for (std::size_t skip = 0; skip < 4; ++skip) {
            std::array<std::uint32_t, 3> c{};
            std::size_t k = 0;
            for (std::size_t a = 0; a < 4; ++a) {
                if (a != skip) {
                    c[k++] = t[a];
                }
            }
            const Vec3 n = cross(mesh.nodes[c[1]] - mesh.nodes[c[0]], mesh.nodes[c[2]] - mesh.nodes[c[0]]);
            if (dot(n, mesh.nodes[t[skip]] - mesh.nodes[c[0]]) > 0.0) {
                std::swap(c[1], c[2]);
            }
            std::array<std::uint32_t, 3> key = c;
            std::sort(key.begin(), key.end());
            faces.push_back({key, c});
        }
    }
    std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) { return a.key < b.key; });
    std::vector<std::array<std::uint32_t, 3>> out;
    for (std::size_t i = 0; i < faces.size();) {
        std::size_t j = i + 1;
        while (j < faces.size() && faces[j].key == faces[i].key) {
            ++j;
        }
        if (j - i == 1) {
            out.push_back(faces[i].corners);
        }
        i = j;
    }
    return out;
}

/// A line of a TetGen file with its number, comments stripped; nullopt at the end.
struct LineReader {
    std::ifstream in;
    std::string name;
    int number = 0;

    std::optional<std::istringstream> next() {
        std::string line;
        while (std::getline(in, line)) {
            ++number;
            line = line.substr(0, line.find('#'));
            if (line.find_first_not_of(" \t\r") != std::string::npos) {
                return std::istringstream(line);
            }
        }
        return std::nullopt;
    }
    [[noreturn]] void fail(const std::string& what) const {
        throw std::runtime_error(name + ":" + std::to_string(number) + ": " + what);
    }
};

} // namespace

TetMesh boxTets(const Vec3& centre, const std::array<double, 3>& size, const std::array<int, 3>& res) {
    TetMesh mesh;
    const int nx = res[0] + 1, ny = res[1] + 1, nz = res[2] + 1;
    mesh.nodes.reserve(std::size_t(nx) * ny * nz);
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            for (int i = 0; i < nx; ++i) {
                mesh.nodes.push_back(centre + Vec3{size[0] * (double(i) / res[0] - 0.5),
                                                   size[1] * (double(j) / res[1] - 0.5),
                                                   size[2] * (double(k) / res[2] - 0.5)});
            }
        }
    }
    auto node = [&](int i, int j, int k) { return std::uint32_t(i + nx * (j + ny * k)); };
    // the six paths along the axes across a cell from one corner to the opposite one, one tetrahedron
    // each. Along each axis a cell is the mirror image of its neighbours (the path starts at the high side
    // of an odd cell): every plane between cells is a plane of symmetry of the cells either side, and a box
    // of an even number of cells across is symmetric about its middle, so a square section loaded square to
    // a side bends only that way (cut the same way in every cell, a cantilever of 2 x 2 cells across bent
    // 13% of its sag sideways, and a cube dropped flat slid 0.4 m; at an odd number across the middle cell
    // is cut one way: 0.8% sideways at 3, 0.1% at 5).
    // Mirroring keeps the mesh conforming: a face between two cells is cut along the same diagonal by both.
    constexpr int kOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    mesh.tets.reserve(std::size_t(res[0]) * res[1] * res[2] * 6);
    for (int k = 0; k < res[2]; ++k) {
        for (int j = 0; j < res[1]; ++j) {
            for (int i = 0; i < res[0]; ++i) {
                const int odd[3] = {i & 1, j & 1, k & 1};
                for (const auto& order : kOrders) {
                    int at[3] = {i + odd[0], j + odd[1], k + odd[2]};
                    std::array<std::uint32_t, 4> t{};
                    t[0] = node(at[0], at[1], at[2]);
                    for (std::size_t s = 0; s < 3; ++s) {
                        at[order[s]] += odd[order[s]] != 0 ? -1 : 1;
                        t[s + 1] = node(at[0], at[1], at[2]);
                    }
                    if (edges(mesh.nodes, t).determinant() < 0.0) {
                        std::swap(t[1], t[2]);
                    }
                    mesh.tets.push_back(t);
                }
            }
        }
    }
    return mesh;
}

bool boxFace(const std::string& face, const std::array<int, 3>& res, std::vector<std::uint32_t>& nodes) {
    static const std::map<std::string, std::pair<int, bool>> kFaces = {
        {"left", {0, false}}, {"right", {0, true}}, {"bottom", {1, false}},
        {"top", {1, true}},   {"back", {2, false}}, {"front", {2, true}}};
    const auto it = kFaces.find(face);
    if (it == kFaces.end()) {
        return false;
    }
    const auto [axis, high] = it->second;
    nodes.clear();
    int at[3];
    for (at[2] = 0; at[2] <= res[2]; ++at[2]) {
        for (at[1] = 0; at[1] <= res[1]; ++at[1]) {
            for (at[0] = 0; at[0] <= res[0]; ++at[0]) {
                if (at[axis] == (high ? res[std::size_t(axis)] : 0)) {
                    nodes.push_back(std::uint32_t(at[0] + (res[0] + 1) * (at[1] + (res[1] + 1) * at[2])));
                }
            }
        }
    }
    return true;
}

TetMesh sphereTets(const Vec3& centre, double radius, int cells) {
    const TetMesh box = boxTets(centre, {2 * radius, 2 * radius, 2 * radius}, {cells, cells, cells});
    TetMesh mesh;
    std::vector<std::uint32_t> renumber(box.nodes.size(), 0xffffffffu);
    for (const auto& t : box.tets) {
        const Vec3 c = (box.nodes[t[0]] + box.nodes[t[1]] + box.nodes[t[2]] + box.nodes[t[3]]) * 0.25;
        if (length(c - centre) > radius) {
            continue;
        }
        std::array<std::uint32_t, 4> kept{};
        for (std::size_t a = 0; a < 4; ++a) {
            if (renumber[t[a]] == 0xffffffffu) {
                renumber[t[a]] = std::uint32_t(mesh.nodes.size());
                mesh.nodes.push_back(box.nodes[t[a]]);
            }
            kept[a] = renumber[t[a]];
        }
        mesh.tets.push_back(kept);
    }
    return mesh;
}

namespace {

/// An element listed twice (the same four nodes, in any order) would count its mass and stiffness twice
/// there: refused at its second line, naming the first.
void refuseRepeatedElements(const TetMesh& mesh) {
    std::map<std::array<std::uint32_t, 4>, std::size_t> seen;
    for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
        std::array<std::uint32_t, 4> key = mesh.tets[e];
        std::sort(key.begin(), key.end());
        const auto [it, fresh] = seen.emplace(key, e);
        if (!fresh) {
            throw std::runtime_error(elementName(mesh, e) + " repeats element " +
                                     std::to_string(it->second + mesh.firstNode) + " (line " +
                                     std::to_string(mesh.lines[it->second]) +
                                     "): the same four nodes; list each element once");
        }
    }
}

} // namespace

TetMesh readTetGen(const std::filesystem::path& ele, const Vec3& offset, std::size_t maxNodes,
                   std::size_t maxTets) {
    std::filesystem::path nodePath = ele;
    nodePath.replace_extension(".node");
    LineReader nodes{std::ifstream(nodePath), nodePath.string()};
    if (!nodes.in) {
        throw std::runtime_error(nodePath.string() + ": cannot be read (the .node file beside '" +
                                 ele.string() + "')");
    }
    TetMesh mesh;
    mesh.file = ele.string();
    auto header = nodes.next();
    long long count = -1, dim = -1, attributes = -1, markers = -1;
    if (!header || !(*header >> count >> dim >> attributes >> markers) || count < 4 || dim != 3 ||
        attributes < 0 || markers < 0 || markers > 1) {
        nodes.fail(
            "expected the header '<nodes> 3 <attributes> <0|1 boundary marker>' with at least 4 nodes");
    }
    if (std::size_t(count) > maxNodes) {
        nodes.fail(std::to_string(count) + " nodes; at most " + std::to_string(maxNodes) + " are allowed");
    }
    mesh.nodes.reserve(std::size_t(count));
    long long first = 0;
    for (long long i = 0; i < count; ++i) {
        auto line = nodes.next();
        long long index = 0;
        double x = 0, y = 0, z = 0;
        if (!line) {
            nodes.fail("the file ends after " + std::to_string(i) + " of its " + std::to_string(count) +
                       " nodes");
        }
        if (!(*line >> index >> x >> y >> z) || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) {
            nodes.fail("expected '<index> <x> <y> <z>', finite numbers");
        }
        if (i == 0) {
            first = index;
            mesh.firstNode = static_cast<std::uint32_t>(index == 1 ? 1 : 0);
            if (first != 0 && first != 1) {
                nodes.fail("the first node is numbered " + std::to_string(index) +
                           "; TetGen numbers from 0 or 1");
            }
        }
        if (index != first + i) {
            nodes.fail("node " + std::to_string(index) + " where " + std::to_string(first + i) +
                       " was expected");
        }
        mesh.nodes.push_back(Vec3{x, y, z} + offset);
    }
    LineReader tets{std::ifstream(ele), ele.string()};
    if (!tets.in) {
        throw std::runtime_error(ele.string() + ": cannot be read");
    }
    header = tets.next();
    long long perTet = 0;
    if (!header || !(*header >> count >> perTet >> attributes) || count < 1 ||
        (perTet != 4 && perTet != 10) || attributes < 0) {
        tets.fail("expected the header '<tetrahedra> 4 <attributes>'");
    }
    if (perTet == 10) {
        tets.fail("second-order (10-node) tetrahedra are not supported: make the mesh without -o2");
    }
    if (std::size_t(count) > maxTets) {
        tets.fail(std::to_string(count) + " tetrahedra; at most " + std::to_string(maxTets) + " are allowed");
    }
    mesh.tets.reserve(std::size_t(count));
    for (long long i = 0; i < count; ++i) {
        auto line = tets.next();
        if (!line) {
            tets.fail("the file ends after " + std::to_string(i) + " of its " + std::to_string(count) +
                      " tetrahedra");
        }
        long long index = 0, n[4] = {};
        if (!(*line >> index >> n[0] >> n[1] >> n[2] >> n[3])) {
            tets.fail("expected '<index> <node> <node> <node> <node>'");
        }
        std::array<std::uint32_t, 4> t{};
        for (std::size_t a = 0; a < 4; ++a) {
            if (n[a] < first || n[a] - first >= static_cast<long long>(mesh.nodes.size())) {
                tets.fail("node " + std::to_string(n[a]) + " is not in '" + nodePath.filename().string() +
                          "' (" + std::to_string(first) + " to " +
                          std::to_string(first + static_cast<long long>(mesh.nodes.size()) - 1) + ")");
            }
            t[a] = std::uint32_t(n[a] - first);
        }
        // TetGen's orientation is ours: the fourth corner on the side the first three's edges turn
        // counter-clockwise about (a positive determinant of the edges from the first)
        mesh.tets.push_back(t);
        mesh.lines.push_back(tets.number);
    }
    refuseRepeatedElements(mesh);
    return mesh;
}

namespace {

/// The message for element e, inverted at rest: how many of the mesh's elements are (all of them: the
/// file lists every element the other way round).
std::string invertedAtRest(const TetMesh& mesh, std::size_t e) {
    std::size_t inverted = 0;
    for (const auto& t : mesh.tets) {
        inverted += edges(mesh.nodes, t).determinant() < 0.0 ? 1 : 0;
    }
    const std::string what = elementName(mesh, e) +
                             " is inverted at rest: its fourth corner lies on the side its first three turn "
                             "clockwise about, where "
                             "TetGen's order puts it on the other (swap two of its corners)";
    if (inverted == mesh.tets.size()) {
        return what + "; every element of the mesh is, as if the file listed them all the other way round";
    }
    return what + "; " + std::to_string(inverted) + " of the mesh's " + std::to_string(mesh.tets.size()) +
           " elements are";
}

} // namespace

SpringNetwork buildFem(const TetMesh& mesh, const FemMaterial& material,
                       const std::vector<std::uint32_t>& pins) {
    SpringNetwork net;
    net.kind = NetworkKind::Fem;
    const std::size_t n = mesh.nodes.size();
    net.x = mesh.nodes;
    net.v.assign(n, Vec3{});
    net.pinned.assign(n, 0);
    std::vector<double> mass(n, 0.0);
    FemElements& fem = net.fem;
    fem.tets = mesh.tets;
    fem.gradients.resize(mesh.tets.size());
    fem.volume.resize(mesh.tets.size());
    fem.rotation.assign(mesh.tets.size(), kNoRotation);
    for (std::size_t e = 0; e < mesh.tets.size(); ++e) {
        const auto& t = mesh.tets[e];
        const Matrix3 d = edges(mesh.nodes, t);
        double longest = 0.0;
        for (std::size_t a = 0; a < 4; ++a) {
            for (std::size_t b = a + 1; b < 4; ++b) {
                longest = std::max(longest, length(mesh.nodes[t[b]] - mesh.nodes[t[a]]));
            }
        }
        const double volume = d.determinant() / 6.0;
        // a regular tetrahedron of edge l has volume l^3 / (6 sqrt 2); a thousandth of that is a sliver
        if (!(std::abs(volume) > 1e-4 * longest * longest * longest)) {
            throw std::invalid_argument(elementName(mesh, e) + " is degenerate: its volume " +
                                        std::to_string(volume) + " m^3 is nearly zero for its size");
        }
        if (volume < 0.0) {
            throw std::invalid_argument(invertedAtRest(mesh, e));
        }
        const Matrix3 inverse = d.inverse();
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (std::size_t a = 1; a < 4; ++a) {
            const Eigen::Vector3d g = inverse.row(Eigen::Index(a - 1)).transpose();
            fem.gradients[e][a] = fromEigen(g);
            sum += g;
        }
        fem.gradients[e][0] = fromEigen(Eigen::Vector3d(-sum));
        fem.volume[e] = volume;
        for (std::uint32_t node : t) {
            mass[node] += 0.25 * material.density * volume;
        }
    }
    net.invMass.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (!(mass[i] > 0.0)) {
            throw std::invalid_argument((mesh.file.empty() ? "" : mesh.file + ": ") + "node " +
                                        std::to_string(i + mesh.firstNode) +
                                        " belongs to no element (make the mesh with tetgen's -j)");
        }
        net.invMass[i] = 1.0 / mass[i];
    }
    for (std::uint32_t p : pins) {
        net.pinned[p] = 1;
    }
    const double e = material.young, nu = material.poisson;
    fem.lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    fem.mu = e / (2.0 * (1.0 + nu));
    fem.stiffnessDamping = material.stiffnessDamping;
    fem.massDamping = material.massDamping;
    net.triangles = boundaryFaces(mesh);
    net.integrator = Integrator::ImplicitEuler;
    return net;
}

Vec3 elementForceOn(const SpringNetwork& net, const FemSolver& solver, std::uint32_t node) {
    const FemElements& fem = net.fem;
    Vec3 sum;
    auto add = [&](std::size_t e, std::size_t k) {
        Quat q = fem.rotation[e]; // a copy: the state is the step's, not this query's
        std::array<Vec3, 4> force;
        elementForces(fem, net.x, net.v, e, e + 1, &q, fem.stiffnessDamping, 0.0, {&force});
        sum += force[k];
    };
    if (solver.nodeCorners.start.size() == net.x.size() + 1) {
        // implicit Euler's lists: the node's corners, in element order
        for (std::uint32_t k = solver.nodeCorners.start[node]; k < solver.nodeCorners.start[node + 1]; ++k) {
            add(solver.nodeCorners.items[k] / 4, solver.nodeCorners.items[k] % 4);
        }
    } else {
        for (std::size_t e = 0; e < fem.tets.size(); ++e) {
            for (std::size_t k = 0; k < 4; ++k) {
                if (fem.tets[e][k] == node) {
                    add(e, k);
                }
            }
        }
    }
    return sum;
}

void addElementForces(const SpringNetwork& net, const std::vector<Vec3>& x, const std::vector<Vec3>& v,
                      std::vector<Vec3>& f, std::vector<Quat>& rotationState, double since) {
    const FemElements& fem = net.fem;
    constexpr std::size_t kBatch = 64;
    std::array<std::array<Vec3, 4>, kBatch> force;
    for (std::size_t first = 0; first < fem.tets.size(); first += kBatch) {
        const std::size_t end = std::min(first + kBatch, fem.tets.size());
        elementForces(fem, x, v, first, end, &rotationState[first], fem.stiffnessDamping, since,
                      {force.data()});
        for (std::size_t e = first; e < end; ++e) {
            for (std::size_t a = 0; a < 4; ++a) {
                f[fem.tets[e][a]] += force[e - first][a];
            }
        }
    }
    for (std::size_t i = 0; i < x.size(); ++i) {
        f[i] -= v[i] * (fem.massDamping / net.invMass[i]);
    }
}

namespace {

/// Lists in compressed-row form from a map item -> list: list l gets its items in ascending order.
void invertLists(const std::vector<std::uint32_t>& listOf, std::uint32_t lists, FemSolver::Lists& out) {
    out.start.assign(std::size_t(lists) + 1, 0);
    for (std::uint32_t l : listOf) {
        ++out.start[std::size_t(l) + 1];
    }
    for (std::uint32_t l = 0; l < lists; ++l) {
        out.start[std::size_t(l) + 1] += out.start[l];
    }
    out.items.resize(listOf.size());
    std::vector<std::uint32_t> next(out.start.begin(), out.start.end() - 1);
    for (std::uint32_t k = 0; k < listOf.size(); ++k) {
        out.items[next[listOf[k]]++] = k;
    }
}

void buildFemPattern(const SpringNetwork& net, FemSolver& s) {
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    pairs.reserve(net.fem.tets.size() * 6);
    for (const auto& t : net.fem.tets) {
        for (std::size_t a = 0; a < 4; ++a) {
            for (std::size_t b = a + 1; b < 4; ++b) {
                pairs.emplace_back(std::min(t[a], t[b]), std::max(t[a], t[b]));
            }
        }
    }
    s.system = BlockMatrix<float>::fromPairs(std::uint32_t(net.x.size()), std::move(pairs));
    const BlockMatrix<float>& a = s.system;
    const auto blocks = std::uint32_t(a.val.size());
    // per block on or right of the diagonal and per node, the element corners that add to it, ascending;
    // a block left of the diagonal is the transpose of its mirror's (the system is symmetric)
    std::vector<std::uint32_t> blockOf(net.fem.tets.size() * 16), nodeOf(net.fem.tets.size() * 4);
    for (std::size_t e = 0; e < net.fem.tets.size(); ++e) {
        const auto& t = net.fem.tets[e];
        for (std::size_t k = 0; k < 16; ++k) {
            // the slot of (t[b], t[a]) with k = 4 a + b; the blocks left of the diagonal to a last list
            const std::uint32_t row = t[k % 4], col = t[k / 4];
            blockOf[16 * e + k] = row <= col ? a.find(row, col) : blocks;
        }
        for (std::size_t k = 0; k < 4; ++k) {
            nodeOf[4 * e + k] = t[k];
        }
    }
    invertLists(blockOf, blocks + 1, s.blockSources);
    s.blockSources.items.resize(s.blockSources.start[blocks]); // the last list's items are the last
    s.blockSources.start.pop_back();
    s.mirror.resize(blocks);
    for (std::uint32_t i = 0; i < a.n; ++i) {
        for (std::uint32_t b = a.rowStart[i]; b < a.rowStart[i + 1]; ++b) {
            s.mirror[b] = a.find(a.col[b], i);
        }
    }
    invertLists(nodeOf, std::uint32_t(net.x.size()), s.nodeCorners);
    s.dv.assign(net.x.size(), Vec3T<float>{});
    s.pcg.remembered = 0; // solutions of another system
    s.multigrid = AggregationMultigrid<float>{};
    s.pinnedWhenBuilt.clear();
}

void findFemPinnedBlocks(const SpringNetwork& net, FemSolver& s) {
    s.pinnedBlocks = s.system.fixedBlocks(net.pinned);
    s.pinnedWhenBuilt = net.pinned;
}

/// Element e's share of one system block (k = 4 a + b: the slot of (b, a), which holds the transpose of
/// A_ba, that is A_ab, as the kernels read a block's rows as its columns): c R K_ab R^T = c V [lambda q_a
/// q_b^T + mu (q_a . q_b) I + mu q_b q_a^T], with q = R g (a rotation keeps g_a . g_b). The element keeps
/// s = sqrt(c V mu) q, so that the block is ratio s_a s_b^T + (s_a . s_b) I + s_b s_a^T with ratio =
/// lambda / mu, from its own 12 numbers alone. In float, on SSE registers (a row each): a block sums a few
/// dozen shares in a fixed order and is stored in float, so double sums would only round later.
struct BlockRows {
    __m128 row[3];
};
void addElementBlock(const FemSolver& s, std::uint32_t source, __m128 ratio, BlockRows& block) {
    const std::array<Vec3T<float>, 4>& scaled = s.turned[source / 16];
    const Vec3T<float>& sa = scaled[(source % 16) / 4];
    const Vec3T<float>& sb = scaled[source % 4];
    const __m128 a = sa.simd(), b = sb.simd();
    const __m128 ra = _mm_mul_ps(ratio, a);
    const float d = dot(sa, sb);
    const __m128 diagonal[3] = {_mm_set_ps(0.0f, 0.0f, 0.0f, d), _mm_set_ps(0.0f, 0.0f, d, 0.0f),
                                _mm_set_ps(0.0f, d, 0.0f, 0.0f)};
    const __m128 raLane[3] = {_mm_shuffle_ps(ra, ra, 0x00), _mm_shuffle_ps(ra, ra, 0x55),
                              _mm_shuffle_ps(ra, ra, 0xaa)};
    const __m128 bLane[3] = {_mm_shuffle_ps(b, b, 0x00), _mm_shuffle_ps(b, b, 0x55),
                             _mm_shuffle_ps(b, b, 0xaa)};
    for (std::size_t r = 0; r < 3; ++r) {
        // row r: ratio a_r b + b_r a + d e_r
        const __m128 share =
            _mm_add_ps(_mm_add_ps(_mm_mul_ps(raLane[r], b), _mm_mul_ps(bLane[r], a)), diagonal[r]);
        block.row[r] = _mm_add_ps(block.row[r], share);
    }
}

/// Implicit Euler (see the header comment); f holds the external forces.
SolveStats implicitFem(SpringNetwork& net, FemSolver& s, std::vector<Vec3>& f, const Environment& env,
                       double h) {
    const std::size_t n = net.x.size();
    const FemElements& fem = net.fem;
    if (s.system.n != n || s.nodeCorners.items.size() != 4 * fem.tets.size()) {
        buildFemPattern(net, s);
    }
    if (s.pinnedWhenBuilt != net.pinned) {
        findFemPinnedBlocks(net, s);
    }
    std::optional<ProfileStage> stage(std::in_place, env.profiler, "springs.fem_assemble");
    const double alpha = fem.massDamping, beta = fem.stiffnessDamping;
    const double c = h * h + h * beta; // the stiffness's weight in the system
    const __m128 ratio = _mm_set1_ps(float(fem.lambda / fem.mu));
    s.rhs.resize(n);
    // each element's rotation, forces and scaled turned gradients s = sqrt(c V mu) R g (addElementBlock),
    // shared out over threads (each element writes its own)
    WorkerPool& pool = poolOr(env.pool);
    s.forces.resize(fem.tets.size());
    s.turned.resize(fem.tets.size());
    pool.forChunks(fem.tets.size(), 256, [&](std::size_t, std::size_t first, std::size_t end) {
        elementForces(fem, net.x, net.v, first, end, &net.fem.rotation[first], h + beta, h,
                      {&s.forces[first], &s.turned[first], c});
    });
    // then each node gathers its corners' forces (in double) and each block of its row on or right of the
    // diagonal its elements' shares (in float), in element order (the additions a scatter element after
    // element makes); the blocks left of the diagonal are their mirrors' transposes
    BlockMatrix<float>& a = s.system;
    pool.forChunks(n, 128, [&](std::size_t, std::size_t first, std::size_t end) {
        for (std::size_t i = first; i < end; ++i) {
            const double m = 1.0 / net.invMass[i];
            Vec3 r = (f[i] - net.v[i] * (alpha * m)) * h;
            for (std::uint32_t k = s.nodeCorners.start[i]; k < s.nodeCorners.start[i + 1]; ++k) {
                const std::uint32_t corner = s.nodeCorners.items[k];
                r += s.forces[corner / 4][corner % 4] * h;
            }
            s.rhs[i] = r;
            for (std::uint32_t block = a.diag[i]; block < a.rowStart[i + 1]; ++block) {
                const float diagonal =
                    a.col[block] == i ? float(m * (1.0 + h * alpha) + h * massDamping(net, env, net.x[i]))
                                      : 0.0f;
                BlockRows sum{{_mm_set_ps(0.0f, 0.0f, 0.0f, diagonal), _mm_set_ps(0.0f, 0.0f, diagonal, 0.0f),
                               _mm_set_ps(0.0f, diagonal, 0.0f, 0.0f)}};
                for (std::uint32_t k = s.blockSources.start[block]; k < s.blockSources.start[block + 1];
                     ++k) {
                    addElementBlock(s, s.blockSources.items[k], ratio, sum);
                }
                // rows in order: each store's fourth lane (zero) is overwritten by the next row's first;
                // the last row's three floats end the block (it holds nine)
                float* out = a.val[block].m.data();
                _mm_storeu_ps(out, sum.row[0]);
                _mm_storeu_ps(out + 3, sum.row[1]);
                alignas(16) float last[4];
                _mm_store_ps(last, sum.row[2]);
                std::copy(last, last + 3, out + 6);
            }
        }
    });
    pool.forChunks(n, 128, [&](std::size_t, std::size_t first, std::size_t end) {
        for (std::size_t i = first; i < end; ++i) {
            for (std::uint32_t block = a.rowStart[i]; block < a.diag[i]; ++block) {
                a.val[block] = a.val[s.mirror[block]].transposed();
            }
        }
    });
    holdResting(net, a, s.restingWeights, s.restingBlocks); // systems/resting_contacts.h
    for (std::uint32_t block : s.pinnedBlocks) {
        a.val[block] = Mat3T<float>{};
    }
    s.rhsFloat.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        if (net.pinned[i]) {
            a.val[a.diag[i]] = Mat3T<float>::identity();
            s.rhsFloat[i] = Vec3T<float>{};
        } else {
            s.rhsFloat[i] = Vec3T<float>::from(s.rhs[i]);
        }
    }
    stage.emplace(env.profiler, "springs.fem_solve");
    s.multigrid.update(a, pool);
    SolveStats stats = solvePcg(a, s.rhsFloat, s.dv, s.multigrid, net.pinned, net.cgTolerance,
                                net.cgMaxIterations, s.pcg, pool);
    if (releasePulling(net, a, s.dv, s.restingWeights, s.restingBlocks)) {
        // again without the contacts that held a leaving node, the preconditioner made again for it: the one
        // made with them took the released nodes for stiffly held, and the second solve took 10-36 iterations
        // against the first's 6 (the TetGen blob of fem_jelly; 1-6 with it made again, which costs less)
        s.multigrid.update(a, pool);
        const SolveStats again = solvePcg(a, s.rhsFloat, s.dv, s.multigrid, net.pinned, net.cgTolerance,
                                          net.cgMaxIterations, s.pcg, pool);
        stats.iterations += again.iterations;
        stats.relativeResidual = again.relativeResidual;
        stats.converged = again.converged;
        stats.solvedAgain = true;
    }
    restingFriction(net, s.restingWeights, s.dv);
    for (std::size_t i = 0; i < n; ++i) {
        if (!net.pinned[i]) {
            net.v[i] += s.dv[i].toVec3();
            net.x[i] += net.v[i] * h;
        }
    }
    return stats;
}

} // namespace

SolveStats stepFem(SpringNetwork& net, FemSolver& solver, std::vector<Vec3>& f, ForceIncidence& incidence,
                   const Environment& env, double h) {
    externalForces(net, env, net.x, net.v, f, incidence);
    if (net.integrator == Integrator::ImplicitEuler) {
        return implicitFem(net, solver, f, env, h);
    }
    addElementForces(net, net.x, net.v, f, net.fem.rotation, h);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (!net.pinned[i]) {
            net.v[i] += f[i] * (net.invMass[i] * h);
            net.x[i] += net.v[i] * h;
        }
    }
    return {};
}

} // namespace tumble
