#include "systems/water_system.h"

#include "components/rigid_body.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/retune.h"
#include "engine/run_report.h"
#include "engine/scene.h"
#include "engine/transform.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace tumble {

namespace {

constexpr double kCflSafety = 0.9; ///< wave steps are taken at this fraction of the CFL limit at most
constexpr int kMaxNodes = 2048;    ///< per side
constexpr std::size_t kMaxNodesInAScene = std::size_t(1) << 22; ///< all surfaces: 4M (2048 x 2048)
constexpr double kMaxNodeStepsPerStep = 1e8;                    ///< wave-step node updates in one fixed step

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
void waveStep(Water& w, double dt, WorkerPool& pool) {
    const int nx = w.nx, nz = w.nz;
    const double ax = w.waveSpeed * w.waveSpeed / (w.dx() * w.dx());
    const double az = w.waveSpeed * w.waveSpeed / (w.dz() * w.dz());
    const double keep = std::exp(-dt * w.damping); // exact decay: stable at any damping
    // an absorbing border moves as a wave leaving it would: u_t = -c du/dn (n outward), from the slope
    // inside; the rows at z's ends take it along z (the corners too), the other rows at x's ends along x
    const bool absorb = w.border == WaterBorder::Absorb;
    const double cx = w.waveSpeed / w.dx(), cz = w.waveSpeed / w.dz();
    const double* h = w.h.data();
    double* v = w.v.data();
    w.hNext.resize(w.h.size());
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
    std::swap(w.h, w.hNext);
}

/// The vertical extent of a body's column at world (x, z), and how much of the node's cell it covers, or
/// false when the column misses it. Spheres by the node's point; other shapes by their world-aligned
/// bounding box, with the cell's covered share (exact for an upright box).
bool columnOf(const RigidBody& b, double x, double z, double halfDx, double halfDz, double& bottom,
              double& top, double& cover) {
    cover = 1.0;
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
    Vec3 local;
    switch (b.shape) {
    case ShapeKind::Box:
        local = b.halfExtents;
        break;
    case ShapeKind::Capsule:
        local = {b.radius, 0.5 * b.height + b.radius, b.radius};
        break;
    case ShapeKind::Cylinder:
        local = {b.radius, 0.5 * b.height, b.radius};
        break;
    case ShapeKind::Convex:
        local = {std::max(-b.mesh->lo.x, b.mesh->hi.x), std::max(-b.mesh->lo.y, b.mesh->hi.y),
                 std::max(-b.mesh->lo.z, b.mesh->hi.z)};
        break;
    default:
        return false;
    }
    // the half extents of the rotated box, along the world axes
    Vec3 e;
    for (const Vec3& axis : {Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}}) {
        const Vec3 w = rotate(b.orientation, axis);
        const double s = axis.x != 0 ? local.x : axis.y != 0 ? local.y : local.z;
        e += Vec3{std::abs(w.x), std::abs(w.y), std::abs(w.z)} * s;
    }
    // how much of the node's cell (dx by dz about it) the box's footprint covers
    auto overlap = [](double c, double half, double lo, double hi) {
        return std::max(0.0, std::min(c + half, hi) - std::max(c - half, lo)) / (2.0 * half);
    };
    cover = overlap(x, halfDx, b.position.x - e.x, b.position.x + e.x) *
            overlap(z, halfDz, b.position.z - e.z, b.position.z + e.z);
    if (cover <= 0.0) {
        return false;
    }
    bottom = b.position.y - e.y;
    top = b.position.y + e.y;
    return true;
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

/// Buoyancy, drag and displacement between one water surface and the moving bodies in it.
void couple(World& world, Water& w, const Vec3& gravity, double dt) {
    std::vector<double>& now = w.occupying;
    const bool wasOccupied = w.anyOccupied; // `occupied` holds a share somewhere (else it is all zeros)
    if (!w.occupyingZero || now.size() != w.h.size()) {
        now.assign(w.h.size(), 0.0); // (kept clear while no body is in the water: a pass over the grid)
    }
    const double area = w.dx() * w.dz();
    bool touched = false; // whether any body reaches into the water this step
    world.view<RigidBody>().each([&](Entity, RigidBody& b) {
        if (!b.dynamic() || b.frozen) {
            return;
        }
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
        double volume = 0.0;
        Vec3 centre;
        for (int k = k0; k <= k1; ++k) {
            for (int i = i0; i <= i1; ++i) {
                double bottom = 0.0, top = 0.0, cover = 1.0;
                if (!columnOf(b, w.nodeX(i), w.nodeZ(k), 0.5 * w.dx(), 0.5 * w.dz(), bottom, top, cover)) {
                    continue;
                }
                // bodies float on the still surface: their own dents and the waves they make do not lift
                // them (read from the live surface, those fed back into the body and grew without bound)
                const std::size_t n = std::size_t(k) * w.nx + i;
                const double surface = w.centre.y;
                const double under = std::clamp(surface - bottom, 0.0, top - bottom);
                if (under <= 0.0) {
                    continue;
                }
                now[n] += under * cover;
                touched = true;
                volume += under * cover * area;
                centre += Vec3{w.nodeX(i), bottom + 0.5 * under, w.nodeZ(k)} * (under * cover * area);
            }
        }
        if (volume <= 0.0) {
            return;
        }
        centre = centre * (1.0 / volume);
        // buoyancy: the weight of the water displaced, upwards, at the centre of that volume; drag on the
        // motion through the water, in proportion to how much of the body is in it
        const Vec3 lift = gravity * (-w.density * volume);
        const double share = std::min(1.0, volume / bodyVolume(b));
        // drag as the exact decay of the step (stable at any strength): the velocity through the water, and
        // the turning (against the smallest moment of inertia the body could have, so never overshooting)
        const double decay = 1.0 - std::exp(-w.bodyDrag * share * dt);
        b.impulse += lift * dt - b.linearVelocity * (decay * b.mass);
        b.angularImpulse += cross(centre - b.position, lift * dt);
        const double smallest = smallestHalfExtent(b);
        b.angularImpulse -= b.angularVelocity * (decay * 0.4 * b.mass * smallest * smallest);
    });
    // the water a body pushes aside as it sinks in leaves the nodes under it and raises the free surface
    // everywhere else by as much in all (and flows back as the body rises): the volume is kept, and the dent
    // under the body makes the waves. (Put into the ring of nodes around the body instead, a sinking crate
    // raised spikes there that fed back into its buoyancy and grew without bound.)
    w.occupyingZero = !touched;
    if (!touched && !wasOccupied) {
        return; // no body in the water, now or last step: nothing moves (the pass below would add zeros)
    }
    w.anyOccupied = touched;
    double moved = 0.0;
    std::size_t free = 0;
    for (std::size_t n = 0; n < w.h.size(); ++n) {
        const double change = now[n] - w.occupied[n];
        w.h[n] -= change;
        moved += change;
        free += now[n] <= 0.0;
    }
    if (moved != 0.0 && free > 0) {
        const double rise = moved / double(free);
        for (std::size_t n = 0; n < w.h.size(); ++n) {
            if (now[n] <= 0.0) {
                w.h[n] += rise;
            }
        }
    }
    w.occupied.swap(now);
    w.occupyingZero = !wasOccupied;
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
}

} // namespace

void stepWater(World& world, const StepContext& ctx) {
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
            couple(world, w, gravity, ctx.dt);
        }
        ProfileStage stage(ctx.profiler, "water.waves");
        for (std::uint32_t s = 0; s < substeps; ++s) {
            waveStep(w, ctx.dt / substeps, poolOr(ctx.pool));
        }
    });
}

void registerWaterSystem(Catalog& catalog) {
    catalog.addComponent({"water", loadWater});
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
             for (int k = 0; k < w.nz; ++k) {
                 for (int i = 0; i < w.nx; ++i) {
                     const double d = std::hypot(w.nodeX(i) - ev.position[0], w.nodeZ(k) - ev.position[2]);
                     if (d < ev.radius) {
                         w.h[std::size_t(k) * w.nx + i] +=
                             ev.amount * 0.5 * (1.0 + std::cos(std::numbers::pi * d / ev.radius));
                     }
                 }
             }
         }});
}

} // namespace tumble
