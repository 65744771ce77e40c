#include "systems/water_system.h"

#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/retune.h"
#include "engine/run_report.h"
#include "engine/scene.h"
#include "engine/transform.h"
#include "systems/collision_system.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace tumble {

namespace {

constexpr double kCflSafety = 0.9; ///< wave steps are taken at this fraction of the CFL limit at most
constexpr double kFaceDrag = 1.05; ///< the drag coefficient of a cube face on (a mass in water: coupleMasses)
constexpr std::size_t kAbsorbGrain = 8192; ///< particles a chunk of absorbParticles' search
constexpr std::size_t kMassesGrain = 1024; ///< masses a chunk of coupleMasses
constexpr int kMaxNodes = 2048;            ///< per side
constexpr std::size_t kMaxNodesInAScene = std::size_t(1) << 22; ///< all surfaces: 4M (2048 x 2048)
constexpr double kMaxNodeStepsPerStep = 1e8;                    ///< wave-step node updates in one fixed step
constexpr double kCellsPerWave = 8.0;  ///< the shortest wave a maker may make, in cells (the grid carries it)
constexpr int kColumnsAcross = 24;     ///< a floating body's columns across its reach, at least
constexpr int kMostColumnsAcross = 96; ///< and at most (a body of many cells: two a cell up to this)

/// Water nodes loaded so far in the scene (a load-time tally).
struct WaterNodes {
    std::size_t count = 0;
};

void loadWater(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    Water w;
    const auto cells = r.vector<2>("cells", {64.0, 64.0}, 3.0, double(kMaxNodes));
    if (cells[0] != std::floor(cells[0]) || cells[1] != std::floor(cells[1])) {
        r.fail("cells", "'cells' are whole numbers of grid nodes along x and z, each 3 to " +
                            std::to_string(kMaxNodes));
    }
    w.nx = int(cells[0]);
    w.nz = int(cells[1]);
    const auto size = r.vector<2>("size", {10.0, 10.0}, 1e-3, 1e6);
    w.sizeX = size[0];
    w.sizeZ = size[1];
    w.depth = r.number("depth", 1.0, 0.0, 1e4);
    w.waveSpeed = r.number("wave_speed", 2.0, 1e-6, 1e4);
    w.damping = r.number("damping", 0.0, 0.0, 1e4);
    w.density = r.number("density", 1000.0, 1e-6, 1e6);
    w.bodyDrag = r.number("drag", 0.5, 0.0, 1e4);
    w.border = r.choice("border", "reflect", {"reflect", "absorb"}) == "reflect" ? WaterBorder::Reflect
                                                                                 : WaterBorder::Absorb;
    if (const toml::table* maker = r.subtable("wave_maker")) {
        TableReader m(*maker, r.where() + " wave_maker", r.context());
        const std::string edge = m.choice("edge", "-x", {"-x", "+x", "-z", "+z"});
        w.maker.edge = edge == "-x" ? 0 : edge == "+x" ? 1 : edge == "-z" ? 2 : 3;
        w.maker.amplitude = m.number("amplitude", 0.1, 0.0, 1e3);
        w.maker.period = m.number("period", 2.0, 1e-3, 1e6);
        m.finish();
        if (w.maker.amplitude >= w.depth && w.depth > 0.0) {
            m.fail("amplitude", "a wave maker's amplitude must be below the water's depth (" +
                                    std::to_string(w.depth) + " m)");
        }
        // a wave shorter than a few cells is not carried by the grid: it stays by the maker and piles up
        const double cell = std::max(w.sizeX / (w.nx - 1), w.sizeZ / (w.nz - 1));
        if (w.waveSpeed * w.maker.period < kCellsPerWave * cell) {
            char text[240];
            std::snprintf(
                text, sizeof text,
                "the maker's waves (wave_speed x period = %g m) are shorter than %g cells of the grid "
                "(%g m): make the period at least %g s, or the cells smaller",
                w.waveSpeed * w.maker.period, kCellsPerWave, kCellsPerWave * cell,
                kCellsPerWave * cell / w.waveSpeed);
            m.fail("period", text);
        }
    }
    w.centre = world.get<Transform>(entity).position;
    const std::size_t n = std::size_t(w.nx) * std::size_t(w.nz);
    // bounded work and memory: wave steps a fixed step from the CFL limit, nodes across the scene
    const double courant =
        w.waveSpeed * scene.dt * std::sqrt(1.0 / (w.dx() * w.dx()) + 1.0 / (w.dz() * w.dz()));
    const double substeps = std::ceil(courant / kCflSafety);
    if (substeps * double(n) > kMaxNodeStepsPerStep) {
        r.fail("wave_speed",
               "this grid would need " + std::to_string(std::int64_t(substeps)) + " wave steps (CFL) of " +
                   std::to_string(n) +
                   " nodes every fixed step; make the cells larger, the waves slower or dt smaller");
    }
    WaterNodes* total = world.tryResource<WaterNodes>();
    if (!total) {
        total = &world.setResource<WaterNodes>();
    }
    total->count += n;
    if (total->count > kMaxNodesInAScene) {
        r.fail("cells", "the scene's water surfaces have more than " + std::to_string(kMaxNodesInAScene) +
                            " nodes in all");
    }
    // heights, velocities, occupancy and the step's scratch (measured 37 bytes a node), and the drawn mesh
    r.charge("cells", std::uint64_t(n) * 96u, r.where() + " (" + std::to_string(n) + " nodes)");
    w.h.assign(n, 0.0);
    w.v.assign(n, 0.0);
    w.occupied.assign(n, 0.0);
    world.emplace<Water>(entity, std::move(w));
}

/// One wave step of dt: v += dt (c^2 Lap(h) - damping v), then h += dt v (symplectic Euler), in one pass
/// that writes the new heights beside the old (hNext, swapped with h after), so a row's new v and h need
/// only the old h around it. Rows are shared out in chunks, so any thread count gives the same bits.
void waveStep(Water& w, std::vector<double>& field, std::vector<double>& rate, double dt, WorkerPool& pool) {
    const int nx = w.nx, nz = w.nz;
    const double ax = w.waveSpeed * w.waveSpeed / (w.dx() * w.dx());
    const double az = w.waveSpeed * w.waveSpeed / (w.dz() * w.dz());
    const double keep = std::exp(-dt * w.damping); // exact decay: stable at any damping
    // an absorbing border moves as a wave leaving it would: u_t = -c du/dn (n outward), from the slope
    // inside; the rows at z's ends take it along z (the corners too), the other rows at x's ends along x
    const bool absorb = w.border == WaterBorder::Absorb;
    const double cx = w.waveSpeed / w.dx(), cz = w.waveSpeed / w.dz();
    const double* h = field.data();
    double* v = rate.data();
    w.hNext.resize(field.size());
    double* next = w.hNext.data();
    // rows per chunk: about 8k nodes, enough work to be worth a thread
    const std::size_t rowsPerChunk = std::max<std::size_t>(1, (std::size_t(1) << 13) / std::size_t(nx));
    pool.forEach(std::size_t(nz), rowsPerChunk, [&](std::size_t row_) {
        const int k = int(row_);
        // a reflecting border mirrors the row or column next to it (zero slope across the border)
        const double* row = h + std::size_t(k) * nx;
        const double* below = h + std::size_t(k > 0 ? k - 1 : 1) * nx;
        const double* above = h + std::size_t(k < nz - 1 ? k + 1 : nz - 2) * nx;
        double* vr = v + std::size_t(k) * nx;
        double* out = next + std::size_t(k) * nx;
        const int e = nx - 1;
        if (absorb && (k == 0 || k == nz - 1)) {
            const double* inside = k == 0 ? above : below;
            for (int i = 0; i < nx; ++i) {
                vr[i] = cz * (inside[i] - row[i]);
            }
        } else {
            vr[0] = absorb ? cx * (row[1] - row[0])
                           : keep * vr[0] + dt * (ax * 2.0 * (row[1] - row[0]) +
                                                  az * (below[0] + above[0] - 2.0 * row[0]));
            for (int i = 1; i < e; ++i) {
                const double lap =
                    ax * (row[i - 1] + row[i + 1] - 2.0 * row[i]) + az * (below[i] + above[i] - 2.0 * row[i]);
                vr[i] = keep * vr[i] + dt * lap;
            }
            vr[e] = absorb ? cx * (row[e - 1] - row[e])
                           : keep * vr[e] + dt * (ax * 2.0 * (row[e - 1] - row[e]) +
                                                  az * (below[e] + above[e] - 2.0 * row[e]));
        }
        for (int i = 0; i < nx; ++i) {
            out[i] = row[i] + dt * vr[i];
        }
    });
    std::swap(field, w.hNext);
}

/// The wave maker's edge at time t: its height and rate, eased in over the first period (so the first
/// crest does not start with a jump), on every node of its edge.
void driveEdge(const Water& w, std::vector<double>& field, std::vector<double>& rate, double t) {
    const WaveMaker& m = w.maker;
    const double omega = 2.0 * std::numbers::pi / m.period;
    double ease = 1.0, easeRate = 0.0;
    if (t < m.period) {
        ease = 0.5 * (1.0 - std::cos(std::numbers::pi * t / m.period));
        easeRate = 0.5 * std::numbers::pi / m.period * std::sin(std::numbers::pi * t / m.period);
    }
    const double height = m.amplitude * ease * std::sin(omega * t);
    const double speed = m.amplitude * (easeRate * std::sin(omega * t) + ease * omega * std::cos(omega * t));
    const bool alongZ = m.edge < 2; // the edges at x's ends run along z
    const int count = alongZ ? w.nz : w.nx;
    for (int j = 0; j < count; ++j) {
        const std::size_t n = alongZ ? std::size_t(j) * w.nx + (m.edge == 0 ? 0 : w.nx - 1)
                                     : std::size_t(m.edge == 2 ? 0 : w.nz - 1) * w.nx + j;
        field[n] = height;
        rate[n] = speed;
    }
}

/// Clips the interval [lo, hi] of the line p + t u (t along it) to the slab |p_a + t u_a| <= e on one axis.
bool clipSlab(double p, double u, double e, double& lo, double& hi) {
    if (std::abs(u) < 1e-12) {
        return std::abs(p) <= e;
    }
    const double t1 = (-e - p) / u, t2 = (e - p) / u;
    lo = std::max(lo, std::min(t1, t2));
    hi = std::min(hi, std::max(t1, t2));
    return lo <= hi;
}

/// Clips [lo, hi] to where the line p + t u is within r of the body's y axis (an infinite cylinder).
bool clipRound(const Vec3& p, const Vec3& u, double r, double& lo, double& hi) {
    const double a = u.x * u.x + u.z * u.z, b = p.x * u.x + p.z * u.z, c = p.x * p.x + p.z * p.z - r * r;
    if (a < 1e-12) {
        return c <= 0.0;
    }
    const double disc = b * b - a * c;
    if (disc < 0.0) {
        return false;
    }
    const double root = std::sqrt(disc);
    lo = std::max(lo, (-b - root) / a);
    hi = std::min(hi, (-b + root) / a);
    return lo <= hi;
}

/// Where the unit-direction line p + t u meets a ball of radius r about c: [lo, hi], or false.
bool ballSpan(const Vec3& p, const Vec3& u, const Vec3& c, double r, double& lo, double& hi) {
    const Vec3 q = p - c;
    const double b = dot(q, u), disc = b * b - (dot(q, q) - r * r);
    if (disc < 0.0) {
        return false;
    }
    lo = -b - std::sqrt(disc);
    hi = -b + std::sqrt(disc);
    return true;
}

/// The vertical extent of a body along the world's vertical line through (x, z): its bottom and top (world
/// y), or false when the line misses it. Exact for every shape (a tilted box's column is shorter at one
/// end than the other, which is what rights it); a hull is clipped by the planes of its faces.
bool verticalExtent(const RigidBody& b, double x, double z, double& bottom, double& top) {
    if (b.shape == ShapeKind::Sphere) {
        const double dx = x - b.position.x, dz = z - b.position.z, d2 = dx * dx + dz * dz;
        if (d2 >= b.radius * b.radius) {
            return false;
        }
        const double half = std::sqrt(b.radius * b.radius - d2);
        bottom = b.position.y - half;
        top = b.position.y + half;
        return true;
    }
    // the line in the body's frame: through p (the point at world height 0), along u (world up); a point at
    // parameter t on it is at world height t
    const Vec3 p = b.toLocal({x, 0.0, z});
    const Vec3 u = rotate(conjugate(b.orientation), Vec3{0.0, 1.0, 0.0});
    double lo = -1e300, hi = 1e300;
    switch (b.shape) {
    case ShapeKind::Box:
        if (!clipSlab(p.x, u.x, b.halfExtents.x, lo, hi) || !clipSlab(p.y, u.y, b.halfExtents.y, lo, hi) ||
            !clipSlab(p.z, u.z, b.halfExtents.z, lo, hi)) {
            return false;
        }
        break;
    case ShapeKind::Cylinder:
        if (!clipRound(p, u, b.radius, lo, hi) || !clipSlab(p.y, u.y, 0.5 * b.height, lo, hi)) {
            return false;
        }
        break;
    case ShapeKind::Capsule: {
        // the straight part and the two end balls: the capsule is convex, so their spans join into one
        bool any = false;
        double l = lo, h = hi;
        if (clipRound(p, u, b.radius, l, h) && clipSlab(p.y, u.y, 0.5 * b.height, l, h)) {
            lo = l;
            hi = h;
            any = true;
        } else {
            lo = 1e300;
            hi = -1e300;
        }
        for (double end : {-0.5 * b.height, 0.5 * b.height}) {
            if (ballSpan(p, u, Vec3{0.0, end, 0.0}, b.radius, l, h)) {
                lo = std::min(lo, l);
                hi = std::max(hi, h);
                any = true;
            }
        }
        if (!any) {
            return false;
        }
        break;
    }
    case ShapeKind::Convex: {
        const ShapeMesh& m = *b.mesh;
        for (std::size_t f = 0; f < m.triangles.size(); ++f) {
            const Vec3& n = m.faceNormals[f];
            const double along = dot(n, u), room = dot(n, m.vertices[m.triangles[f][0]] - p);
            if (std::abs(along) < 1e-12) {
                if (room < 0.0) {
                    return false;
                }
            } else if (along > 0.0) {
                hi = std::min(hi, room / along);
            } else {
                lo = std::max(lo, room / along);
            }
            if (lo > hi) {
                return false;
            }
        }
        break;
    }
    default:
        return false;
    }
    bottom = lo;
    top = hi;
    return true;
}

/// The box a body fills in the world (its own box, turned with it), from lo to hi.
void horizontalBox(const RigidBody& b, Vec3& lo, Vec3& hi) {
    Vec3 low, high; // in the body's frame
    switch (b.shape) {
    case ShapeKind::Sphere:
        high = {b.radius, b.radius, b.radius};
        break;
    case ShapeKind::Box:
        high = b.halfExtents;
        break;
    case ShapeKind::Capsule:
        high = {b.radius, 0.5 * b.height + b.radius, b.radius};
        break;
    case ShapeKind::Cylinder:
        high = {b.radius, 0.5 * b.height, b.radius};
        break;
    default:
        low = b.mesh ? b.mesh->lo : Vec3{-0.5, -0.5, -0.5};
        high = b.mesh ? b.mesh->hi : Vec3{0.5, 0.5, 0.5};
    }
    if (b.shape != ShapeKind::Convex) {
        low = high * -1.0;
    }
    const Vec3 half = (high - low) * 0.5, mid = b.toWorld((high + low) * 0.5);
    Vec3 reach;
    for (const Vec3& axis : {Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}}) {
        const Vec3 along = rotate(b.orientation, axis);
        const double s = axis.x != 0 ? half.x : axis.y != 0 ? half.y : half.z;
        reach += Vec3{std::abs(along.x), std::abs(along.y), std::abs(along.z)} * s;
    }
    lo = mid - reach;
    hi = mid + reach;
}

/// The smallest half size of a body: its moment of inertia is at least 0.4 m r^2 with r this.
double smallestHalfExtent(const RigidBody& b) {
    switch (b.shape) {
    case ShapeKind::Sphere:
    case ShapeKind::Capsule:
    case ShapeKind::Cylinder:
        return b.shape == ShapeKind::Cylinder ? std::min(b.radius, 0.5 * b.height) : b.radius;
    case ShapeKind::Box:
        return std::min({b.halfExtents.x, b.halfExtents.y, b.halfExtents.z});
    default: {
        const Vec3 d = b.mesh ? (b.mesh->hi - b.mesh->lo) * 0.5 : Vec3{0.5, 0.5, 0.5};
        return std::min({d.x, d.y, d.z});
    }
    }
}

/// How far a body reaches from its centre, horizontally at most.
double reachOf(const RigidBody& b) {
    switch (b.shape) {
    case ShapeKind::Sphere:
        return b.radius;
    case ShapeKind::Box:
        return length(b.halfExtents);
    case ShapeKind::Capsule:
        return b.radius + 0.5 * b.height;
    case ShapeKind::Cylinder:
        return length(Vec3{b.radius, 0.5 * b.height, b.radius});
    default:
        return b.mesh ? std::max(length(b.mesh->lo), length(b.mesh->hi)) : 1.0;
    }
}

/// The volume of a body, for the share of it under water.
double bodyVolume(const RigidBody& b) {
    switch (b.shape) {
    case ShapeKind::Sphere:
        return 4.0 / 3.0 * std::numbers::pi * b.radius * b.radius * b.radius;
    case ShapeKind::Box:
        return 8.0 * b.halfExtents.x * b.halfExtents.y * b.halfExtents.z;
    case ShapeKind::Cylinder:
        return std::numbers::pi * b.radius * b.radius * b.height;
    case ShapeKind::Capsule:
        return std::numbers::pi * b.radius * b.radius * (b.height + 4.0 / 3.0 * b.radius);
    default: {
        const Vec3 d = b.mesh ? b.mesh->hi - b.mesh->lo : Vec3{1, 1, 1};
        return 0.5 * d.x * d.y * d.z; // a hull fills about half its box
    }
    }
}

/// Where world (x, z), on the grid, falls between nodes: the node below-left of it (n00), the one above
/// it in z (n01; n00 + 1 and n01 + 1 are their neighbours in x), and how far along each way (0 to 1).
struct Corners {
    int i = 0, k = 0; ///< the cell's lower node along x and z
    std::size_t n00 = 0, n01 = 0;
    double fx = 0.0, fz = 0.0;
};

Corners cornersAt(const Water& w, double x, double z) {
    const double gx = std::clamp((x - w.nodeX(0)) / w.dx(), 0.0, double(w.nx - 1));
    const double gz = std::clamp((z - w.nodeZ(0)) / w.dz(), 0.0, double(w.nz - 1));
    const int i = std::min(int(gx), w.nx - 2), k = std::min(int(gz), w.nz - 2);
    Corners c;
    c.i = i;
    c.k = k;
    c.n00 = std::size_t(k) * w.nx + i;
    c.n01 = c.n00 + std::size_t(w.nx);
    c.fx = gx - i;
    c.fz = gz - k;
    return c;
}

/// A node's share of its cell inside the grid (1, a half on an edge, a quarter in a corner): the wave step
/// keeps the sum of share x height between reflecting borders, so the water's volume is that sum x dx dz.
double nodeShare(const Water& w, int i, int k) {
    return (i == 0 || i == w.nx - 1 ? 0.5 : 1.0) * (k == 0 || k == w.nz - 1 ? 0.5 : 1.0);
}

/// Keeps the ambient surface from the first time anything reaches over the water: so far every wave is the
/// ambient's (nothing has dented it).
void startAmbient(Water& w) {
    if (!w.ambient.empty()) {
        return;
    }
    w.ambient = w.h;
    w.ambientV = w.v;
    w.ambientStill = std::all_of(w.h.begin(), w.h.end(), [](double x) { return x == 0.0; }) &&
                     std::all_of(w.v.begin(), w.v.end(), [](double x) { return x == 0.0; }) &&
                     w.maker.edge < 0;
}

/// A field of heights' world height at (x, z), bilinear between the four nodes round it, and its slope
/// (d/dx, 0, d/dz).
double surfaceAt(const Water& w, const std::vector<double>& field, const Corners& c, Vec3& slope) {
    const double* a = field.data();
    const double a00 = a[c.n00], a10 = a[c.n00 + 1], a01 = a[c.n01], a11 = a[c.n01 + 1];
    slope = Vec3{((a10 - a00) * (1.0 - c.fz) + (a11 - a01) * c.fz) / w.dx(), 0.0,
                 ((a01 - a00) * (1.0 - c.fx) + (a11 - a10) * c.fx) / w.dz()};
    return w.centre.y + (a00 * (1.0 - c.fx) + a10 * c.fx) * (1.0 - c.fz) +
           (a01 * (1.0 - c.fx) + a11 * c.fx) * c.fz;
}

/// The ambient surface's height and slope (surfaceAt).
double ambientAt(const Water& w, const Corners& c, Vec3& slope) {
    return surfaceAt(w, w.ambient, c, slope);
}

/// Adds a volume, given as a height over one whole cell, to the four nodes round a point by their bilinear
/// weights. A node on the grid's edge holds half a cell and a corner a quarter (nodeShare), so it rises by
/// its weight over its share: the volume, the sum of share x height x dx dz, grows by height x dx dz
/// wherever the point is. (Caught: before, a drop into the outermost ring of cells added half its volume
/// or less, and a body there displaced as little.)
void spread(const Water& w, std::vector<double>& field, const Corners& c, double height) {
    field[c.n00] += height * (1.0 - c.fx) * (1.0 - c.fz) / nodeShare(w, c.i, c.k);
    field[c.n00 + 1] += height * c.fx * (1.0 - c.fz) / nodeShare(w, c.i + 1, c.k);
    field[c.n01] += height * (1.0 - c.fx) * c.fz / nodeShare(w, c.i, c.k + 1);
    field[c.n01 + 1] += height * c.fx * c.fz / nodeShare(w, c.i + 1, c.k + 1);
}

/// The velocity a mass in water would end the next step with under gravity and the water alone, from v: the
/// push (lift and slope) with the heave implicit in the waterline's stiffness k = rho g side^2 while its cube
/// crosses the surface (`crossing`), m (v' - v) = dt (m g + push - k dt v'); then the water's resistance
/// to the cube's face, 1/2 rho Cd side^2 |v'| v' on its part under water, implicit in the speed s = |v'| it
/// ends with: v' (1 + dt c s) = v, so dt c s^2 + s = |v| with c `resist` (it slows a mass to rest at most,
/// never back), what sets the speed a mass sinks or rises at; then the water's `drag`, as for bodies.
/// (Without the face's resistance and the implicit heave, a cloth of a fiftieth of water's density dropped
/// from 2 m was thrown 1.2 m back off the surface by the whole lift of the masses a step took under;
/// without the heave alone it never came to rest.)
Vec3 endVelocity(const Water& w, const Vec3& v0, const Vec3& push, const Vec3& gravity, double side,
                 double under, double m, bool crossing, double dt) {
    const double g = std::max(0.0, -gravity.y);
    Vec3 v = v0 + (gravity + push * (1.0 / m)) * dt;
    const double k = crossing ? w.density * g * side * side : 0.0;
    v.y = (m * (v0.y + dt * gravity.y) + dt * push.y) / (m + k * dt * dt);
    const double resist = 0.5 * w.density * kFaceDrag * side * side * under / m, speed = length(v);
    if (resist > 0.0 && speed > 0.0) {
        const double ends = 2.0 * speed / (1.0 + std::sqrt(1.0 + 4.0 * dt * resist * speed));
        v = v * (ends / speed);
    }
    return v * std::exp(-w.bodyDrag * under * dt);
}

/// Buoyancy, drag and displacement between one water surface and a spring network's masses (cloth, ropes,
/// soft bodies, fem bodies), mass by mass; returns whether any mass displaces water.
///
/// Each mass stands for a cube of its share of the network's volume (SpringNetwork::volumePerKg: a cloth's
/// sheet and a rope's strand are as thick as their `thickness`), upright about it; the part of that cube
/// between the pool's floor and the ambient surface (as for bodies: a network does not float on its own
/// dent) is lifted by the weight of its water, with the response to the mass's own heave implicit in its
/// waterline's stiffness, rho g times the cube's face (so a cloth of a tenth of the water's density lies on
/// the surface at any step rather than bouncing off it); the surface's slope carries it, and the water's
/// drag slows it (the exact decay of the step, in proportion to the part under water). What it displaces
/// leaves the nodes round it, as a body's does. A network of point masses (volume zero) takes the drag
/// alone. The push goes to the next step as a force (SpringNetwork::waterForce): the velocity change
/// endVelocity works out, less the gravity the step adds itself (a mass anchored to a body hands it on).
bool coupleMasses(Water& w, SpringNetwork& net, const Vec3& gravity, double dt, WorkerPool& pool) {
    const double area = w.dx() * w.dz();
    const double g = std::max(0.0, -gravity.y);
    const double floor = w.centre.y - w.depth;
    const double spanX = w.nodeX(w.nx - 1), spanZ = w.nodeZ(w.nz - 1);
    const std::size_t n = net.x.size();
    // the masses share out over the pool's threads, each writing its own force and displaced volume; the
    // volumes are spread on the grid after, in mass order (the same bits at any thread count). Until the
    // first thing reaches over the water the ambient surface is the surface itself (startAmbient)
    const std::vector<double>& ambient = w.ambient.empty() ? w.h : w.ambient;
    const bool hadForce = !net.waterForce.empty();
    if (!hadForce) {
        net.waterForce.assign(n, Vec3{});
    }
    w.massDisplaced.assign(n, 0.0);
    struct Count {
        std::size_t over = 0, under = 0; ///< masses over the water's grid, and those in the water
        Count& operator+=(const Count& o) {
            over += o.over;
            under += o.under;
            return *this;
        }
    };
    const Count count = pool.sum(n, kMassesGrain, Count{}, [&](std::size_t first, std::size_t end) {
        Count part;
        for (std::size_t i = first; i < end; ++i) {
            const Vec3& p = net.x[i];
            if (net.invMass[i] <= 0.0 || !(p.x >= w.nodeX(0) && p.x <= spanX) ||
                !(p.z >= w.nodeZ(0) && p.z <= spanZ) || p.y < floor) {
                continue;
            }
            ++part.over;
            const Corners c = cornersAt(w, p.x, p.z);
            Vec3 slope;
            const double surface = surfaceAt(w, ambient, c, slope);
            const double m = 1.0 / net.invMass[i];
            const double volume = net.volumePerKg * m;
            const double side = std::cbrt(volume);
            // the part of the cube under water (a point: all of it or none)
            const double bottom = std::max(p.y - 0.5 * side, floor), top = p.y + 0.5 * side;
            const double under = side > 0.0 ? std::clamp((std::min(surface, top) - bottom) / side, 0.0, 1.0)
                                            : (p.y < surface ? 1.0 : 0.0);
            if (under <= 0.0) {
                continue;
            }
            ++part.under;
            const double displaced = volume * under;
            // (a held mass gets the same force: an anchored one hands it to its body, and one unpinned
            // before the next step moves off with it as a free mass would)
            const Vec3 push = slope * (-w.density * g * displaced) + gravity * (-w.density * displaced);
            const bool crossing = top > surface && p.y - 0.5 * side < surface;
            const Vec3 ends = endVelocity(w, net.v[i], push, gravity, side, under, m, crossing, dt);
            net.waterForce[i] += (ends - net.v[i] - gravity * dt) * (m / dt);
            w.massDisplaced[i] = displaced;
        }
        return part;
    });
    if (count.over > 0) {
        startAmbient(w);
    }
    if (count.under == 0 && !hadForce) {
        net.waterForce.clear(); // (none in the water: the network's bits are as without water)
    }
    bool touched = false;
    for (std::size_t i = 0; i < n; ++i) {
        if (w.massDisplaced[i] > 0.0) {
            spread(w, w.occupying, cornersAt(w, net.x[i].x, net.x[i].z), w.massDisplaced[i] / area);
            touched = true;
        }
    }
    return touched;
}

/// Buoyancy, drag and displacement between one water surface and the moving bodies in it.
///
/// Bodies float on the ambient surface (the waves they did not make), so that their own dent never lifts
/// or sinks them: read from the surface they dent, a body fed back into itself (a sinking crate's trough
/// sank it further; the displaced water piled around it pushed it out harder than it came in) and grew
/// without bound. The body is cut into columns on a grid of its own (at least 24 across, two a water
/// cell), each with its exact vertical extent (what rights a tilted box: its columns are deeper on its low
/// side) against the ambient surface read between the nodes, and each column's
/// submerged part is lifted by the weight of its water at its middle. The lift's response to the body's
/// own motion is taken implicitly (the heave stiffness of the waterline, rho g times its area, and the tilt
/// stiffness about each horizontal axis, rho g V GM), so a body a thousand times lighter than water settles
/// in a step instead of flying out: stable at any density ratio and step. (No added mass: an impulse cannot
/// tell a free body from a held one, and it weakened a tethered buoy's pull sixfold.) Waves carry a body by
/// the slope of the surface over it (the pressure gradient under a wave, g times the slope per unit of
/// displaced mass). The water feels the body through its displacement: the water a body pushes aside leaves
/// the nodes under it and raises the rest of the surface by as much.
void couple(World& world, Water& w, const Vec3& gravity, double dt, WorkerPool& pool) {
    std::vector<double>& now = w.occupying;
    const bool wasOccupied = w.anyOccupied; // `occupied` holds a share somewhere (else it is all zeros)
    if (!w.occupyingZero || now.size() != w.h.size()) {
        now.assign(w.h.size(), 0.0); // (kept clear while no body is in the water: a pass over the grid)
    }
    const double area = w.dx() * w.dz();        // a node's cell
    const double g = std::max(0.0, -gravity.y); // the stiffness of the waterline: rho g
    const double floor = w.centre.y - w.depth;  // the pool's floor: no water below it
    bool touched = false;                       // whether any body reaches into the water this step
    auto coupleBody = [&](RigidBody& b) {
        // the nodes under the body's horizontal reach
        const double reach = reachOf(b);
        // node indices, clamped in double first (a body far away must not overflow an int)
        auto index = [](double at, int last) { return int(std::clamp(at, -1.0, double(last) + 1.0)); };
        const int i0 = std::max(0, index(std::floor((b.position.x - reach - w.nodeX(0)) / w.dx()), w.nx));
        const int i1 =
            std::min(w.nx - 1, index(std::ceil((b.position.x + reach - w.nodeX(0)) / w.dx()), w.nx));
        const int k0 = std::max(0, index(std::floor((b.position.z - reach - w.nodeZ(0)) / w.dz()), w.nz));
        const int k1 =
            std::min(w.nz - 1, index(std::ceil((b.position.z + reach - w.nodeZ(0)) / w.dz()), w.nz));
        if (i0 > i1 || k0 > k1) {
            return; // not over the water
        }
        startAmbient(w);
        // the body's columns on a grid of its own over its box in the world (exact for an upright box), at
        // least kColumnsAcross a side and two a water cell, so that the footprint does not depend on where
        // the body sits on the water's grid (sampled at the nodes, a cube between them settled tilted and a
        // 3 cm ball sank)
        const double spanX = w.nodeX(w.nx - 1), spanZ = w.nodeZ(w.nz - 1);
        Vec3 lo, hi;
        horizontalBox(b, lo, hi);
        const double cell = std::min(w.dx(), w.dz());
        auto columns = [&](double width) { // clamped in double first (a huge body must not overflow an int)
            return int(std::clamp(std::ceil(2.0 * width / cell), double(kColumnsAcross),
                                  double(kMostColumnsAcross)));
        };
        const int acrossX = columns(hi.x - lo.x), acrossZ = columns(hi.z - lo.z);
        const double stepX = (hi.x - lo.x) / acrossX, stepZ = (hi.z - lo.z) / acrossZ, column = stepX * stepZ;
        double volume = 0.0, waterline = 0.0, waterlineMomentX = 0.0, waterlineMomentZ = 0.0;
        Vec3 centre, slope;
        for (int v = 0; v < acrossZ; ++v) {
            const double z = lo.z + (v + 0.5) * stepZ;
            if (z < w.nodeZ(0) || z > spanZ) {
                continue; // off the water
            }
            for (int u = 0; u < acrossX; ++u) {
                const double x = lo.x + (u + 0.5) * stepX;
                double bottom = 0.0, top = 0.0;
                if (x < w.nodeX(0) || x > spanX || !verticalExtent(b, x, z, bottom, top)) {
                    continue;
                }
                // the ambient surface there, bilinear between the four nodes round it, and its slope
                const Corners c = cornersAt(w, x, z);
                Vec3 columnSlope;
                const double surface = ambientAt(w, c, columnSlope);
                // the part in the water: between the pool's floor and the surface
                const double low = std::max(bottom, floor);
                const double depth = std::min(surface, top) - low;
                if (depth <= 0.0) {
                    continue;
                }
                const double displaced = depth * column;
                volume += displaced;
                centre += Vec3{x, low + 0.5 * depth, z} * displaced;
                slope += columnSlope * displaced;
                if (top > surface) { // the column crosses the surface: part of the waterline
                    const double rx = x - b.position.x, rz = z - b.position.z;
                    waterline += column;
                    waterlineMomentX += column * rx * rx;
                    waterlineMomentZ += column * rz * rz;
                }
                // the water it displaces leaves the four nodes round it, as heights over their cells
                spread(w, now, c, displaced / area);
                touched = true;
            }
        }
        if (volume <= 0.0) {
            return;
        }
        centre = centre * (1.0 / volume);
        const double m = b.mass;
        const Vec3 lift = gravity * (-w.density * volume); // the weight of the water displaced
        // heave, implicit in the waterline's stiffness k = rho g A: the lift where the step will leave the
        // body, lift - k dt v', with v' the velocity it ends with, m (v' - v) = dt (m g + lift - k dt v'),
        // taken as an impulse less the gravity the rigid system adds itself. Stable at any density and step;
        // fully under water (no waterline) it is the lift itself, so a body tied down pulls with all of it.
        const double k = w.density * g * waterline;
        const double after = (m * b.linearVelocity.y + dt * (m * gravity.y + lift.y)) / (m + k * dt * dt);
        Vec3 impulse{0.0, dt * lift.y - k * dt * dt * after, 0.0};
        // the pressure gradient under the waves: -rho g (slope) per unit of submerged volume; and lift along
        // gravity's horizontal part, if it has one
        impulse += (slope * (-w.density * g) + Vec3{lift.x, 0.0, lift.z}) * dt;
        // drag as the exact decay of the step (stable at any strength), in proportion to how much of the body
        // is in the water
        const double share = std::min(1.0, volume / bodyVolume(b));
        const double decay = 1.0 - std::exp(-w.bodyDrag * share * dt);
        b.impulse += impulse - b.linearVelocity * (decay * m);
        // the righting torque of the columns' lift about the centre of mass (none on a ball: its water
        // pushes through its centre), implicit in the tilt stiffness about each horizontal axis, rho g V GM
        // = rho g (the waterline's second moment about the axis + V (centre of buoyancy - centre of mass)
        // height), none where that is negative (an unstable float turns over freely) or zero (a log about
        // its axis); against the smallest moment of inertia the body could have (so it never overshoots)
        const double smallest = smallestHalfExtent(b);
        const double inertia = 0.4 * m * smallest * smallest;
        if (b.shape != ShapeKind::Sphere) {
            const Vec3 torque = cross(centre - b.position, lift);
            const double rise = volume * (centre.y - b.position.y);
            const double kx = std::max(0.0, w.density * g * (waterlineMomentZ + rise)); // turning about x
            const double kz = std::max(0.0, w.density * g * (waterlineMomentX + rise)); // about z
            auto turn = [&](double tau, double omega, double stiff) {
                return (tau * dt - omega * stiff * dt * dt) * (inertia / (inertia + stiff * dt * dt));
            };
            b.angularImpulse += Vec3{turn(torque.x, b.angularVelocity.x, kx), torque.y * dt,
                                     turn(torque.z, b.angularVelocity.z, kz)};
        }
        b.angularImpulse -= b.angularVelocity * (decay * inertia);
    };
    world.view<RigidBody>().each([&](Entity, RigidBody& b) {
        if (b.dynamic() && !b.frozen) {
            coupleBody(b);
        }
    });
    // a 2D body floats as the slab it is drawn as (systems/collision_system.h), and takes the push in its
    // plane and the turn about z
    if (Pool<RigidBody2D>* bodies2d = world.findPool<RigidBody2D>()) {
        for (std::size_t k = 0; k < bodies2d->size(); ++k) {
            RigidBody2D& b = bodies2d->values()[k];
            if (!b.dynamic()) {
                continue;
            }
            const Transform* t = world.tryGet<Transform>(bodies2d->entities()[k]);
            RigidBody slab = slabOf(b, t ? t->position.z : 0.0, 0.0);
            coupleBody(slab);
            b.impulse[0] += slab.impulse.x;
            b.impulse[1] += slab.impulse.y;
            b.angularImpulse += slab.angularImpulse.z;
        }
    }
    world.view<SpringNetwork>().each([&](Entity, SpringNetwork& net) {
        if (!net.frozen && coupleMasses(w, net, gravity, dt, pool)) {
            touched = true;
        }
    });
    // the water a body pushes aside as it sinks in leaves the nodes under it and raises the free surface
    // everywhere else by as much in all (and flows back as the body rises): the volume (the nodes' shares
    // of their heights) is kept, and the dent under the body makes the waves
    w.occupyingZero = !touched;
    if (!touched && !wasOccupied) {
        return; // no body in the water, now or last step: nothing moves (the pass below would add zeros)
    }
    w.anyOccupied = touched;
    double moved = 0.0, free = 0.0;
    for (int k = 0; k < w.nz; ++k) {
        for (int i = 0; i < w.nx; ++i) {
            const std::size_t n = std::size_t(k) * w.nx + i;
            const double change = now[n] - w.occupied[n], share = nodeShare(w, i, k);
            w.h[n] -= change;
            moved += change * share;
            free += now[n] <= 0.0 ? share : 0.0;
        }
    }
    if (moved != 0.0 && free > 0.0) {
        const double rise = moved / free;
        for (std::size_t n = 0; n < w.h.size(); ++n) {
            if (now[n] <= 0.0) {
                w.h[n] += rise;
            }
        }
    }
    w.occupied.swap(now);
    w.occupyingZero = !wasOccupied;
}

/// Particles that collide (`collide = true`) and fall in through the surface this step (under it now,
/// above it a step ago, and above the pool's floor) are drops the water takes in: each dies in its
/// emitter's next update, and its volume, a ball as wide as the particle's size at its age, is added to the
/// surface where it fell (over the four nodes round it, and to the ambient surface too, so that bodies rock
/// on the rings): rain raises the pond by what falls in and rings it. A particle born under water, or that
/// does not collide, passes through. The candidates (over the grid, below its highest node) are found chunk
/// by chunk over the pool's threads and taken in in particle order: the same bits at any thread count.
void absorbParticles(World& world, Water& w, double dt, WorkerPool& pool) {
    if (!world.findPool<ParticleEmitter>()) {
        return;
    }
    const float x0 = float(w.nodeX(0)), x1 = float(w.nodeX(w.nx - 1));
    const float z0 = float(w.nodeZ(0)), z1 = float(w.nodeZ(w.nz - 1));
    const float floor = float(w.centre.y - w.depth);
    const double area = w.dx() * w.dz();
    float highest = 0.0f; // (found when an emitter has particles that collide)
    bool measured = false;
    world.view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) {
        ParticlePool& p = e.pool;
        if (!e.def.collide || p.count == 0) {
            return;
        }
        if (!measured) {
            highest = float(w.centre.y + *std::max_element(w.h.begin(), w.h.end()));
            measured = true;
        }
        w.drops.resize(WorkerPool::chunkCount(p.count, kAbsorbGrain));
        pool.forChunks(p.count, kAbsorbGrain, [&](std::size_t c, std::size_t first, std::size_t end) {
            w.drops[c].clear();
            for (std::size_t i = first; i < end; ++i) {
                // (a particle already dying this step, taken in or at the end of its life, is left alone)
                if (p.py[i] < highest && p.py[i] > floor && p.px[i] >= x0 && p.px[i] <= x1 && p.pz[i] >= z0 &&
                    p.pz[i] <= z1 && std::int32_t(p.deathStep[i] - p.clock) > 0) {
                    w.drops[c].push_back(std::uint32_t(i));
                }
            }
        });
        for (const std::vector<std::uint32_t>& chunk : w.drops) {
            for (const std::uint32_t i : chunk) {
                const Corners c = cornersAt(w, p.px[i], p.pz[i]);
                Vec3 slope; // (not needed here)
                const double surface = surfaceAt(w, w.h, c, slope);
                const double was = double(p.py[i]) - double(p.vy[i]) * dt; // where it was a step ago
                if (!(double(p.py[i]) < surface && was >= surface)) {
                    continue;
                }
                const float life = std::min(1.0f, float(p.clock - p.birthStep[i]) /
                                                      (float(p.deathStep[i] - p.birthStep[i]) + 1.0f));
                const double across = particleSize(e.def, life);
                const double height = std::numbers::pi / 6.0 * across * across * across / area;
                spread(w, w.h, c, height);
                if (!w.ambient.empty()) {
                    spread(w, w.ambient, c, height);
                    w.ambientStill = false; // its rings travel on the surface bodies float on
                }
                p.deathStep[i] = p.clock; // dies in the next update
            }
        }
    });
}

void dumpWater(const Water& w, JsonWriter& out) {
    out.key("h").beginArray();
    for (int k = 0; k < w.nz; ++k) {
        out.numbers(w.h.data() + std::size_t(k) * w.nx, std::size_t(w.nx));
    }
    out.endArray();
}

void hashWater(const Water& w, Hasher& h) {
    h.add(w.h);
    h.add(w.v);
    h.add(w.occupied);
    h.add(w.ambient);
    h.add(w.ambientV);
}

} // namespace

void stepWater(World& world, const StepContext& ctx) {
    if (const Pool<Water>* waters = world.findPool<Water>(); waters && waters->size() > 0) {
        // the water's push on spring networks' masses is this step's alone (every surface adds its own)
        world.view<SpringNetwork>().each([](Entity, SpringNetwork& net) { net.waterForce.clear(); });
    }
    const auto& g = world.resource<SceneDef>().gravity;
    const Vec3 gravity{g[0], g[1], g[2]};
    world.view<const Name, Water>().each([&](Entity, const Name& name, Water& w) {
        // the CFL limit of the scheme: c dt sqrt(1/dx^2 + 1/dz^2) <= 1
        const double courant =
            w.waveSpeed * ctx.dt * std::sqrt(1.0 / (w.dx() * w.dx()) + 1.0 / (w.dz() * w.dz()));
        const auto substeps = std::uint32_t(std::max(1.0, std::ceil(courant / kCflSafety)));
        if (substeps > 1 && w.substeps == 1) {
            world.resource<RunReport>().notes.push_back(
                "water '" + name.value +
                "': dt is above the stability (CFL) limit of its grid (Courant number " +
                std::to_string(courant) + "); it takes " + std::to_string(substeps) + " wave steps per step");
        }
        w.substeps = substeps;
        {
            ProfileStage stage(ctx.profiler, "water.bodies");
            couple(world, w, gravity, ctx.dt, poolOr(ctx.pool));
            absorbParticles(world, w, ctx.dt, poolOr(ctx.pool));
        }
        ProfileStage stage(ctx.profiler, "water.waves");
        const double step = ctx.dt / substeps;
        const bool ambient = !w.ambient.empty() && !w.ambientStill;
        for (std::uint32_t s = 0; s < substeps; ++s) {
            waveStep(w, w.h, w.v, step, poolOr(ctx.pool));
            if (ambient) {
                waveStep(w, w.ambient, w.ambientV, step, poolOr(ctx.pool));
            }
            if (w.maker.edge >= 0) {
                const double t = ctx.time + step * double(s + 1);
                driveEdge(w, w.h, w.v, t);
                if (ambient) {
                    driveEdge(w, w.ambient, w.ambientV, t);
                }
            }
        }
    });
}

void registerWaterSystem(Catalog& catalog) {
    catalog.addComponent({"water", loadWater, {}, true});
    catalog.addState<Water>("water", dumpWater, hashWater);
    // a `set` event on the water's keys (engine/retune.h): its physics, not its grid
    catalog.addRetune(Retune{
        {"water"},
        [](const World& w, Entity e) { return w.has<Water>(e); },
        [](const World& bw, Entity b, const World& aw, Entity a) -> std::optional<std::string> {
            const Water &was = bw.get<Water>(b), &now = aw.get<Water>(a);
            if (was.nx != now.nx || was.nz != now.nz || was.sizeX != now.sizeX || was.sizeZ != now.sizeZ ||
                was.border != now.border || was.centre != now.centre) {
                return std::string("a water surface's grid (cells, size, border, place) cannot change during "
                                   "a run; its wave_speed, damping, depth, density and drag can");
            }
            return std::nullopt;
        },
        [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
            Water& water = w.get<Water>(e);
            const Water &was = bw.get<Water>(b), &now = aw.get<Water>(a);
            takeChanged(water.depth, was.depth, now.depth);
            takeChanged(water.waveSpeed, was.waveSpeed, now.waveSpeed);
            takeChanged(water.damping, was.damping, now.damping);
            takeChanged(water.density, was.density, now.density);
            takeChanged(water.bodyDrag, was.bodyDrag, now.bodyDrag);
            takeChanged(water.maker.amplitude, was.maker.amplitude, now.maker.amplitude);
            takeChanged(water.maker.period, was.maker.period, now.maker.period);
            takeChanged(water.maker.edge, was.maker.edge, now.maker.edge);
            water.ambientStill = water.ambientStill && water.maker.edge < 0;
        }});
    // disturb: a smooth bump of `amount` metres (negative: a dip) within `radius` of `position`
    catalog.addEventAction(
        {"disturb",
         "a water surface",
         {"position", "radius", "amount"},
         [](const World& w, Entity e) { return w.has<Water>(e); },
         [](const World&, Entity, const EventDef& ev) -> std::optional<std::string> {
             if (ev.radius <= 0.0) {
                 return "needs radius > 0 (m) and position = [x, y, z]; amount is the height of the bump (m)";
             }
             return std::nullopt;
         },
         [](World& world, Entity e, const EventDef& ev) {
             Water& w = world.get<Water>(e);
             w.ambientStill = false; // a disturbance is a wave no body made: the ambient surface has it too
             for (int k = 0; k < w.nz; ++k) {
                 for (int i = 0; i < w.nx; ++i) {
                     const double d = std::hypot(w.nodeX(i) - ev.position[0], w.nodeZ(k) - ev.position[2]);
                     if (d < ev.radius) {
                         const double bump =
                             ev.amount * 0.5 * (1.0 + std::cos(std::numbers::pi * d / ev.radius));
                         w.h[std::size_t(k) * w.nx + i] += bump;
                         if (!w.ambient.empty()) {
                             w.ambient[std::size_t(k) * w.nx + i] += bump;
                         }
                     }
                 }
             }
         }});
}

} // namespace tumble
