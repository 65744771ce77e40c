#include "systems/air_system.h"

#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/retune.h"
#include "engine/run_report.h"
#include "engine/scene.h"
#include "engine/transform.h"
#include "systems/air_solver.h"
#include "systems/collision_system.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace tumble {

namespace {

constexpr double kMaxCellsPerSide = 1024.0;
/// What a grid holds, at most, charged to the memory cap before its bodies and sources are known: per cell,
/// the fields and the advection's copies (10 floats, a face array up to 1.25 floats a cell on a side of 4),
/// the vorticity's scratch (7 floats), the solid flags (2 bytes), the voxeliser's (5) and the driving
/// sources' regions (12): 94 bytes; per cell of the grid padded by one cell a side, the projection's
/// vectors (5 floats, the pressure before last among them) and its finest level's (6), and its coarser
/// levels' (6 floats on at most 0.35 as many padded cells): 53 bytes. At 64^3, 152 bytes a cell charged
/// against 122 measured without bodies (BM_Air64Step) and about 136 with bodies and driving sources; on
/// thin boxes the padding is most of it (1024 x 1024 x 4: 174 charged, about 143 held).
constexpr std::uint64_t kBytesPerCell = 94;
constexpr std::uint64_t kBytesPerPaddedCell = 53;
/// MacCormack's step back: two face arrays' floats a cell more.
constexpr std::uint64_t kMacCormackBytesPerCell = 10;

constexpr std::array<std::string_view, 6> kSides{"-x", "+x", "-y", "+y", "-z", "+z"};

void readBorder(TableReader& r, Air& air) {
    const toml::node* node = r.node("border");
    if (!node) {
        return;
    }
    if (node->is_string()) {
        const AirBorder b =
            r.choice("border", "closed", {"closed", "open"}) == "open" ? AirBorder::Open : AirBorder::Closed;
        air.border.fill(b);
        return;
    }
    const toml::table* sides = node->is_table() ? r.subtable("border") : nullptr;
    if (!sides) {
        r.fail("border", "'border' is \"closed\", \"open\", or a table of sides, e.g. border = { \"+y\" = "
                         "\"open\" } (sides -x +x -y +y -z +z; the others closed)");
    }
    TableReader s(*sides, r.where() + " border", r.context());
    for (std::size_t side = 0; side < 6; ++side) {
        air.border[side] = s.choice(kSides[side], "closed", {"closed", "open"}) == "open" ? AirBorder::Open
                                                                                          : AirBorder::Closed;
    }
    s.finish();
}

void loadAir(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    Air air;
    const auto cells = r.vector<3>("cells", {32.0, 32.0, 32.0}, 4.0, kMaxCellsPerSide);
    for (std::size_t a = 0; a < 3; ++a) {
        if (cells[a] != std::floor(cells[a])) {
            r.fail("cells", "'cells' are whole numbers of cells along x, y and z, each 4 to 1024");
        }
        air.cells[a] = int(cells[a]);
    }
    const auto size = r.vector<3>("size", {4.0, 4.0, 4.0}, 1e-3, 1e5);
    air.cell = size[0] / cells[0];
    for (std::size_t a = 1; a < 3; ++a) {
        if (std::abs(size[a] / cells[a] - air.cell) > 1e-6 * air.cell) {
            char text[300];
            std::snprintf(
                text, sizeof text,
                "the cells must be cubes: size / cells gives %g, %g and %g m along x, y and z; make "
                "them equal (e.g. size = [%g, %g, %g])",
                size[0] / cells[0], size[1] / cells[1], size[2] / cells[2], air.cell * cells[0],
                air.cell * cells[1], air.cell * cells[2]);
            r.failAgainst("size", {"cells"}, text);
        }
    }
    readBorder(r, air);
    air.vorticity = r.number("vorticity", 0.0, 0.0, 100.0);
    const auto buoyancy = r.vector<2>("buoyancy", {0.0, 0.0}, 0.0, 1e4);
    air.smokeWeight = buoyancy[0];
    air.heatLift = buoyancy[1];
    air.dissipation = r.number("dissipation", 0.0, 0.0, 1e4);
    air.viscosity = r.number("viscosity", 0.0, 0.0, 1e3);
    if (airViscositySubsteps(air, scene.dt) > kMostViscositySubsteps) {
        // explicit diffusion takes nu dt / dx^2 * 6 substeps a step: more would run for minutes a step
        char text[300];
        std::snprintf(
            text, sizeof text,
            "viscosity %g m^2/s with cells of %g m and a step of %g s needs more than %d substeps a "
            "step (nu dt / dx^2 <= 1/6 each); at most %g m^2/s here, or a shorter step or larger cells",
            air.viscosity, air.cell, scene.dt, kMostViscositySubsteps,
            kMostViscositySubsteps * air.cell * air.cell / (6.0 * scene.dt));
        r.fail("viscosity", text);
    }
    air.maccormack =
        r.choice("advection", "semi_lagrangian", {"semi_lagrangian", "maccormack"}) == "maccormack";
    air.tolerance = r.number("tolerance", 1e-3, 1e-9, 1e3);
    air.coefficient = r.number("coefficient", 1.0, 0.0, 1e6);
    air.dumpFields = r.boolean("dump_fields", false);
    const auto colour = r.vector<3>("smoke_color", {0.92, 0.92, 0.94}, 0.0, 1.0);
    air.smokeColour = {float(colour[0]), float(colour[1]), float(colour[2])};
    air.smokeOpacity = r.number("smoke_opacity", 20.0, 0.0, 1e6);
    const std::string slice = r.choice("velocity_slice", "none", {"none", "x", "y", "z"});
    air.velocitySlice = slice == "none" ? -1 : slice[0] - 'x';
    const std::uint64_t n = std::uint64_t(air.cellCount());
    const std::uint64_t padded =
        std::uint64_t(air.cells[0] + 2) * std::uint64_t(air.cells[1] + 2) * std::uint64_t(air.cells[2] + 2);
    r.charge("cells",
             n * (kBytesPerCell + (air.maccormack ? kMacCormackBytesPerCell : 0)) +
                 padded * kBytesPerPaddedCell,
             r.where() + " (" + std::to_string(n) + " cells)");
    air.centre = world.get<Transform>(entity).position;
    initAir(air);
    world.emplace<Air>(entity, std::move(air));
}

void loadAirSource(TableReader& r, World& world, Entity entity, const SceneDef&) {
    AirSource s;
    r.requiredString("air"); // resolved by linkAirSource, once every entity exists
    s.sphere = r.choice("shape", "sphere", {"sphere", "box"}) == "sphere";
    if (s.sphere) {
        if (r.has("half_extents")) {
            r.fail("half_extents",
                   "'half_extents' is a box's; a sphere takes 'radius' (or set shape = \"box\")");
        }
        s.radius = r.number("radius", 0.25, 1e-6, 1e5);
    } else {
        if (r.has("radius")) {
            r.fail("radius", "'radius' is a sphere's; a box takes 'half_extents' = [x, y, z]");
        }
        const auto h = r.vector<3>("half_extents", {0.25, 0.25, 0.25}, 1e-6, 1e5);
        s.halfExtents = {h[0], h[1], h[2]};
    }
    s.smoke = r.number("smoke", 1.0, 0.0, 1e6);
    s.heat = r.number("heat", 0.0, -1e6, 1e6);
    if (r.has("velocity")) {
        s.drives = true;
        const auto v = r.vector<3>("velocity", {0.0, 0.0, 0.0}, -1e4, 1e4);
        s.velocity = {v[0], v[1], v[2]};
    }
    world.emplace<AirSource>(entity, s);
}

void linkAirSource(TableReader& r, World& world, Entity entity, const EntityLookup& lookup) {
    const Entity air = lookup(r, "air", true);
    const std::string& name = world.get<Name>(air).value;
    if (!world.has<Air>(air)) {
        r.fail("air", "entity '" + name + "' has no [entity.air] for this source to feed");
    }
    const Air& a = world.get<Air>(air);
    const Vec3 at = world.get<Transform>(entity).position;
    const Vec3 lo = a.origin(),
               hi = a.origin() + Vec3{a.cells[0] * a.cell, a.cells[1] * a.cell, a.cells[2] * a.cell};
    if (!(at.x >= lo.x && at.x <= hi.x && at.y >= lo.y && at.y <= hi.y && at.z >= lo.z && at.z <= hi.z)) {
        char text[320];
        std::snprintf(
            text, sizeof text,
            "the source at (%g, %g, %g) is outside air '%s', whose box runs from (%g, %g, %g) to (%g, "
            "%g, %g); move it (its [transform] position) inside",
            at.x, at.y, at.z, name.c_str(), lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
        r.fail("air", text);
    }
    world.get<AirSource>(entity).air = air;
}

bool inside(const AirSource& s, const Vec3& p) {
    if (s.sphere) {
        return dot(p, p) <= s.radius * s.radius;
    }
    return std::abs(p.x) <= s.halfExtents.x && std::abs(p.y) <= s.halfExtents.y &&
           std::abs(p.z) <= s.halfExtents.z;
}

void dumpAir(const Air& a, JsonWriter& out) {
    out.key("cells").beginArray().value(a.cells[0]).value(a.cells[1]).value(a.cells[2]).endArray();
    out.key("smoke_total").value(airSmokeTotal(a));
    const Vec3 c = airSmokeCentroid(a);
    const double centroid[3] = {c.x, c.y, c.z};
    out.key("smoke_centroid").numbers(centroid);
    out.key("divergence_max").value(a.divergenceMax);
    out.key("kinetic_energy").value(airKineticEnergy(a));
    if (a.dumpFields) {
        const std::pair<const char*, const std::vector<float>*> fields[] = {
            {"u", &a.u}, {"v", &a.v}, {"w", &a.w}, {"smoke", &a.smoke}, {"heat", &a.heat}};
        for (const auto& [name, field] : fields) {
            const std::vector<double> values(field->begin(), field->end());
            out.key(name).numbers(values.data(), values.size());
        }
    }
}

void hashAir(const Air& a, Hasher& h) {
    h.add(a.u);
    h.add(a.v);
    h.add(a.w);
    h.add(a.smoke);
    h.add(a.heat);
    h.add(a.pressure);
    h.add(a.earlierPressure);
    h.add(a.projections); // whether the next guess carries the two pressures on
}

/// The cells a source at `at` may reach, a cell more each way: [lo, hi) along each axis, within the box.
void sourceSpan(const Air& air, const AirSource& source, const Vec3& at, int (&lo)[3], int (&hi)[3]) {
    const Vec3 reach = source.sphere ? Vec3{source.radius, source.radius, source.radius} : source.halfExtents;
    const Vec3 origin = air.origin();
    const double from[3] = {at.x - reach.x - origin.x, at.y - reach.y - origin.y, at.z - reach.z - origin.z};
    const double to[3] = {at.x + reach.x - origin.x, at.y + reach.y - origin.y, at.z + reach.z - origin.z};
    for (std::size_t a = 0; a < 3; ++a) {
        // clamped as doubles first: a reach of many cells must not overflow an int
        lo[a] = int(std::clamp(std::floor(from[a] / air.cell) - 1.0, 0.0, double(air.cells[a])));
        hi[a] = int(std::clamp(std::ceil(to[a] / air.cell) + 1.0, 0.0, double(air.cells[a])));
    }
}

/// Calls fn(i, j, k) for each cell of a source at `at`: those whose centres are inside its shape, else (a
/// shape smaller than a cell) the cell holding `at` when it is in the box, unless `orHolding` is false.
template <class F>
void forSourceCells(const Air& air, const AirSource& source, const Vec3& at, F&& fn, bool orHolding = true) {
    const Vec3 origin = air.origin();
    int lo[3], hi[3];
    sourceSpan(air, source, at, lo, hi);
    bool any = false;
    for (int k = lo[2]; k < hi[2]; ++k) {
        for (int j = lo[1]; j < hi[1]; ++j) {
            for (int i = lo[0]; i < hi[0]; ++i) {
                if (inside(source, origin + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell - at)) {
                    fn(i, j, k);
                    any = true;
                }
            }
        }
    }
    if (!any && orHolding && airContains(air, at)) {
        int c[3];
        const double local[3] = {at.x - origin.x, at.y - origin.y, at.z - origin.z};
        for (std::size_t a = 0; a < 3; ++a) {
            c[a] = int(std::clamp(std::floor(local[a] / air.cell), 0.0, double(air.cells[a] - 1)));
        }
        fn(c[0], c[1], c[2]);
    }
}

/// The index of the face along `axis` numbered (f[0], f[1], f[2]) (f[axis] from 0 to cells[axis]).
std::size_t faceIndex(const Air& air, int axis, const std::array<int, 3>& f) {
    std::array<int, 3> n = air.cells;
    n[std::size_t(axis)] += 1;
    return std::size_t(f[0]) +
           std::size_t(n[0]) * (std::size_t(f[1]) + std::size_t(n[1]) * std::size_t(f[2]));
}

} // namespace

void feedAir(Air& air, const AirSource& source, const Vec3& at, double dt) {
    const auto smoke = float(source.smoke * dt), heat = float(source.heat * dt);
    forSourceCells(air, source, at, [&](int i, int j, int k) {
        air.smoke[air.at(i, j, k)] += smoke;
        air.heat[air.at(i, j, k)] += heat;
    });
    if (!source.drives) {
        return;
    }
    // the faces inside: each component on its own faces (the box's sides' faces too); a shape with no face
    // inside (smaller than a cell) drives the faces of its cells
    const Vec3 origin = air.origin();
    int lo[3], hi[3];
    sourceSpan(air, source, at, lo, hi);
    std::vector<float>* faces[3] = {&air.u, &air.v, &air.w};
    const double speed[3] = {source.velocity.x, source.velocity.y, source.velocity.z};
    int driven = 0;
    for (int a = 0; a < 3; ++a) {
        std::array<int, 3> n = air.cells;
        n[std::size_t(a)] += 1;
        for (int k = lo[2]; k < std::min(hi[2] + (a == 2), n[2]); ++k) {
            for (int j = lo[1]; j < std::min(hi[1] + (a == 1), n[1]); ++j) {
                for (int i = lo[0]; i < std::min(hi[0] + (a == 0), n[0]); ++i) {
                    const Vec3 p = origin + Vec3{i + (a == 0 ? 0.0 : 0.5), j + (a == 1 ? 0.0 : 0.5),
                                                 k + (a == 2 ? 0.0 : 0.5)} *
                                                air.cell;
                    if (inside(source, p - at)) {
                        (*faces[a])[faceIndex(air, a, {i, j, k})] = float(speed[a]);
                        ++driven;
                    }
                }
            }
        }
    }
    if (driven == 0) {
        forSourceCells(air, source, at, [&](int i, int j, int k) {
            for (int a = 0; a < 3; ++a) {
                for (int side = 0; side < 2; ++side) {
                    std::array<int, 3> f{i, j, k};
                    f[std::size_t(a)] += side;
                    (*faces[a])[faceIndex(air, a, f)] = float(speed[a]);
                }
            }
        });
    }
}

namespace {

/// A cell's owner in the voxeliser: -1 air, b >= 0 inside body b, kFirstSource - s in driving source s.
constexpr std::int32_t kFirstSource = -2;

const Vec3& sourceVelocity(const std::vector<HeldSource>& sources, std::int32_t owner) {
    return sources[std::size_t(kFirstSource - owner)].source->velocity;
}

/// Marks the cells of each driving source (forSourceCells).
void markSources(const Air& air, const std::vector<HeldSource>& sources, std::vector<std::int32_t>& owner) {
    for (std::size_t s = 0; s < sources.size(); ++s) {
        const auto mark = kFirstSource - std::int32_t(s);
        // a shape with no cell's centre inside (thinner than a cell) is not held: the one cell holding its
        // centre would stand in the middle of its jet, still across it
        forSourceCells(
            air, *sources[s].source, sources[s].at,
            [&](int i, int j, int k) { owner[air.at(i, j, k)] = mark; }, false);
    }
}

/// Calls fn(s, neighbour cell, flow into it) for each face between a cell of driving source s and an air
/// cell (owner -1) of the box: the flow is the source's velocity along the face's normal, out of the source.
/// Only each source's span of cells is read (a held source has no cell outside it).
template <class F>
void forHeldFacesIntoAir(const Air& air, const std::vector<HeldSource>& sources,
                         const std::vector<std::int32_t>& owner, F&& fn) {
    for (std::size_t h = 0; h < sources.size(); ++h) {
        const auto mark = kFirstSource - std::int32_t(h);
        const Vec3& v = sources[h].source->velocity;
        const double speed[3] = {v.x, v.y, v.z};
        int lo[3], hi[3];
        sourceSpan(air, *sources[h].source, sources[h].at, lo, hi);
        for (int k = lo[2]; k < hi[2]; ++k) {
            for (int j = lo[1]; j < hi[1]; ++j) {
                for (int i = lo[0]; i < hi[0]; ++i) {
                    if (owner[air.at(i, j, k)] != mark) {
                        continue;
                    }
                    for (int a = 0; a < 3; ++a) {
                        for (int side = 0; side < 2; ++side) {
                            std::array<int, 3> m{i, j, k};
                            m[std::size_t(a)] += side == 0 ? -1 : 1;
                            if (m[std::size_t(a)] >= 0 && m[std::size_t(a)] < air.cells[std::size_t(a)] &&
                                owner[air.at(m[0], m[1], m[2])] == -1) {
                                fn(h, air.at(m[0], m[1], m[2]), side == 0 ? -speed[a] : speed[a]);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Labels the air's connected regions (owner -1, joined through faces) in `region`; returns for each
/// whether it reaches an open side. One visit a cell, its coordinates carried on the stack (no division).
std::vector<std::uint8_t> airRegions(const Air& air, const std::vector<std::int32_t>& owner,
                                     std::vector<std::int32_t>& region,
                                     std::vector<std::array<std::int32_t, 4>>& stack) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    const std::size_t sy = std::size_t(nx), sz = sy * std::size_t(ny);
    region.assign(owner.size(), -1);
    std::vector<std::uint8_t> open;
    bool sideOpen[6];
    for (std::size_t side = 0; side < 6; ++side) {
        sideOpen[side] = air.border[side] == AirBorder::Open;
    }
    for (std::size_t c0 = 0; c0 < owner.size(); ++c0) {
        if (owner[c0] != -1 || region[c0] >= 0) {
            continue;
        }
        const auto label = std::int32_t(open.size());
        bool reaches = false;
        region[c0] = label;
        stack.push_back({std::int32_t(c0), int(c0 % sy), int(c0 / sy % std::size_t(ny)), int(c0 / sz)});
        while (!stack.empty()) {
            // named copies, not a structured binding: clang 14 cannot capture bindings in the lambda
            const std::array<std::int32_t, 4> top = stack.back();
            stack.pop_back();
            const std::int32_t c = top[0], i = top[1], j = top[2], k = top[3];
            // a neighbour inside the box joins the region; past a side, the side may be open
            const auto visit = [&](bool inside, std::int32_t m, int di, int dj, int dk, std::size_t side) {
                if (!inside) {
                    reaches = reaches || sideOpen[side];
                } else if (owner[std::size_t(m)] == -1 && region[std::size_t(m)] < 0) {
                    region[std::size_t(m)] = label;
                    stack.push_back({m, i + di, j + dj, k + dk});
                }
            };
            visit(i > 0, c - 1, -1, 0, 0, 0);
            visit(i < nx - 1, c + 1, 1, 0, 0, 1);
            visit(j > 0, c - std::int32_t(sy), 0, -1, 0, 2);
            visit(j < ny - 1, c + std::int32_t(sy), 0, 1, 0, 3);
            visit(k > 0, c - std::int32_t(sz), 0, 0, -1, 4);
            visit(k < nz - 1, c + std::int32_t(sz), 0, 0, 1, 5);
        }
        open.push_back(reaches ? 1 : 0);
    }
    return open;
}

/// A pocket of air that reaches no open side (a closed room; the closed end of a duct a fan fills) can
/// take no net flow from the held sources around it: its own pressure problem would have no solution (the
/// projection left the difference as divergence, and its CG ran to its cap). The sources that feed a
/// pocket unevenly are let go (their cells air again, their faces driven as any source's, the projection
/// free to change them), until every pocket they feed is even. Done again only when the marked cells or
/// the sources' velocities change (its flood fill reads every cell).
void releaseUnbalanced(Air& air, const std::vector<HeldSource>& sources, std::vector<std::int32_t>& owner) {
    AirScratch& s = air.scratch;
    std::vector<double> velocities;
    for (const HeldSource& h : sources) {
        velocities.insert(velocities.end(),
                          {h.source->velocity.x, h.source->velocity.y, h.source->velocity.z});
    }
    if (owner == s.marked && velocities == s.markedVelocities) {
        for (const std::int32_t mark : s.released) {
            std::replace(owner.begin(), owner.end(), mark, std::int32_t(-1));
        }
        return;
    }
    s.marked = owner;
    s.markedVelocities = velocities;
    s.released.clear();
    for (bool again = true; again;) {
        const std::vector<std::uint8_t> open = airRegions(air, owner, s.region, s.regionStack);
        std::vector<double> net(open.size(), 0.0), gross(open.size(), 0.0);
        forHeldFacesIntoAir(air, sources, owner, [&](std::size_t, std::size_t cell, double flow) {
            net[std::size_t(s.region[cell])] += flow;
            gross[std::size_t(s.region[cell])] += std::abs(flow);
        });
        std::vector<std::uint8_t> release(sources.size(), 0);
        forHeldFacesIntoAir(air, sources, owner, [&](std::size_t source, std::size_t cell, double) {
            const auto r = std::size_t(s.region[cell]);
            release[source] |= !open[r] && std::abs(net[r]) > 1e-6 * gross[r];
        });
        again = false;
        for (std::size_t h = 0; h < sources.size(); ++h) {
            if (release[h]) {
                const auto mark = kFirstSource - std::int32_t(h);
                std::replace(owner.begin(), owner.end(), mark, std::int32_t(-1));
                s.released.push_back(mark);
                again = true;
            }
        }
    }
}

/// Holds each face of a solid cell that touches the air at its owner's velocity there: the faces across
/// the surface make the air flow round a body (out of and into a source), those along it drag the air
/// beside it (no slip). A closed side's faces stay walls.
void holdSolidFaces(Air& air, const std::vector<const RigidBody*>& bodies,
                    const std::vector<HeldSource>& sources, const std::vector<std::int32_t>& owner) {
    const Vec3 origin = air.origin();
    auto solidAt = [&](int i, int j, int k) {
        return i < 0 || j < 0 || k < 0 || i >= air.cells[0] || j >= air.cells[1] || k >= air.cells[2] ||
               owner[air.at(i, j, k)] != -1;
    };
    for (int k = 0; k < air.cells[2]; ++k) {
        for (int j = 0; j < air.cells[1]; ++j) {
            for (int i = 0; i < air.cells[0]; ++i) {
                const std::int32_t b = owner[air.at(i, j, k)];
                if (b == -1 || (solidAt(i - 1, j, k) && solidAt(i + 1, j, k) && solidAt(i, j - 1, k) &&
                                solidAt(i, j + 1, k) && solidAt(i, j, k - 1) && solidAt(i, j, k + 1))) {
                    continue; // air, or deep inside
                }
                for (std::uint32_t a = 0; a < 3; ++a) {
                    for (int side = 0; side < 2; ++side) {
                        std::array<int, 3> f{i, j, k};
                        f[a] += side; // the face's index along its axis
                        if ((f[a] == 0 || f[a] == air.cells[a]) &&
                            air.border[2 * a + std::size_t(side)] == AirBorder::Closed) {
                            continue;
                        }
                        Vec3 at = origin + Vec3{f[0] + 0.5, f[1] + 0.5, f[2] + 0.5} * air.cell;
                        (a == 0 ? at.x : a == 1 ? at.y : at.z) -= 0.5 * air.cell;
                        const Vec3 v =
                            b >= 0 ? bodies[std::size_t(b)]->velocityAt(at) : sourceVelocity(sources, b);
                        air.fixedFaces.push_back({a, std::uint32_t(faceIndex(air, int(a), f)),
                                                  float(a == 0   ? v.x
                                                        : a == 1 ? v.y
                                                                 : v.z)});
                    }
                }
            }
        }
    }
}

} // namespace

void voxeliseSolids(Air& air, const std::vector<const RigidBody*>& bodies,
                    const std::vector<HeldSource>& sources) {
    const std::size_t n = air.cellCount();
    if (bodies.empty() && sources.empty()) {
        air.fixedFaces.clear();
        if (!air.solid.empty()) {
            air.solid.clear();
            air.solidChanged = true;
        }
        return;
    }
    // per cell: the body it is inside (the last listed), else the driving source, else air
    std::vector<std::int32_t>& owner = air.scratch.owner;
    owner.assign(n, -1);
    markSources(air, sources, owner);
    const Vec3 origin = air.origin();
    const Vec3 end = origin + Vec3{air.cells[0] * air.cell, air.cells[1] * air.cell, air.cells[2] * air.cell};
    for (std::size_t b = 0; b < bodies.size(); ++b) {
        const RigidBody& body = *bodies[b];
        if (body.shape == ShapeKind::Mesh) {
            continue; // an open surface has no inside to fill (README, "Air")
        }
        Aabb box;
        if (!worldBox(body, box)) {
            box.lo = origin; // a plane: the whole grid
            box.hi = end;
        }
        int lo[3], hi[3];
        const double from[3] = {box.lo.x - origin.x, box.lo.y - origin.y, box.lo.z - origin.z};
        const double to[3] = {box.hi.x - origin.x, box.hi.y - origin.y, box.hi.z - origin.z};
        for (std::size_t a = 0; a < 3; ++a) {
            lo[a] = int(std::clamp(std::floor(from[a] / air.cell - 0.5), 0.0, double(air.cells[a])));
            hi[a] = int(std::clamp(std::ceil(to[a] / air.cell + 0.5), 0.0, double(air.cells[a])));
        }
        for (int k = lo[2]; k < hi[2]; ++k) {
            for (int j = lo[1]; j < hi[1]; ++j) {
                for (int i = lo[0]; i < hi[0]; ++i) {
                    Vec3 normal;
                    if (signedDistance(body, origin + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell, normal) <
                        0.0) {
                        owner[air.at(i, j, k)] = std::int32_t(b);
                    }
                }
            }
        }
    }
    if (!sources.empty()) {
        releaseUnbalanced(air, sources, owner);
    }
    std::vector<std::uint8_t>& solid = air.scratch.solid; // compared with the last step's, then swapped in
    solid.clear();
    air.fixedFaces.clear();
    if (std::any_of(owner.begin(), owner.end(), [](std::int32_t o) { return o != -1; })) {
        solid.resize(n);
        for (std::size_t c = 0; c < n; ++c) {
            solid[c] = owner[c] >= 0 ? kBodyCell : owner[c] == -1 ? 0 : kSourceCell;
        }
        holdSolidFaces(air, bodies, sources, owner);
    }
    if (solid != air.solid) {
        air.solid.swap(solid);
        air.solidChanged = true;
    }
}

/// A grid that blew up (air_solver.h, kMostAirSpeed) is frozen, still, and says so once: its velocity
/// zero (what moves through it feels no air), non-finite smoke and heat cleared; the rest of the scene runs
/// on and the run ends as a failure. (Stepped on, its next advection sent NaN positions into the gathers,
/// which read past the arrays: the run crashed.)
void freezeAir(World& world, const StepContext& ctx, Entity grid, Air& air) {
    air.frozen = true;
    for (std::vector<float>* f : {&air.u, &air.v, &air.w}) {
        std::fill(f->begin(), f->end(), 0.0f);
    }
    for (std::vector<float>* f : {&air.smoke, &air.heat}) {
        for (float& x : *f) {
            x = std::isfinite(x) ? x : 0.0f;
        }
    }
    const Name* name = world.tryGet<Name>(grid);
    world.resource<RunReport>().failures.push_back(
        "air '" + (name ? name->value : std::string("?")) + "' blew up at frame " +
        std::to_string(ctx.frame) + " (t = " + std::to_string(ctx.time) + " s): a cell's flow passed " +
        std::to_string(int(kMostAirSpeed)) +
        " m/s or was not finite; it is frozen, still, from here on. Remedy: weaker sources, buoyancy or "
        "vorticity, or a smaller step");
}

void advanceAir(World& world, const StepContext& ctx) {
    const auto& g = world.resource<SceneDef>().gravity;
    const Vec3 gravity{g[0], g[1], g[2]};
    std::vector<const RigidBody*> bodies;
    world.view<const RigidBody>().each([&](Entity, const RigidBody& b) { bodies.push_back(&b); });
    std::vector<HeldSource> held;
    world.view<Air>().each([&](Entity grid, Air& air) {
        if (air.frozen) {
            return;
        }
        {
            ProfileStage stage(ctx.profiler, "air.bodies");
            held.clear();
            world.view<const Transform, const AirSource>().each(
                [&](Entity, const Transform& t, const AirSource& s) {
                    if (s.air == grid && s.drives) {
                        held.push_back({&s, t.position});
                    }
                });
            voxeliseSolids(air, bodies, held);
        }
        // timed as three stages, each once a step: the advection, the sources (after it: air_solver.h, in
        // the order they were loaded), then forces, viscosity and the projection
        std::optional<ProfileStage> stage(std::in_place, ctx.profiler, "air.advect");
        if (!advectAir(air, ctx.dt, poolOr(ctx.pool))) {
            freezeAir(world, ctx, grid, air);
            return;
        }
        stage.emplace(ctx.profiler, "air.sources");
        world.view<const Transform, const AirSource>().each(
            [&](Entity, const Transform& t, const AirSource& s) {
                if (s.air == grid) {
                    feedAir(air, s, t.position, ctx.dt);
                }
            });
        stage.emplace(ctx.profiler, "air.project");
        finishAirStep(air, gravity, ctx.dt, poolOr(ctx.pool));
    });
}

namespace {

/// A `set` event on an air grid's keys (engine/retune.h): its physics and its drawing, not its grid.
Retune airRetune() {
    return Retune{
        {"air"},
        [](const World& w, Entity e) { return w.has<Air>(e); },
        [](const World& bw, Entity b, const World& aw, Entity a) -> std::optional<std::string> {
            const Air &was = bw.get<Air>(b), &now = aw.get<Air>(a);
            if (was.cells != now.cells || was.cell != now.cell || was.border != now.border ||
                !(was.centre == now.centre)) {
                return std::string("an air grid's cells, size, border and place cannot change during a run; "
                                   "its vorticity, buoyancy, dissipation, viscosity, advection, tolerance, "
                                   "coefficient and drawing keys can");
            }
            return std::nullopt;
        },
        [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
            Air& air = w.get<Air>(e);
            const Air &was = bw.get<Air>(b), &now = aw.get<Air>(a);
            takeChanged(air.vorticity, was.vorticity, now.vorticity);
            takeChanged(air.smokeWeight, was.smokeWeight, now.smokeWeight);
            takeChanged(air.heatLift, was.heatLift, now.heatLift);
            takeChanged(air.dissipation, was.dissipation, now.dissipation);
            takeChanged(air.viscosity, was.viscosity, now.viscosity);
            takeChanged(air.tolerance, was.tolerance, now.tolerance);
            takeChanged(air.coefficient, was.coefficient, now.coefficient);
            takeChanged(air.dumpFields, was.dumpFields, now.dumpFields);
            takeChanged(air.smokeColour, was.smokeColour, now.smokeColour);
            takeChanged(air.smokeOpacity, was.smokeOpacity, now.smokeOpacity);
            takeChanged(air.velocitySlice, was.velocitySlice, now.velocitySlice);
            if (was.maccormack != now.maccormack) {
                air.maccormack = now.maccormack; // its step back's vectors made, or freed
                const std::size_t faces = std::max({air.u.size(), air.v.size(), air.w.size()});
                std::vector<float>(air.maccormack ? faces : 0, 0.0f).swap(air.scratch.back);
                std::vector<float>(air.maccormack ? air.heat.size() : 0, 0.0f).swap(air.scratch.back2);
            }
        }};
}

/// A `set` event on a source's keys: everything but the air it feeds (its place is its transform's).
Retune airSourceRetune() {
    return Retune{{"air_source"},
                  [](const World& w, Entity e) { return w.has<AirSource>(e); },
                  [](const World& bw, Entity b, const World& aw, Entity a) -> std::optional<std::string> {
                      const Entity was = bw.get<AirSource>(b).air, now = aw.get<AirSource>(a).air;
                      if (bw.get<Name>(was).value != aw.get<Name>(now).value) {
                          return std::string(
                              "the air a source feeds cannot change during a run; its shape, smoke, heat "
                              "and velocity can");
                      }
                      return std::nullopt;
                  },
                  [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
                      AirSource& s = w.get<AirSource>(e);
                      const AirSource &was = bw.get<AirSource>(b), &now = aw.get<AirSource>(a);
                      takeChanged(s.sphere, was.sphere, now.sphere);
                      takeChanged(s.radius, was.radius, now.radius);
                      takeChanged(s.halfExtents, was.halfExtents, now.halfExtents);
                      takeChanged(s.smoke, was.smoke, now.smoke);
                      takeChanged(s.heat, was.heat, now.heat);
                      takeChanged(s.drives, was.drives, now.drives);
                      takeChanged(s.velocity, was.velocity, now.velocity);
                  }};
}

} // namespace

void registerAirSystem(Catalog& catalog) {
    catalog.addComponent({"air", loadAir, {}, true});
    catalog.addComponent({"air_source", loadAirSource, linkAirSource});
    catalog.addState<Air>("air", dumpAir, hashAir);
    catalog.addRetune(airRetune());
    catalog.addRetune(airSourceRetune());
}

} // namespace tumble
