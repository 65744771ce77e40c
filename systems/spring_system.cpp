#include "systems/spring_system.h"

#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "engine/json.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/random.h"
#include "engine/retune.h"
#include "engine/run_report.h"
#include "engine/scene.h"
#include "engine/transform.h"
#include "systems/cloth_collision.h"
#include "systems/fem.h"
#include "systems/obj_mesh.h"
#include "systems/spring_builders.h"
#include "systems/spring_integrators.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace tumble {

namespace {

constexpr double kHugeCoordinate = 1e9; // m
constexpr std::size_t kMaxMasses = 1u << 20;
constexpr std::int64_t kMaxClothVertices = 512 * 512;
constexpr double kMaxSpeed = 1e4; // m/s: beyond it a network has blown up

/// Keys every network takes: integrator, drag, contact and solver settings.
void readCommon(TableReader& r, SpringNetwork& net, const char* defaultIntegrator,
                std::span<const std::string_view> integrators = kIntegratorNames) {
    const std::string name = r.choice("integrator", defaultIntegrator, integrators);
    for (std::size_t i = 0; i < std::size(kIntegratorNames); ++i) {
        if (kIntegratorNames[i] == name) {
            net.integrator = static_cast<Integrator>(i);
        }
    }
    net.drag = r.number("drag", 0.0, 0.0, 1e9);
    net.thickness = r.number("thickness", 0.01, 0.0, 10.0);
    net.friction = r.number("friction", 0.5, 0.0, 100.0);
    net.cgTolerance = r.number("cg_tolerance", 1e-3, 1e-14, 0.5);
    net.cgMaxIterations = static_cast<int>(r.integer("cg_max_iterations", 200, 1, 100000));
    net.doublePrecisionSolve = r.choice("solver_precision", "float", {"float", "double"}) == "double";
    net.blowUpFails = r.choice("on_blow_up", "fail", {"fail", "freeze"}) == "fail";
}

/// `pin`: a preset name or a list of mass indices.
std::vector<std::uint32_t>
readPins(TableReader& r, std::size_t masses, const std::string& fallback,
         const std::function<bool(const std::string&, std::vector<std::uint32_t>&)>& preset,
         const std::string& presetNames) {
    std::vector<std::uint32_t> pins;
    const toml::node* n = r.node("pin");
    if (n && n->is_array()) {
        // any length: a list longer than the masses holds an index out of range or one twice, and says which
        // (at most masses + 1 items are read)
        const toml::array* list = r.array("pin", std::numeric_limits<std::size_t>::max());
        std::vector<std::uint8_t> listed(masses, 0);
        for (const toml::node& item : *list) {
            // a float is refused before it is read as an integer (1e308 does not fit one)
            const auto i = item.is_integer() ? item.value<std::int64_t>() : std::nullopt;
            if (!i || *i < 0 || static_cast<std::size_t>(*i) >= masses) {
                r.failAt(item, "'pin' in " + r.where() + " lists mass indices, each a whole number in [0, " +
                                   std::to_string(masses - 1) + "]");
            }
            if (listed[std::size_t(*i)]) {
                r.failAt(item, "'pin' in " + r.where() + " lists mass " + std::to_string(*i) +
                                   " twice (a typo for another index?)");
            }
            listed[std::size_t(*i)] = 1;
            pins.push_back(static_cast<std::uint32_t>(*i));
        }
        return pins;
    }
    const std::string name = r.string("pin", fallback);
    if (!preset(name, pins)) {
        r.fail("pin", "'pin' in " + r.where() + " is '" + name + "'; expected " + presetNames +
                          " or a list of mass indices");
    }
    return pins;
}

Vec3 readVec3(TableReader& r, const toml::node& n, std::string_view key) {
    double v[3];
    r.readNumbers(n, key, v, 3, -kHugeCoordinate, kHugeCoordinate);
    return {v[0], v[1], v[2]};
}

/// Charges the network's memory to the scene (what a step of its integrator will allocate too), then gives
/// it to the entity. Bytes per mass and per link were measured: peak RSS of 400x400 cloths and a 50^3 soft
/// body over two steps (implicit: the matrix blocks, the multigrid levels and the CG vectors; since then 96
/// bytes a mass more, the six vectors of CG's first guess, and 56 bytes a link fewer).
void attach(TableReader& r, World& world, Entity entity, SpringNetwork net) {
    const bool implicit = net.integrator == Integrator::ImplicitEuler;
    const std::uint64_t bytes = net.x.size() * (implicit ? 700u : 200u) +
                                net.links.size() * (implicit ? 350u : 80u) +
                                (net.selfCollision ? net.triangles.size() * 1000u : 0u);
    r.charge("", bytes,
             r.where() + " (" + std::to_string(net.x.size()) + " masses, " +
                 std::to_string(net.links.size()) + " springs" + (implicit ? ", implicit" : "") + ")");
    net.implicitCharged = implicit;
    if (net.selfCollision) {
        // the rest state of the contact pair rule, and the start of the first step
        world.emplace<ClothCollision>(entity, makeClothCollision(net.x));
    }
    world.emplace<SpringNetwork>(entity, std::move(net));
    world.emplace<SpringWorkspace>(entity);
}

/// [entity.springs]: masses and links given explicitly (README, "Spring networks").
void loadSprings(TableReader& r, World& world, Entity entity, const SceneDef&) {
    SpringNetwork net;
    readCommon(r, net, "symplectic_euler");
    const double stiffness = r.number("stiffness", 100.0, 0.0, 1e12);
    const double damping = r.number("damping", 0.0, 0.0, 1e9);
    const Vec3 origin = world.get<Transform>(entity).position;

    const toml::array* masses = r.array("masses", kMaxMasses);
    if (!masses || masses->empty()) {
        r.fail("masses", r.where() + " needs 'masses', a non-empty array of { x = [x, y, z], m = kg }");
    }
    for (const toml::node& item : *masses) {
        const toml::table* t = item.as_table();
        if (!t) {
            r.failAt(item, "each element of 'masses' must be an inline table { x = [...], m = ... }");
        }
        TableReader m(*t, r.where() + " masses[" + std::to_string(net.x.size()) + "]", r.context());
        const toml::node* x = m.node("x");
        if (!x) {
            m.fail("x", m.where() + " needs 'x' = [x, y, z]");
        }
        const double mass = m.number("m", 1.0, 1e-9, 1e12);
        const bool pinned = m.boolean("pinned", false);
        Vec3 v;
        if (const toml::node* vn = m.node("v")) {
            v = readVec3(m, *vn, "v");
        }
        net.x.push_back(origin + readVec3(m, *x, "x"));
        net.v.push_back(pinned ? Vec3{} : v);
        net.invMass.push_back(1.0 / mass);
        net.pinned.push_back(pinned ? 1 : 0);
        m.finish();
    }

    if (const toml::array* links = r.array("links", 8 * kMaxMasses)) {
        for (const toml::node& item : *links) {
            const toml::table* t = item.as_table();
            if (!t) {
                r.failAt(item, "each element of 'links' must be an inline table { a = i, b = j }");
            }
            TableReader l(*t, r.where() + " links[" + std::to_string(net.links.size()) + "]", r.context());
            const auto last = static_cast<std::int64_t>(net.x.size()) - 1;
            SpringLink s;
            if (!l.has("a") || !l.has("b")) {
                l.fail(l.has("a") ? "b" : "a", l.where() + " needs both 'a' and 'b' (mass indices)");
            }
            s.a = static_cast<std::uint32_t>(l.integer("a", 0, 0, last));
            s.b = static_cast<std::uint32_t>(l.integer("b", 0, 0, last));
            if (s.a == s.b) {
                l.fail("b", "a link must join two different masses, not mass " + std::to_string(s.a) +
                                " to itself");
            }
            s.rest = l.number("rest", length(net.x[s.b] - net.x[s.a]), 0.0, kHugeCoordinate);
            s.k = l.number("k", stiffness, 0.0, 1e12);
            s.kd = l.number("kd", damping, 0.0, 1e9);
            l.finish();
            net.links.push_back(s);
        }
    }
    attach(r, world, entity, std::move(net));
}

/// [entity.rope]: a chain of masses (README, "Spring networks").
void loadRope(TableReader& r, World& world, Entity entity, const SceneDef&) {
    RopeDef def;
    def.origin = world.get<Transform>(entity).position;
    def.segments = static_cast<int>(r.integer("segments", 20, 1, 100000));
    def.length = r.number("length", 2.0, 1e-6, 1e6);
    const auto d = r.vector<3>("direction", {1.0, 0.0, 0.0}, -kHugeCoordinate, kHugeCoordinate);
    const Vec3 dir{d[0], d[1], d[2]};
    if (length(dir) < 1e-12) {
        r.fail("direction", "'direction' in " + r.where() + " must not be zero");
    }
    def.direction = dir * (1.0 / length(dir));
    def.mass = r.number("mass", 1.0, 1e-9, 1e12);
    def.stiffness = r.number("stiffness", 1000.0, 0.0, 1e12);
    def.bend = r.number("bend", 0.0, 0.0, 1e12);
    def.damping = r.number("damping", 0.0, 0.0, 1e9);
    const auto n = static_cast<std::uint32_t>(def.segments + 1);
    def.pins = readPins(
        r, n, "first",
        [n](const std::string& p, std::vector<std::uint32_t>& out) {
            out = p == "first"  ? std::vector<std::uint32_t>{0}
                  : p == "both" ? std::vector<std::uint32_t>{0, n - 1}
                                : std::vector<std::uint32_t>{};
            return p == "first" || p == "both" || p == "none";
        },
        "'first', 'both', 'none'");
    SpringNetwork net = buildRope(def);
    readCommon(r, net, "implicit_euler");
    // in water, a strand as thick as its thickness (its radius: the distance it keeps from surfaces)
    net.volumePerKg = std::numbers::pi * net.thickness * net.thickness * def.length / def.mass;
    attach(r, world, entity, std::move(net));
}

/// [entity.cloth] (README, "Spring networks").
void loadCloth(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    ClothDef def;
    def.centre = world.get<Transform>(entity).position;
    def.rows = static_cast<int>(r.integer("rows", 20, 2, 1000));
    def.cols = static_cast<int>(r.integer("cols", 20, 2, 1000));
    if (std::int64_t(def.rows) * def.cols > kMaxClothVertices) {
        r.fail("cols", r.where() + " has " + std::to_string(std::int64_t(def.rows) * def.cols) +
                           " vertices; at most " + std::to_string(kMaxClothVertices) +
                           " (512 x 512) are allowed, which already costs about a second per implicit step");
    }
    def.size = r.vector<2>("size", {1.0, 1.0}, 1e-6, 1e6);
    def.vertical = r.choice("plane", "xy", {"xy", "xz"}) == "xy";
    def.mass = r.number("mass", 1.0, 1e-9, 1e12);
    def.stretch = r.number("stretch", 5000.0, 0.0, 1e12);
    def.shear = r.number("shear", 500.0, 0.0, 1e12);
    def.bend = r.number("bend", 50.0, 0.0, 1e12);
    def.damping = r.number("damping", 0.02, 0.0, 1e9);
    def.tube = r.boolean("tube", false);
    if (def.tube && def.cols < 3) {
        r.fail("cols", "a tube needs at least 3 columns around it");
    }
    const int rows = def.rows, cols = def.cols;
    def.pins = readPins(
        r, std::size_t(rows) * cols, "top-corners",
        [rows, cols](const std::string& p, std::vector<std::uint32_t>& out) {
            return clothPinPreset(p, rows, cols, out);
        },
        "'top-corners', 'top-row', 'left-edge', 'corners', 'none'");
    const bool selfCollision = r.boolean("self_collision", false);
    const double wrinkle = r.number("wrinkle", 0.0, 0.0, 1e3);
    SpringNetwork net = buildCloth(def);
    if (wrinkle > 0.0) {
        // no real sheet is flat: each mass off the plane by up to `wrinkle`, from the scene seed, so that a
        // sheet dropped edge-first buckles one way or the other rather than balancing on its edge
        Rng rng(streamSeed(scene.seed, "wrinkle:" + world.get<Name>(entity).value));
        const Vec3 normal = def.vertical ? Vec3{0.0, 0.0, 1.0} : Vec3{0.0, 1.0, 0.0};
        for (std::size_t i = 0; i < net.x.size(); ++i) {
            if (!net.pinned[i]) {
                net.x[i] += normal * rng.uniform(-wrinkle, wrinkle);
            }
        }
    }
    readCommon(r, net, "implicit_euler");
    net.volumePerKg = def.size[0] * def.size[1] * net.thickness / def.mass; // in water, a sheet that thick
    net.selfCollision = selfCollision;
    if (selfCollision && net.thickness <= 0.0) {
        r.fail("thickness",
               "self-collision keeps the cloth's sheets a 'thickness' apart: it must be above 0");
    }
    // masses closer than the thickness along the sheet would collide with their own neighbours' triangles
    // (left to the springs), and every vertex would face a crowd of triangles each step
    const double pi = 3.14159265358979323846;
    const double around = def.tube ? def.size[0] / pi * std::sin(pi / cols) // a tube's chord
                                   : def.size[0] / (cols - 1);
    const double spacing = std::min(around, def.size[1] / (rows - 1));
    if (selfCollision && net.thickness > spacing) {
        r.fail("thickness", "self-collision needs a 'thickness' (" + std::to_string(net.thickness) +
                                " m) no larger than the cloth's grid spacing (" + std::to_string(spacing) +
                                " m): make it thinner, or the cloth coarser");
    }
    attach(r, world, entity, std::move(net));
}

/// [entity.softbody] (README, "Spring networks").
void loadSoftBody(TableReader& r, World& world, Entity entity, const SceneDef&) {
    SoftBodyDef def;
    def.centre = world.get<Transform>(entity).position;
    def.size = r.vector<3>("size", {1.0, 1.0, 1.0}, 1e-6, 1e6);
    const auto res = r.vector<3>("resolution", {4.0, 4.0, 4.0}, 2.0, 1000.0);
    for (std::size_t a = 0; a < 3; ++a) {
        if (res[a] != std::floor(res[a])) {
            r.fail("resolution", "'resolution' in " + r.where() + " must be whole numbers");
        }
        def.resolution[a] = static_cast<int>(res[a]);
    }
    if (std::int64_t(def.resolution[0]) * def.resolution[1] * def.resolution[2] > 200000) {
        r.fail("resolution", r.where() + " has more than 200000 masses");
    }
    def.mass = r.number("mass", 1.0, 1e-9, 1e12);
    def.stiffness = r.number("stiffness", 1000.0, 0.0, 1e12);
    def.shear = r.number("shear", def.stiffness, 0.0, 1e12);
    def.bend = r.number("bend", 0.1 * def.stiffness, 0.0, 1e12);
    def.damping = r.number("damping", 0.5, 0.0, 1e9);
    const std::size_t n = std::size_t(def.resolution[0]) * def.resolution[1] * def.resolution[2];
    def.pins = readPins(
        r, n, "none",
        [](const std::string& p, std::vector<std::uint32_t>& out) {
            out.clear();
            return p == "none";
        },
        "'none'");
    SpringNetwork net = buildSoftBody(def);
    readCommon(r, net, "implicit_euler");
    net.volumePerKg = def.size[0] * def.size[1] * def.size[2] / def.mass; // in water, the box it fills
    attach(r, world, entity, std::move(net));
}

/// `resolution` of an fem box: three whole numbers of cells, at least one each.
std::array<int, 3> readCells(TableReader& r, std::array<double, 3> fallback) {
    const auto res = r.vector<3>("resolution", fallback, 1.0, 1000.0);
    std::array<int, 3> cells{};
    for (std::size_t a = 0; a < 3; ++a) {
        if (res[a] != std::floor(res[a])) {
            r.fail("resolution", "'resolution' in " + r.where() + " must be whole numbers of cells");
        }
        cells[a] = static_cast<int>(res[a]);
    }
    return cells;
}

/// The mesh of [entity.fem]: a box, a sphere or TetGen's files; the elements and nodes are charged to the
/// memory cap before they are made. Box faces name pins; `faces` says whether they can.
TetMesh readFemMesh(TableReader& r, const Vec3& centre, std::array<int, 3>& boxCells, bool& isBox) {
    const std::string mesh = r.string("mesh", "box");
    // what a body and its solver hold: 800 bytes a tetrahedron in all on a 12 x 12 x 12 box (nodes are a
    // fifth of the tetrahedra there), BM_Fem10kImplicit's bytes_per_tet
    constexpr std::size_t kBytesPerTet = 650, kBytesPerNode = 800;
    auto charge = [&](std::size_t nodes, std::size_t tets) {
        r.charge("mesh", tets * kBytesPerTet + nodes * kBytesPerNode,
                 r.where() + " (" + std::to_string(nodes) + " nodes, " + std::to_string(tets) +
                     " tetrahedra)");
    };
    isBox = mesh == "box";
    if (isBox) {
        const auto size = r.vector<3>("size", {1.0, 1.0, 1.0}, 1e-6, 1e6);
        boxCells = readCells(r, {4.0, 4.0, 4.0});
        const std::size_t cells = std::size_t(boxCells[0]) * boxCells[1] * boxCells[2];
        if (cells > 400000) {
            r.fail("resolution", r.where() + " has " + std::to_string(cells) +
                                     " cells (6 tetrahedra each); at most 400000 are allowed");
        }
        charge(std::size_t(boxCells[0] + 1) * (boxCells[1] + 1) * (boxCells[2] + 1), 6 * cells);
        return boxTets(centre, size, boxCells);
    }
    if (mesh == "sphere") {
        const double radius = r.number("radius", 0.5, 1e-6, 1e6);
        const auto cells = static_cast<int>(r.integer("resolution", 6, 1, 60));
        charge(std::size_t(cells + 1) * (cells + 1) * (cells + 1), 6 * std::size_t(cells) * cells * cells);
        return sphereTets(centre, radius, cells);
    }
    if (mesh.size() < 4 || mesh.substr(mesh.size() - 4) != ".ele") {
        r.fail("mesh", "'mesh' in " + r.where() + " is '" + mesh +
                           "'; expected \"box\", \"sphere\" or a TetGen .ele file (its .node beside it)");
    }
    const std::string file = findMeshFile(mesh, r.context().file);
    if (file.empty()) {
        r.fail("mesh",
               "mesh file '" + mesh + "' not found (looked next to the scenario and under the project root)");
    }
    const std::uint64_t cap = r.context().memoryCap;
    try {
        TetMesh m =
            readTetGen(file, centre, std::size_t(cap / kBytesPerNode), std::size_t(cap / kBytesPerTet));
        charge(m.nodes.size(), m.tets.size());
        return m;
    } catch (const std::runtime_error& e) {
        r.fail("mesh", e.what());
    }
}

/// An fem body's surface in cloth contact (`self_collision`): charged as a cloth's triangles are, its
/// thickness above 0 and within its mean surface edge (as a cloth's within its grid spacing: masses closer
/// along the surface would each face a crowd of their neighbours' triangles; a pair closer at rest, where a
/// mesher left a short edge, is kept from crossing and not repelled, as a cloth's is).
void checkFemContact(TableReader& r, SpringNetwork& net) {
    r.charge("self_collision", net.triangles.size() * 1000u,
             r.where() + "'s surface in contact (" + std::to_string(net.triangles.size()) + " triangles)");
    if (net.thickness <= 0.0) {
        r.fail("thickness", "self-collision keeps the body's surface a 'thickness' from other surfaces: it "
                            "must be above 0");
    }
    double sum = 0.0;
    for (const Triangle& t : net.triangles) {
        for (int k = 0; k < 3; ++k) {
            sum += length(net.x[t[k]] - net.x[t[(k + 1) % 3]]);
        }
    }
    const double mean = sum / (3.0 * double(net.triangles.size()));
    if (net.thickness > mean) {
        r.fail("thickness", "self-collision needs a 'thickness' (" + std::to_string(net.thickness) +
                                " m) no larger than the body's mean surface edge (" + std::to_string(mean) +
                                " m): make it thinner, or the mesh coarser");
    }
    net.selfCollision = true;
}

/// Gives every free node of an fem body its start motion (FemElements::startLinear, startAngular): v + w x
/// (x - the centre of mass), where the nodes are now (at the load, where the mesh puts them at rest).
void giveRigidMotion(SpringNetwork& net) {
    Vec3 com;
    double total = 0.0;
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        com += net.x[i] * (1.0 / net.invMass[i]);
        total += 1.0 / net.invMass[i];
    }
    com = com * (1.0 / total);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (!net.pinned[i]) {
            net.v[i] = net.fem.startLinear + cross(net.fem.startAngular, net.x[i] - com);
        }
    }
}

/// How many elements the material's pressure waves cross in a step, past which the solve fails: sqrt((lambda
/// + 2 mu) / rho) h / L, L the cube root of an element's volume. The step's matrix is M + h^2 K (and h K's
/// damping), and K's rows sum to zero along a rigid motion only to float's precision, 1e-7 of h^2 K: once
/// that passes a fraction of the masses, the solve no longer sees them, and gravity with them. Measured on a
/// 1 m box of 2 x 2 x 2 cells falling freely at 1/60 s, density 1000, poisson 0.3: young 1e11 (703
/// elements a step) fell as it should, 3e11 (1218) 9% too fast, 1e12 (2224) not at all, 3e12 flew off
/// sideways at 100 m/s; none of them blew up past the 10 km/s that says so.
constexpr double kMostElementsAStep = 1000.0;

/// Refuses a material too stiff for the scene's step (kMostElementsAStep), at `young`.
void checkFemStiffness(TableReader& r, const SpringNetwork& net, double density, double h) {
    double smallest = std::numeric_limits<double>::infinity();
    for (double volume : net.fem.volume) {
        smallest = std::min(smallest, std::cbrt(volume));
    }
    const double speed = std::sqrt((net.fem.lambda + 2.0 * net.fem.mu) / density);
    const double crossed = speed * h / smallest;
    if (crossed > kMostElementsAStep) {
        char text[400];
        std::snprintf(text, sizeof text,
                      "the material is too stiff for the step: its pressure waves (%.3g m/s) cross %.0f "
                      "elements (%.3g m) in one step of %.3g s, and the solve, in float, loses the masses "
                      "past %.0f; make scene.dt smaller, the material softer or lighter, or the elements "
                      "larger (a body this stiff may be a rigid_body)",
                      speed, crossed, smallest, h, kMostElementsAStep);
        r.fail("young", text);
    }
}

/// [entity.fem] (README, "Finite-element bodies").
void loadFem(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    const Vec3 centre = world.get<Transform>(entity).position;
    std::array<int, 3> cells{};
    bool isBox = false;
    const TetMesh mesh = readFemMesh(r, centre, cells, isBox);
    FemMaterial material;
    material.young = r.number("young", 1e5, 1e-3, 1e13);
    material.poisson = r.number("poisson", 0.3, -1e9, 1e9);
    if (!(material.poisson > -1.0 && material.poisson < 0.5)) {
        r.fail("poisson", "'poisson' in " + r.where() + " is " + std::to_string(material.poisson) +
                              "; a stable material has -1 < poisson < 0.5 (0.5 is incompressible, which "
                              "linear tetrahedra lock on)");
    }
    material.density = r.number("density", 1000.0, 1e-6, 1e6);
    material.stiffnessDamping = r.number("damping", 0.01, 0.0, 1e3);
    material.massDamping = r.number("mass_damping", 0.0, 0.0, 1e6);
    const std::size_t n = mesh.nodes.size();
    const std::vector<std::uint32_t> pins = readPins(
        r, n, "none",
        [&](const std::string& p, std::vector<std::uint32_t>& out) {
            out.clear();
            return p == "none" || (isBox && boxFace(p, cells, out));
        },
        isBox ? "'none', 'top', 'bottom', 'left', 'right', 'front', 'back'"
              : "'none' (the mesh is not a box)");
    const auto lin = r.vector<3>("linear_velocity", {0.0, 0.0, 0.0}, -1e4, 1e4);
    const auto ang = r.vector<3>("angular_velocity", {0.0, 0.0, 0.0}, -1e4, 1e4);
    const bool selfCollision = r.boolean("self_collision", false);
    SpringNetwork net;
    try {
        net = buildFem(mesh, material, pins);
    } catch (const std::invalid_argument& e) {
        r.fail("mesh", r.where() + ": " + e.what());
    }
    // an fem body is advanced by these two alone (the integrator's error lists just them)
    constexpr std::string_view kFemIntegrators[] = {"implicit_euler", "symplectic_euler"};
    readCommon(r, net, "implicit_euler", kFemIntegrators);
    net.volumePerKg = 1.0 / material.density;
    if (net.doublePrecisionSolve) {
        r.fail("solver_precision", "an fem body solves in float: leave out 'solver_precision'");
    }
    checkFemStiffness(r, net, material.density, scene.dt);
    if (selfCollision) {
        checkFemContact(r, net);
    }
    net.fem.startLinear = {lin[0], lin[1], lin[2]};
    net.fem.startAngular = {ang[0], ang[1], ang[2]};
    giveRigidMotion(net);
    net.implicitCharged = true;
    if (net.selfCollision) {
        world.emplace<ClothCollision>(entity, makeClothCollision(net.x));
    }
    world.emplace<SpringNetwork>(entity, std::move(net));
    world.emplace<SpringWorkspace>(entity);
}

constexpr std::string_view kShapeNames[] = {"springs", "rope", "cloth", "softbody", "fem"};

void dumpNetwork(const SpringNetwork& net, JsonWriter& w) {
    w.key("shape").value(kShapeNames[static_cast<std::size_t>(net.kind)]);
    w.key("integrator").value(integratorName(net.integrator));
    if (net.kind == NetworkKind::Cloth || net.kind == NetworkKind::SoftBody) {
        w.key("grid").beginArray();
        for (std::size_t a = 0; a < (net.kind == NetworkKind::Cloth ? 2u : 3u); ++a) {
            w.value(static_cast<std::uint64_t>(net.grid[a]));
        }
        w.endArray();
    }
    if (net.frozen) {
        w.key("frozen").value(true);
    }
    auto list = [&w](const char* key, const std::vector<Vec3>& a) {
        w.key(key).beginArray();
        for (const Vec3& p : a) {
            const double xyz[3] = {p.x, p.y, p.z};
            w.numbers(xyz);
        }
        w.endArray();
    };
    list("x", net.x);
    list("v", net.v);
}

/// The rows dumpNetwork writes under "x" and "v".
bool networkRows(const World& w, Entity e, std::string_view field, Catalog::Rows& rows) {
    const SpringNetwork& net = w.get<SpringNetwork>(e);
    if (field != "x" && field != "v") {
        return false;
    }
    const std::vector<Vec3>& a = field == "x" ? net.x : net.v;
    rows.resize(a.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
        rows[i] = {a[i].x, a[i].y, a[i].z};
    }
    return true;
}

void hashNetwork(const SpringNetwork& net, Hasher& h) {
    // the links are left out: they are the scenario's, no system or event changes them, and the scenario
    // (which a replay carries) stands for them; hashing them every frame was 70% of the curtain's hash
    h.add(net.x);
    h.add(net.v);
    if (!net.waterForce.empty()) { // (none out of water: the bits of a scene without water are as before)
        h.add(net.waterForce);
    }
    h.add(net.invMass);
    h.add(net.pinned);
    h.add(net.drag);
    h.add(net.integrator);
    h.add(net.frozen);
    if (net.kind == NetworkKind::Fem) {
        h.add(net.fem.rotation); // where the next step's search for each element's rotation starts
    }
}

std::optional<std::string> needsVector(const World&, Entity, const EventDef& ev) {
    if (ev.value.size() != 3) {
        return "needs value = [x, y, z]";
    }
    return std::nullopt;
}

std::optional<std::string> needsIndices(const World& world, Entity e, const EventDef& ev) {
    const std::size_t n = world.get<SpringNetwork>(e).x.size();
    if (ev.value.empty()) {
        return "needs value = [i, j, ...], the indices of the masses";
    }
    for (double d : ev.value) {
        if (d < 0 || d != std::floor(d) || d >= static_cast<double>(n)) {
            std::string index; // as written, the shortest text that reads back (-1, 2.5), not -1.000000
            appendNumber(index, d);
            return "mass index " + index + " is not a whole number in [0, " + std::to_string(n - 1) + "]";
        }
    }
    return std::nullopt;
}

/// unpin: the indices of masses, none of them held by an anchor (its body holds it, not a pin).
std::optional<std::string> needsFreeableIndices(const World& world, Entity e, const EventDef& ev) {
    if (auto problem = needsIndices(world, e, ev)) {
        return problem;
    }
    for (const SpringAnchor& a : world.get<SpringNetwork>(e).anchors) {
        for (double d : ev.value) {
            if (static_cast<std::uint32_t>(d) == a.mass) {
                return "mass " + std::to_string(a.mass) +
                       " is held by a rigid body ([[joint]] type \"anchor\"), " + "not by a pin";
            }
        }
    }
    return std::nullopt;
}

bool hasSprings(const World& w, Entity e) {
    return w.has<SpringNetwork>(e);
}

bool isFem(const World& w, Entity e) {
    const SpringNetwork* net = w.tryGet<SpringNetwork>(e);
    return net && net->kind == NetworkKind::Fem;
}

bool isSpringNetwork(const World& w, Entity e) {
    return hasSprings(w, e) && !isFem(w, e);
}

/// Adds an action on the free masses (or, for pin/unpin, on the masses listed) of a network.
void addNetworkAction(Catalog& catalog, const char* action,
                      std::optional<std::string> (*check)(const World&, Entity, const EventDef&),
                      void (*apply)(SpringNetwork&, const EventDef&)) {
    catalog.addEventAction(
        {action,
         "a spring network",
         {"value"},
         hasSprings,
         check,
         [apply](World& w, Entity e, const EventDef& ev) { apply(w.get<SpringNetwork>(e), ev); }});
}

/// What to try when a network of this integrator blows up.
std::string remedy(const SpringNetwork& net, const StepContext& ctx) {
    const std::string smaller = "--set scene.dt=" + std::to_string(ctx.dt / 4) +
                                " (with scene.substeps x4 to keep "
                                "the frame rate)";
    switch (net.integrator) {
    case Integrator::ExplicitEuler:
        return "explicit Euler gains energy on an undamped spring at any step; use symplectic_euler, rk4 or "
               "implicit_euler (integrator = \"implicit_euler\")";
    case Integrator::Midpoint:
    case Integrator::Rk4:
    case Integrator::SymplecticEuler:
        if (net.kind == NetworkKind::Fem && net.fem.stiffnessDamping > 0.0) {
            // the damping force -beta K v taken explicitly needs h < 2 / (beta omega^2), for stiff elements
            // far below the elastic limit 2 / omega: a step four times smaller seldom saves it
            return "the element damping (damping = " + std::to_string(net.fem.stiffnessDamping) +
                   " s) is taken explicitly, which needs a step under 2 / (damping omega^2), for stiff "
                   "elements "
                   "far below what they alone need: set damping = 0, or integrator = \"implicit_euler\" "
                   "(stable at any step and damping), or a smaller step, " +
                   smaller + " or less";
        }
        return "a smaller step, " + smaller + ", or integrator = \"implicit_euler\", stable at any step";
    case Integrator::ImplicitEuler:
        return "implicit Euler is stable for springs, so a force it takes explicitly (a strong wind or "
               "field, a "
               "collider) or a non-physical setting drove it; weaken those, or a smaller step, " +
               smaller;
    }
    return smaller;
}

/// Non-finite, or faster than any sandbox scene moves: the integrator has diverged.
bool blewUp(const SpringNetwork& net) {
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (!isFinite(net.x[i]) || !isFinite(net.v[i]) || dot(net.v[i], net.v[i]) > kMaxSpeed * kMaxSpeed) {
            return true;
        }
    }
    return false;
}

/// The point that holds an anchored mass, and its velocity, on a 3D or a 2D body; nothing if the body is
/// gone. A 2D body holds the mass at its point of the plane, `local.z` off the plane (its entity's z).
struct Holder {
    Vec3 at;
    Vec3 velocity;
};
std::optional<Holder> holderOf(World& world, const SpringAnchor& a) {
    if (!world.alive(a.body)) {
        return std::nullopt;
    }
    if (const RigidBody* body = world.tryGet<RigidBody>(a.body)) {
        const Vec3 at = body->toWorld(a.local);
        return Holder{at, body->velocityAt(at)};
    }
    if (const RigidBody2D* body = world.tryGet<RigidBody2D>(a.body)) {
        const Transform* t = world.tryGet<Transform>(a.body);
        const Vec2 at = body->toWorld({a.local.x, a.local.y});
        const Vec2 v = body->velocityAt(at);
        return Holder{{at[0], at[1], (t ? t->position.z : 0.0) + a.local.z}, {v[0], v[1], 0.0}};
    }
    return std::nullopt;
}

/// Hands a force on the held point over to its body as an impulse over the step: a 2D body takes the part
/// in its plane, and the turn about z of it about its centre of mass (the rest its plane holds).
void push(World& world, const SpringAnchor& a, Vec3 at, Vec3 f, double dt) {
    if (RigidBody* body = world.tryGet<RigidBody>(a.body)) {
        if (body->dynamic()) {
            body->impulse += f * dt;
            body->angularImpulse += cross(at - body->position, f * dt);
        }
    } else if (RigidBody2D* body2 = world.tryGet<RigidBody2D>(a.body); body2 && body2->dynamic()) {
        const Vec2 c = body2->toWorld(body2->localCentre());
        body2->impulse[0] += f.x * dt;
        body2->impulse[1] += f.y * dt;
        body2->angularImpulse += ((at.x - c[0]) * f.y - (at.y - c[1]) * f.x) * dt;
    }
}

} // namespace

/// Anchored masses take the position and velocity of the body's point that holds them (pinned, a mass
/// moves by its velocity through the step, so it keeps up with the body); a body that is gone lets go.
void followAnchors(World& world, SpringNetwork& net) {
    for (std::size_t k = 0; k < net.anchors.size();) {
        const std::optional<Holder> h = holderOf(world, net.anchors[k]);
        if (!h) {
            net.pinned[net.anchors[k].mass] = 0;
            net.anchors.erase(net.anchors.begin() + std::ptrdiff_t(k));
            continue;
        }
        net.x[net.anchors[k].mass] = h->at;
        net.v[net.anchors[k].mass] = h->velocity;
        ++k;
    }
}

/// What the springs and gravity pull each anchored mass with, handed to its body as an impulse over the
/// step (the mass's own inertia is left out: it moves with the body).
void pullAnchors(World& world, SpringNetwork& net, const SpringWorkspace& work, const Environment& env,
                 double dt) {
    for (const SpringAnchor& a : net.anchors) {
        // the integrators leave a pinned mass where it was, at rest; a held one moves with its body, as the
        // implicit solve assumed it would (its right-hand side carries the pinned mass's velocity): leaving
        // it behind put its neighbours a step ahead of it, a force along the body's motion that pumped energy
        // into a crate on a rope until it flew apart
        const Holder h = *holderOf(world, a); // followAnchors let go of every anchor whose body is gone
        net.v[a.mass] = h.velocity;
        net.x[a.mass] = h.at + h.velocity * dt;
        Vec3 f = env.gravity * (1.0 / net.invMass[a.mass]);
        if (!net.waterForce.empty()) {
            f += net.waterForce[a.mass]; // the water's lift on it
        }
        for (const SpringLink& s : net.links) {
            if (s.a != a.mass && s.b != a.mass) {
                continue;
            }
            const Vec3 d = net.x[s.b] - net.x[s.a];
            const double len = length(d);
            if (len < 1e-12) {
                continue;
            }
            const Vec3 u = d * (1.0 / len);
            const Vec3 onA = u * (s.k * (len - s.rest) + s.kd * dot(net.v[s.b] - net.v[s.a], u));
            f += s.a == a.mass ? onA : -onA;
        }
        if (net.kind == NetworkKind::Fem) {
            f += elementForceOn(net, work.fem, a.mass);
        }
        push(world, a, h.at, f, dt); // the lever from where the body is now, to the point where it is now
    }
}

namespace {

/// One network's step, as integrateSprings takes it apart.
struct NetworkStep {
    const Name* name;
    SpringNetwork* net;
    SpringWorkspace* work;
    bool threw = false;
    std::string problem;
};

/// Freezes a network that blew up where it is, and says so once; the rest of the scene runs on.
void freeze(World& world, const StepContext& ctx, NetworkStep& s) {
    SpringNetwork& net = *s.net;
    net.frozen = true;
    for (Vec3& v : net.v) {
        v = Vec3{};
    }
    RunReport& report = world.resource<RunReport>();
    (net.blowUpFails ? report.failures : report.notes)
        .push_back("entity '" + s.name->value + "' blew up at frame " + std::to_string(ctx.frame) + " (t = " +
                   std::to_string(ctx.time) + " s) under " + std::string(integratorName(net.integrator)) +
                   ": " + s.problem + "; it is frozen from here on. Remedy: " + remedy(net, ctx));
}

} // namespace

double networkWork(const SpringNetwork& net) {
    // measured: BM_CurtainSymplectic35 0.096 ms a step against BM_CurtainImplicit35 1.02 ms at one thread,
    // about 10 times; the explicit methods go as their force evaluations a step
    static constexpr double kPerMass[kIntegratorCount] = {1.0, 2.0, 4.0, 1.0, 10.0}; // in Integrator's order
    return double(net.x.size()) * kPerMass[static_cast<std::size_t>(net.integrator)];
}

NetworkShares shareOutNetworks(const std::vector<double>& work, int threads) {
    // stress_cloth's 150 x 150 cloth beside three smaller ones at two threads: 53 ms a frame side by side,
    // 37 one after another, each on both threads
    std::vector<std::size_t> order(work.size());
    double left = 0.0;
    for (std::size_t i = 0; i < work.size(); ++i) {
        order[i] = i;
        left += work[i];
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return work[a] > work[b]; });
    NetworkShares out;
    std::vector<std::uint8_t> alone(work.size(), 0);
    for (std::size_t k = 0; k < order.size(); ++k) {
        // an equal share: of the threads, or of the networks left if fewer (two equal networks at three
        // threads step side by side)
        const std::size_t i = order[k];
        const double sharers = double(std::min(std::size_t(std::max(threads, 1)), order.size() - k));
        if (!(work[i] * sharers > left)) {
            break;
        }
        out.alone.push_back(i);
        alone[i] = 1;
        left -= work[i];
    }
    for (std::size_t i = 0; i < work.size(); ++i) {
        if (!alone[i]) {
            out.together.push_back(i);
        }
    }
    return out;
}

void integrateSprings(World& world, const StepContext& ctx) {
    const auto& g = world.resource<SceneDef>().gravity;
    const Pool<ForceField>* fields = world.findPool<ForceField>();
    std::vector<const Air*> airs;
    world.view<const Air>().each([&](Entity, const Air& air) { airs.push_back(&air); });
    const Environment env{{g[0], g[1], g[2]},
                          fields && fields->size() > 0 ? &fields->values() : nullptr,
                          ctx.profiler,
                          ctx.pool,
                          airs.empty() ? nullptr : &airs};
    // the largest networks step alone, their loops on every thread while that pays, the rest side by side
    // (shareOutNetworks; each touches only itself); what touches bodies runs before and after, in entity
    // order: following reads bodies, pulling adds to their impulses
    std::vector<NetworkStep> steps;
    world.view<const Name, SpringNetwork, SpringWorkspace>().each(
        [&](Entity, const Name& name, SpringNetwork& net, SpringWorkspace& work) {
            if (!net.frozen) {
                followAnchors(world, net);
                steps.push_back({&name, &net, &work, false, {}});
            }
        });
    // a SolverError freezes its network; any other error ends the run, after every network has stepped (as
    // a loop on one thread does), the one of the first network in entity order that threw
    std::vector<std::exception_ptr> errors(steps.size());
    WorkerPool& pool = poolOr(ctx.pool);
    auto step = [&](std::size_t i) {
        // each network shares its loops out or keeps them on its thread, whichever its clock finds faster
        // (engine/thread_choice.h: the same bits either way)
        const ThreadChoice::Run run(steps[i].work->threadChoice, pool);
        Environment own = env;
        own.pool = &run.pool();
        try {
            stepNetwork(*steps[i].net, *steps[i].work, own, ctx.dt);
        } catch (const SolverError& e) {
            steps[i].threw = true;
            steps[i].problem = e.what();
        } catch (...) {
            errors[i] = std::current_exception();
        }
    };
    std::vector<double> work;
    for (const NetworkStep& s : steps) {
        work.push_back(networkWork(*s.net));
    }
    const NetworkShares shares = shareOutNetworks(work, pool.threads());
    for (std::size_t i : shares.alone) {
        step(i);
    }
    pool.forEach(shares.together.size(), 1, [&](std::size_t k) { step(shares.together[k]); });
    for (const std::exception_ptr& error : errors) {
        if (error) {
            std::rethrow_exception(error);
        }
    }
    for (NetworkStep& s : steps) {
        if (!s.threw) {
            pullAnchors(world, *s.net, *s.work, env, ctx.dt);
            if (blewUp(*s.net)) {
                s.problem = "its state became non-finite or faster than 10 km/s";
            }
        }
        if (!s.problem.empty()) {
            freeze(world, ctx, s);
        }
    }
}

namespace {

/// Implicit Euler's warm start and the solutions its first guess remembers (linear_solver.h) shape the next
/// step, so they are state too: the last step's dv, and the remembered solutions the next solve keeps.
template <class S>
void hashSolverState(Hasher& h, const std::vector<Vec3T<S>>& dv, const PcgVectors<S>& pcg) {
    h.add(dv);
    for (std::size_t k = 0; k < std::min(pcg.remembered, kGuessHistory - 1); ++k) {
        h.add(pcg.solutions[k]);
    }
}

/// Whether two loads of a network have the same masses, links and surface: what a set event must keep.
std::optional<std::string> sameShape(const SpringNetwork& b, const SpringNetwork& a) {
    bool same = b.kind == a.kind && b.x.size() == a.x.size() && b.links.size() == a.links.size() &&
                b.triangles == a.triangles && b.grid == a.grid && b.anchors.size() == a.anchors.size();
    for (std::size_t k = 0; same && k < b.links.size(); ++k) {
        same = b.links[k].a == a.links[k].a && b.links[k].b == a.links[k].b;
    }
    if (!same) {
        return std::string("a network's masses and springs cannot change during a run (rows, cols, segments, "
                           "resolution, masses, links, the bend springs' presence); its stiffness, damping, "
                           "masses' weight, pins and the like can");
    }
    if (b.selfCollision != a.selfCollision) {
        return std::string(
            "self_collision cannot change during a run (it puts the surface into cloth contact)");
    }
    // the volumes to rounding: a set of the transform loads the mesh elsewhere, where its corners' sums
    // round otherwise (a moved body was refused as a changed mesh)
    bool sameVolumes = b.fem.volume.size() == a.fem.volume.size();
    for (std::size_t e = 0; sameVolumes && e < b.fem.volume.size(); ++e) {
        sameVolumes = std::abs(b.fem.volume[e] - a.fem.volume[e]) <=
                      1e-9 * std::max(std::abs(b.fem.volume[e]), std::abs(a.fem.volume[e]));
    }
    if (b.fem.tets != a.fem.tets || !sameVolumes) {
        return std::string("an fem body's mesh cannot change during a run (mesh, size, radius, resolution); "
                           "its material (young, poisson, density, damping, mass_damping) and pins can");
    }
    return std::nullopt;
}

/// A `set` event on a network's keys (engine/retune.h): what differs between the two loads, per mass and
/// per link (a cloth's `stretch` reaches its structural springs alone); a moved transform moves the masses.
void patchNetwork(World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
    SpringNetwork& net = w.get<SpringNetwork>(e);
    const SpringNetwork &was = bw.get<SpringNetwork>(b), &now = aw.get<SpringNetwork>(a);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        takeChanged(net.invMass[i], was.invMass[i], now.invMass[i]);
        takeChanged(net.pinned[i], was.pinned[i], now.pinned[i]);
    }
    for (std::size_t k = 0; k < net.links.size(); ++k) {
        takeChanged(net.links[k].rest, was.links[k].rest, now.links[k].rest);
        takeChanged(net.links[k].k, was.links[k].k, now.links[k].k);
        takeChanged(net.links[k].kd, was.links[k].kd, now.links[k].kd);
    }
    takeChanged(net.fem.lambda, was.fem.lambda, now.fem.lambda);
    takeChanged(net.fem.mu, was.fem.mu, now.fem.mu);
    takeChanged(net.fem.stiffnessDamping, was.fem.stiffnessDamping, now.fem.stiffnessDamping);
    takeChanged(net.fem.massDamping, was.fem.massDamping, now.fem.massDamping);
    takeChanged(net.drag, was.drag, now.drag);
    takeChanged(net.volumePerKg, was.volumePerKg, now.volumePerKg);
    takeChanged(net.integrator, was.integrator, now.integrator);
    takeChanged(net.thickness, was.thickness, now.thickness);
    takeChanged(net.friction, was.friction, now.friction);
    takeChanged(net.cgTolerance, was.cgTolerance, now.cgTolerance);
    takeChanged(net.cgMaxIterations, was.cgMaxIterations, now.cgMaxIterations);
    takeChanged(net.doublePrecisionSolve, was.doublePrecisionSolve, now.doublePrecisionSolve);
    takeChanged(net.implicitCharged, was.implicitCharged, now.implicitCharged);
    takeChanged(net.blowUpFails, was.blowUpFails, now.blowUpFails);
    // velocities: a spring network's masses take those a set gives them ("v" of `springs` masses); an fem
    // body whose `linear_velocity` or `angular_velocity` is set takes that motion again, about where its
    // centre of mass is now (as a rigid body set to a velocity moves with it from where it is)
    if (net.kind == NetworkKind::Fem) {
        if (was.fem.startLinear != now.fem.startLinear || was.fem.startAngular != now.fem.startAngular) {
            net.fem.startLinear = now.fem.startLinear;
            net.fem.startAngular = now.fem.startAngular;
            giveRigidMotion(net);
        }
    } else {
        for (std::size_t i = 0; i < net.x.size(); ++i) {
            if (!net.pinned[i]) {
                takeChanged(net.v[i], was.v[i], now.v[i]);
            }
        }
    }
    // a set of the transform moves the masses from where the entity is now to where the set puts it (the
    // load compared with may have it elsewhere again: engine/retune.cpp)
    const Vec3& to = aw.get<Transform>(a).position;
    const Vec3 moved = to != bw.get<Transform>(b).position ? to - w.get<Transform>(e).position : Vec3{};
    if (moved != Vec3{}) {
        for (Vec3& x : net.x) {
            x += moved;
        }
        net.resting.clear(); // the surfaces it rested on are where it was
    }
}

} // namespace

void registerSpringSystem(Catalog& catalog) {
    catalog.addComponent({"springs", loadSprings, {}, true});
    catalog.addComponent({"rope", loadRope, {}, true});
    catalog.addComponent({"cloth", loadCloth, {}, true});
    catalog.addComponent({"softbody", loadSoftBody, {}, true});
    catalog.addComponent({"fem", loadFem, {}, true});
    catalog.addRetune(Retune{{"springs", "rope", "cloth", "softbody", "fem"},
                             hasSprings,
                             [](const World& bw, Entity b, const World& aw, Entity a) {
                                 return sameShape(bw.get<SpringNetwork>(b), aw.get<SpringNetwork>(a));
                             },
                             patchNetwork});
    catalog.addState(
        StateCodec{"fem", isFem,
                   [](const World& w, Entity e, JsonWriter& out) {
                       const SpringNetwork& net = w.get<SpringNetwork>(e);
                       out.key("nodes").value(static_cast<std::uint64_t>(net.x.size()));
                       out.key("tetrahedra").value(static_cast<std::uint64_t>(net.fem.tets.size()));
                       dumpNetwork(net, out);
                   },
                   [](const World& w, Entity e, Hasher& h) {
                       hashNetwork(w.get<SpringNetwork>(e), h);
                       if (const auto* work = w.tryGet<SpringWorkspace>(e)) {
                           hashSolverState(h, work->fem.dv, work->fem.pcg);
                       }
                   },
                   networkRows});
    catalog.addState(StateCodec{
        "springs", isSpringNetwork,
        [](const World& w, Entity e, JsonWriter& out) { dumpNetwork(w.get<SpringNetwork>(e), out); },
        [](const World& w, Entity e, Hasher& h) {
            hashNetwork(w.get<SpringNetwork>(e), h);
            if (const auto* work = w.tryGet<SpringWorkspace>(e)) {
                hashSolverState(h, work->single.dv, work->single.pcg);
                hashSolverState(h, work->precise.dv, work->precise.pcg);
            }
        },
        networkRows});

    // impulse: a momentum change J shared by the free masses (each gets dv = J / their total mass)
    addNetworkAction(catalog, "impulse", needsVector, [](SpringNetwork& net, const EventDef& ev) {
        double total = 0.0;
        for (std::size_t i = 0; i < net.invMass.size(); ++i) {
            total += net.pinned[i] ? 0.0 : 1.0 / net.invMass[i];
        }
        if (total <= 0.0) {
            return;
        }
        const Vec3 dv = Vec3{ev.value[0], ev.value[1], ev.value[2]} * (1.0 / total);
        for (std::size_t i = 0; i < net.v.size(); ++i) {
            if (!net.pinned[i]) {
                net.v[i] += dv;
            }
        }
    });
    addNetworkAction(catalog, "set_velocity", needsVector, [](SpringNetwork& net, const EventDef& ev) {
        for (std::size_t i = 0; i < net.v.size(); ++i) {
            if (!net.pinned[i]) {
                net.v[i] = {ev.value[0], ev.value[1], ev.value[2]};
            }
        }
    });
    addNetworkAction(catalog, "pin", needsIndices, [](SpringNetwork& net, const EventDef& ev) {
        for (double d : ev.value) {
            net.pinned[static_cast<std::size_t>(d)] = 1;
            net.v[static_cast<std::size_t>(d)] = {};
        }
    });
    addNetworkAction(catalog, "unpin", needsFreeableIndices, [](SpringNetwork& net, const EventDef& ev) {
        for (double d : ev.value) {
            net.pinned[static_cast<std::size_t>(d)] = 0;
        }
    });
}

} // namespace tumble
