#include "systems/spring_builders.h"

#include <string>

namespace tumble {

namespace {

void addLink(SpringNetwork& net, std::uint32_t a, std::uint32_t b, double k, double kd) {
    net.links.push_back({a, b, length(net.x[b] - net.x[a]), k, kd});
}

void addMasses(SpringNetwork& net, std::size_t n, double totalMass) {
    net.v.assign(n, Vec3{});
    net.invMass.assign(n, static_cast<double>(n) / totalMass);
    net.pinned.assign(n, 0);
}

} // namespace

void pinMasses(SpringNetwork& net, const std::vector<std::uint32_t>& pins) {
    for (std::uint32_t i : pins) {
        net.pinned[i] = 1;
    }
}

SpringNetwork buildRope(const RopeDef& def) {
    SpringNetwork net;
    net.kind = NetworkKind::Rope;
    const auto n = static_cast<std::uint32_t>(def.segments + 1);
    for (std::uint32_t i = 0; i < n; ++i) {
        net.x.push_back(def.origin + def.direction * (def.length * i / def.segments));
    }
    addMasses(net, n, def.mass);
    for (std::uint32_t i = 0; i + 1 < n; ++i) {
        addLink(net, i, i + 1, def.stiffness, def.damping);
    }
    if (def.bend > 0.0) {
        for (std::uint32_t i = 0; i + 2 < n; ++i) {
            addLink(net, i, i + 2, def.bend, def.damping);
        }
    }
    net.grid = {n, 1, 1};
    pinMasses(net, def.pins);
    return net;
}

SpringNetwork buildCloth(const ClothDef& def) {
    SpringNetwork net;
    net.kind = NetworkKind::Cloth;
    const auto rows = static_cast<std::uint32_t>(def.rows), cols = static_cast<std::uint32_t>(def.cols);
    // a tube's columns wrap around: column cols is column 0 again
    auto at = [cols](std::uint32_t r, std::uint32_t c) { return r * cols + c % cols; };
    const std::uint32_t across = def.tube ? cols : cols - 1; // quads (and links) along a row
    const double radius = def.size[0] / (2.0 * 3.14159265358979323846);
    for (std::uint32_t r = 0; r < rows; ++r) {
        for (std::uint32_t c = 0; c < cols; ++c) {
            const double w = static_cast<double>(r) / (rows - 1) - 0.5;
            if (def.tube) {
                // seen from the end rows start at, counter-clockwise: the triangles face outwards
                const double angle = 2.0 * 3.14159265358979323846 * c / cols;
                const double a = radius * std::cos(angle), b = radius * std::sin(angle);
                net.x.push_back(def.vertical ? def.centre + Vec3{a, -w * def.size[1], -b}
                                             : def.centre + Vec3{a, b, w * def.size[1]});
                continue;
            }
            const double u = static_cast<double>(c) / (cols - 1) - 0.5;
            net.x.push_back(def.vertical ? def.centre + Vec3{u * def.size[0], -w * def.size[1], 0.0}
                                         : def.centre + Vec3{u * def.size[0], 0.0, w * def.size[1]});
        }
    }
    addMasses(net, std::size_t(rows) * cols, def.mass);
    // links grouped by kind, and ordered so that consecutive links share no mass: the force loop's
    // scattered adds then never wait on each other
    for (std::uint32_t parity = 0; parity < 2; ++parity) { // stretch along rows: even columns, then odd
        for (std::uint32_t r = 0; r < rows; ++r) {
            for (std::uint32_t c = parity; c < across; c += 2) {
                addLink(net, at(r, c), at(r, c + 1), def.stretch, def.damping);
            }
        }
    }
    for (std::uint32_t parity = 0; parity < 2; ++parity) { // stretch along columns
        for (std::uint32_t r = parity; r + 1 < rows; r += 2) {
            for (std::uint32_t c = 0; c < cols; ++c) {
                addLink(net, at(r, c), at(r + 1, c), def.stretch, def.damping);
            }
        }
    }
    for (std::uint32_t r = 0; r + 1 < rows; ++r) { // shear: both diagonals of every quad
        for (std::uint32_t c = 0; c < across; ++c) {
            addLink(net, at(r, c), at(r + 1, c + 1), def.shear, def.damping);
        }
    }
    for (std::uint32_t r = 0; r + 1 < rows; ++r) {
        for (std::uint32_t c = 0; c < across; ++c) {
            addLink(net, at(r, c + 1), at(r + 1, c), def.shear, def.damping);
        }
    }
    if (def.bend > 0.0) { // bend: two apart, in four interleaved classes so neighbours do not touch
        for (std::uint32_t phase = 0; phase < 4; phase += 2) {
            for (std::uint32_t r = 0; r < rows; ++r) {
                for (std::uint32_t c = 0; c < (def.tube ? cols : cols - 2); ++c) {
                    if ((c % 4) / 2 == phase / 2) {
                        addLink(net, at(r, c), at(r, c + 2), def.bend, def.damping);
                    }
                }
            }
        }
        for (std::uint32_t phase = 0; phase < 4; phase += 2) {
            for (std::uint32_t r = 0; r + 2 < rows; ++r) {
                if ((r % 4) / 2 != phase / 2) {
                    continue;
                }
                for (std::uint32_t c = 0; c < cols; ++c) {
                    addLink(net, at(r, c), at(r + 2, c), def.bend, def.damping);
                }
            }
        }
    }
    // two triangles per quad, counter-clockwise seen from +z ("xy", rows going down) or from +y ("xz",
    // rows going towards +z): the same corner order in both planes. Like the links, in classes
    // (lower/upper triangle, even/odd column) whose consecutive members share no vertex
    for (std::uint32_t upper = 0; upper < 2; ++upper) {
        for (std::uint32_t parity = 0; parity < 2; ++parity) {
            for (std::uint32_t r = 0; r + 1 < rows; ++r) {
                for (std::uint32_t c = parity; c < across; c += 2) {
                    const std::uint32_t q00 = at(r, c), q01 = at(r, c + 1), q10 = at(r + 1, c),
                                        q11 = at(r + 1, c + 1);
                    net.triangles.push_back(upper ? std::array{q00, q11, q01} : std::array{q00, q10, q11});
                }
            }
        }
    }
    net.grid = {rows, cols, 1};
    pinMasses(net, def.pins);
    return net;
}

SpringNetwork buildSoftBody(const SoftBodyDef& def) {
    SpringNetwork net;
    net.kind = NetworkKind::SoftBody;
    const int nx = def.resolution[0], ny = def.resolution[1], nz = def.resolution[2];
    auto at = [&](int i, int j, int k) { return static_cast<std::uint32_t>((k * ny + j) * nx + i); };
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            for (int i = 0; i < nx; ++i) {
                net.x.push_back(def.centre + Vec3{(double(i) / (nx - 1) - 0.5) * def.size[0],
                                                  (double(j) / (ny - 1) - 0.5) * def.size[1],
                                                  (double(k) / (nz - 1) - 0.5) * def.size[2]});
            }
        }
    }
    addMasses(net, std::size_t(nx) * ny * nz, def.mass);
    auto inside = [&](int i, int j, int k) {
        return i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz;
    };
    // neighbour offsets, each undirected pair once: 3 axes, 6 face diagonals, 4 body diagonals
    static const int kStructural[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    static const int kShear[10][3] = {{1, 1, 0},  {1, -1, 0}, {1, 0, 1},  {1, 0, -1}, {0, 1, 1},
                                      {0, 1, -1}, {1, 1, 1},  {1, 1, -1}, {1, -1, 1}, {1, -1, -1}};
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            for (int i = 0; i < nx; ++i) {
                for (const auto& o : kStructural) {
                    if (inside(i + o[0], j + o[1], k + o[2])) {
                        addLink(net, at(i, j, k), at(i + o[0], j + o[1], k + o[2]), def.stiffness,
                                def.damping);
                    }
                    if (def.bend > 0.0 && inside(i + 2 * o[0], j + 2 * o[1], k + 2 * o[2])) {
                        addLink(net, at(i, j, k), at(i + 2 * o[0], j + 2 * o[1], k + 2 * o[2]), def.bend,
                                def.damping);
                    }
                }
                for (const auto& o : kShear) {
                    if (def.shear > 0.0 && inside(i + o[0], j + o[1], k + o[2])) {
                        addLink(net, at(i, j, k), at(i + o[0], j + o[1], k + o[2]), def.shear, def.damping);
                    }
                }
            }
        }
    }
    // the six faces of the lattice as triangles facing outwards, for the renderer (wind acts on cloth only)
    auto face = [&](int axis, int side) {
        const int u = (axis + 1) % 3, v = (axis + 2) % 3;
        const int res[3] = {nx, ny, nz};
        auto corner = [&](int a, int b) {
            int c[3];
            c[axis] = side ? res[axis] - 1 : 0;
            c[u] = a;
            c[v] = b;
            return at(c[0], c[1], c[2]);
        };
        for (int a = 0; a + 1 < res[u]; ++a) {
            for (int b = 0; b + 1 < res[v]; ++b) {
                const std::uint32_t p00 = corner(a, b), p10 = corner(a + 1, b), p11 = corner(a + 1, b + 1),
                                    p01 = corner(a, b + 1);
                // (u, v, axis) is right-handed: u x v points along +axis, so the +axis face keeps that order
                if (side) {
                    net.triangles.push_back({p00, p10, p11});
                    net.triangles.push_back({p00, p11, p01});
                } else {
                    net.triangles.push_back({p00, p11, p10});
                    net.triangles.push_back({p00, p01, p11});
                }
            }
        }
    };
    for (int axis = 0; axis < 3; ++axis) {
        face(axis, 0);
        face(axis, 1);
    }
    net.grid = {static_cast<std::uint32_t>(nx), static_cast<std::uint32_t>(ny),
                static_cast<std::uint32_t>(nz)};
    pinMasses(net, def.pins);
    return net;
}

bool clothPinPreset(const std::string& preset, int rows, int cols, std::vector<std::uint32_t>& out) {
    const auto r = static_cast<std::uint32_t>(rows), c = static_cast<std::uint32_t>(cols);
    out.clear();
    if (preset == "none") {
        return true;
    }
    if (preset == "top-corners") {
        out = {0, c - 1};
    } else if (preset == "corners") {
        out = {0, c - 1, (r - 1) * c, r * c - 1};
    } else if (preset == "top-row") {
        for (std::uint32_t i = 0; i < c; ++i) {
            out.push_back(i);
        }
    } else if (preset == "left-edge") {
        for (std::uint32_t i = 0; i < r; ++i) {
            out.push_back(i * c);
        }
    } else {
        return false;
    }
    return true;
}

} // namespace tumble
