#include "systems/obj_mesh.h"

#include "engine/assets.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace tumble {

namespace fs = std::filesystem;

namespace {
constexpr std::size_t kMaxVertices = 1u << 20;
constexpr std::uint64_t kMaxObjBytes = 256ull << 20;
constexpr std::size_t kMaxTriangles = 2u << 20;
constexpr std::size_t kMaxHullVertices = 4096;
constexpr double kMaxCoordinate = 1e9; ///< m: beyond it products of coordinates overflow the checks below
} // namespace

std::shared_ptr<const ShapeMesh> readObjMesh(const std::string& file, const std::string& displayName) {
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) {
        throw std::runtime_error(displayName + ": not a regular file");
    }
    const auto size = fs::file_size(file, ec);
    if (ec || size > kMaxObjBytes) {
        throw std::runtime_error(displayName + ": larger than a mesh may be (" +
                                 std::to_string(kMaxObjBytes >> 20) + " MiB)");
    }
    if (size == 0) { // nothing to read (and /proc's files, which say 0, may block a read forever)
        throw std::runtime_error(displayName + ": empty");
    }
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        throw std::runtime_error(displayName + ": cannot be read");
    }
    // one byte past its size, to see a file that changed since it was measured
    std::string text(static_cast<std::size_t>(size) + 1, '\0');
    in.read(text.data(), static_cast<std::streamsize>(text.size()));
    text.resize(static_cast<std::size_t>(in.gcount()));
    if (text.size() != size) {
        throw std::runtime_error(displayName + ": changed while it was read");
    }
    return parseObjMesh(text, displayName);
}

std::shared_ptr<const ShapeMesh> parseObjMesh(const std::string& text, const std::string& displayName) {
    std::istringstream in(text);
    auto mesh = std::make_shared<ShapeMesh>();
    mesh->path = displayName;
    std::string line;
    int lineNo = 0;
    auto fail = [&](const std::string& what) {
        throw std::runtime_error(displayName + ":" + std::to_string(lineNo) + ": " + what);
    };
    while (std::getline(in, line)) {
        ++lineNo;
        std::istringstream ss(line);
        std::string tag;
        ss >> tag;
        if (tag == "v") {
            Vec3 p;
            if (!(ss >> p.x >> p.y >> p.z) || !isFinite(p)) {
                fail("a vertex needs three finite numbers: 'v x y z'");
            }
            if (std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)}) > kMaxCoordinate) {
                fail("a vertex coordinate is beyond 1e9 m");
            }
            if (mesh->vertices.size() >= kMaxVertices) {
                fail("too many vertices (at most " + std::to_string(kMaxVertices) + ")");
            }
            mesh->vertices.push_back(p);
        } else if (tag == "f") {
            std::vector<std::uint32_t> corners;
            std::string corner;
            while (ss >> corner) {
                long index = 0;
                try {
                    index = std::stol(corner.substr(0, corner.find('/')));
                } catch (const std::exception&) {
                    fail("'" + corner + "' is not a vertex index");
                }
                // negative indices count back from the last vertex read
                const long n = static_cast<long>(mesh->vertices.size());
                const long resolved = index < 0 ? n + index : index - 1;
                if (index == 0 || resolved < 0 || resolved >= n) {
                    fail("vertex " + std::to_string(index) + " does not exist (" + std::to_string(n) +
                         " read so far)");
                }
                if (corners.size() + mesh->triangles.size() >= kMaxTriangles + 2) {
                    fail("too many triangles (at most " + std::to_string(kMaxTriangles) + ")");
                }
                corners.push_back(static_cast<std::uint32_t>(resolved));
            }
            if (corners.size() < 3) {
                fail("a face needs at least three vertices");
            }
            for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
                const std::array<std::uint32_t, 3> t{corners[0], corners[k], corners[k + 1]};
                const auto& v = mesh->vertices;
                if (length(cross(v[t[1]] - v[t[0]], v[t[2]] - v[t[0]])) <= 1e-12) {
                    fail("a face with no area (repeated or collinear vertices)");
                }
                mesh->triangles.push_back(t);
                mesh->faceLines.push_back(lineNo);
            }
        }
    }
    if (mesh->triangles.empty()) {
        throw std::runtime_error(displayName + ": no faces ('f' lines)");
    }
    mesh->lo = mesh->hi = mesh->vertices[mesh->triangles[0][0]];
    for (const Vec3& p : mesh->vertices) {
        mesh->lo = {std::min(mesh->lo.x, p.x), std::min(mesh->lo.y, p.y), std::min(mesh->lo.z, p.z)};
        mesh->hi = {std::max(mesh->hi.x, p.x), std::max(mesh->hi.y, p.y), std::max(mesh->hi.z, p.z)};
    }
    for (const auto& t : mesh->triangles) {
        const Vec3 n =
            cross(mesh->vertices[t[1]] - mesh->vertices[t[0]], mesh->vertices[t[2]] - mesh->vertices[t[0]]);
        mesh->faceNormals.push_back(n * (1.0 / length(n)));
    }
    return mesh;
}

std::shared_ptr<const ShapeMesh> convexHullMesh(const ShapeMesh& file) {
    auto fail = [&](int line, const std::string& what) {
        throw std::runtime_error(file.path + (line ? ":" + std::to_string(line) : "") + ": " + what);
    };
    // the check below tests every vertex against every face; a hull is a few hundred points at most (Bullet
    // keeps every point of a btConvexHullShape and visits them all in each support query)
    if (file.vertices.size() > kMaxHullVertices) {
        fail(0, "a convex shape has at most " + std::to_string(kMaxHullVertices) +
                    " vertices (this one has " + std::to_string(file.vertices.size()) +
                    "); use shape = \"mesh\" for a static one");
    }
    // a closed convex polyhedron of V vertices has at most 2V - 4 triangles; more means repeated faces
    if (file.triangles.size() + 4 > 2 * file.vertices.size()) {
        fail(0, "a convex shape of " + std::to_string(file.vertices.size()) + " vertices has at most " +
                    std::to_string(2 * file.vertices.size() - 4) + " triangles; this one has " +
                    std::to_string(file.triangles.size()));
    }
    // closed and wound outward: the signed volume of the tetrahedra from the origin is positive; its
    // centroid is the body's centre of mass
    double volume = 0.0;
    Vec3 moment;
    for (const auto& t : file.triangles) {
        const Vec3 &a = file.vertices[t[0]], &b = file.vertices[t[1]], &c = file.vertices[t[2]];
        const double v = dot(a, cross(b, c)) / 6.0;
        volume += v;
        moment += (a + b + c) * (v / 4.0);
    }
    if (!(volume > 0.0)) {
        fail(0, "a convex shape must be a closed hull with its faces counter-clockwise seen from outside "
                "(its volume comes out " +
                    std::to_string(volume) + " m^3)");
    }
    const Vec3 centre = moment * (1.0 / volume);
    const double size = length(file.hi - file.lo);
    for (std::size_t f = 0; f < file.triangles.size(); ++f) {
        const Vec3& on = file.vertices[file.triangles[f][0]];
        for (const Vec3& p : file.vertices) {
            if (dot(p - on, file.faceNormals[f]) > 1e-6 * size) {
                fail(file.faceLines[f],
                     "this face has points of the shape in front of it: a convex shape must "
                     "be its own convex hull, faces counter-clockwise seen from outside");
            }
        }
    }
    auto hull = std::make_shared<ShapeMesh>(file);
    for (Vec3& p : hull->vertices) {
        p -= centre;
    }
    hull->lo -= centre;
    hull->hi -= centre;
    hull->centre = centre;
    return hull;
}

std::string findMeshFile(const std::string& name, const std::string& scenarioFile) {
    const fs::path p(name);
    std::error_code ec;
    if (p.is_absolute()) {
        return fs::is_regular_file(p, ec) ? name : "";
    }
    const fs::path besideScenario = fs::path(scenarioFile).parent_path() / p;
    if (fs::is_regular_file(besideScenario, ec)) {
        return besideScenario.string();
    }
    const fs::path underRoot = fs::path(assetDirectory()).parent_path() / p;
    if (fs::is_regular_file(underRoot, ec)) {
        return underRoot.string();
    }
    return "";
}

} // namespace tumble
