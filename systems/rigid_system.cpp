#include "systems/rigid_system.h"

#include "components/joint.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/profiler.h"
#include "engine/retune.h"
#include "engine/transform.h"
#include "systems/box2d_bridge.h"
#include "systems/bullet_bridge.h"
#include "systems/obj_mesh.h"

#include <cmath>
#include <map>

namespace tumble {

namespace {

/// The lightest moving body: both engines compute in float, where a mass below about 1e-38 kg is zero (a
/// static body) and one near it gives an inverse mass that overflows.
constexpr double kLightestBody = 1e-6; ///< kg

std::string lightestMessage(double mass) {
    char text[64];
    std::snprintf(text, sizeof text, "%g", mass);
    return std::string("a moving body's mass is ") + text +
           " kg, below the least the engines' float arithmetic carries (1e-6 kg); 0 makes it static";
}

constexpr double kHuge = 1e9;

/// What one body costs in its engine (the body, its shape, its broad-phase proxy and contacts), roughly.
constexpr std::uint64_t kBodyBytes = 2048;

/// Meshes already read, by file, so that 300 rocks share one.
struct MeshCache {
    std::map<std::string, std::shared_ptr<const ShapeMesh>> byFile; ///< "convex:" or "mesh:" + file
};

std::shared_ptr<const ShapeMesh> loadMesh(TableReader& r, World& world, bool convex) {
    const std::string name = r.requiredString("mesh");
    const std::string file = findMeshFile(name, r.context().file);
    if (file.empty()) {
        r.fail("mesh",
               "mesh file '" + name + "' not found (looked next to the scenario and under the project root)");
    }
    MeshCache* cache = world.tryResource<MeshCache>();
    if (!cache) {
        cache = &world.setResource<MeshCache>();
    }
    const std::string key = (convex ? "convex:" : "mesh:") + file;
    auto found = cache->byFile.find(key);
    if (found != cache->byFile.end()) {
        return found->second;
    }
    std::shared_ptr<const ShapeMesh> mesh;
    try {
        mesh = readObjMesh(file, name);
        mesh = convex ? convexHullMesh(*mesh) : mesh;
    } catch (const std::runtime_error& e) {
        r.fail("mesh", e.what());
    }
    // Bullet's copy of the triangles and its bounding-volume tree over them, beside ours
    r.charge("mesh", mesh->triangles.size() * 200u + mesh->vertices.size() * 48u,
             "mesh '" + name + "' (" + std::to_string(mesh->triangles.size()) + " triangles)");
    return cache->byFile[key] = mesh;
}

Vec3 vec(const std::array<double, 3>& a) {
    return {a[0], a[1], a[2]};
}

void loadRigidBody(TableReader& r, World& world, Entity entity, const SceneDef&) {
    r.charge("shape", kBodyBytes, r.where());
    RigidBody b;
    const std::string shape =
        r.choice("shape", "box", {"plane", "box", "sphere", "capsule", "cylinder", "convex", "mesh"});
    b.shape = shape == "plane"      ? ShapeKind::Plane
              : shape == "box"      ? ShapeKind::Box
              : shape == "sphere"   ? ShapeKind::Sphere
              : shape == "capsule"  ? ShapeKind::Capsule
              : shape == "cylinder" ? ShapeKind::Cylinder
              : shape == "convex"   ? ShapeKind::Convex
                                    : ShapeKind::Mesh;
    if (b.shape == ShapeKind::Plane) {
        const Vec3 normal = vec(r.vector<3>("normal", {0.0, 1.0, 0.0}, -kHuge, kHuge));
        if (length(normal) < 1e-12) {
            r.fail("normal", "'normal' of a plane must not be zero");
        }
        b.normal = normal * (1.0 / length(normal));
    }
    if (b.shape == ShapeKind::Box) {
        b.halfExtents = vec(r.vector<3>("half_extents", {0.5, 0.5, 0.5}, 1e-3, kHuge));
    }
    if (b.shape == ShapeKind::Sphere || b.shape == ShapeKind::Capsule || b.shape == ShapeKind::Cylinder) {
        b.radius = r.number("radius", 0.5, 1e-3, kHuge);
    }
    if (b.shape == ShapeKind::Capsule || b.shape == ShapeKind::Cylinder) {
        b.height = r.number("height", 1.0, b.shape == ShapeKind::Cylinder ? 1e-3 : 0.0, kHuge);
    }
    if (b.shape == ShapeKind::Convex || b.shape == ShapeKind::Mesh) {
        b.mesh = loadMesh(r, world, b.shape == ShapeKind::Convex);
    }
    b.mass = r.number("mass", 0.0, 0.0, 1e9);
    if (b.mass > 0.0 && b.mass < kLightestBody) {
        r.fail("mass", lightestMessage(b.mass));
    }
    if (b.mass > 0.0 && (b.shape == ShapeKind::Plane || b.shape == ShapeKind::Mesh)) {
        r.fail("mass", "a " + shape + " can only be static (mass = 0)" +
                           (b.shape == ShapeKind::Mesh ? "; a moving mesh is a 'convex' shape" : ""));
    }
    b.friction = r.number("friction", 0.6, 0.0, 100.0);
    b.restitution = r.number("restitution", 0.0, 0.0, 1.0);
    b.canSleep = r.boolean("sleep", true);
    const auto q = r.vector<4>("orientation", {0.0, 0.0, 0.0, 1.0}, -kHuge, kHuge);
    const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (qn < 1e-9) {
        r.fail("orientation", "'orientation' is a quaternion [x, y, z, w] and must not be zero");
    }
    b.orientation = {q[0] / qn, q[1] / qn, q[2] / qn, q[3] / qn};
    if (b.shape == ShapeKind::Plane && b.orientation != Quat{}) {
        r.fail("orientation", "a plane is oriented by its 'normal', not by 'orientation'");
    }
    b.linearVelocity = vec(r.vector<3>("linear_velocity", {0.0, 0.0, 0.0}, -1e5, 1e5));
    b.angularVelocity = vec(r.vector<3>("angular_velocity", {0.0, 0.0, 0.0}, -1e5, 1e5));
    if (!b.dynamic() && (b.linearVelocity != Vec3{} || b.angularVelocity != Vec3{})) {
        r.fail(b.linearVelocity != Vec3{} ? "linear_velocity" : "angular_velocity",
               "a static body (mass = 0) cannot move; give it a mass to set its velocity");
    }
    const bool plane = b.shape == ShapeKind::Plane;
    b.color = vec(
        r.vector<3>("color", plane ? std::array{0.55, 0.57, 0.52} : std::array{0.62, 0.60, 0.56}, 0.0, 1.0));
    // the entity's position places the shape as its file has it; the body's centre is its centre of mass
    b.position =
        world.get<Transform>(entity).position + (b.mesh ? rotate(b.orientation, b.mesh->centre) : Vec3{});
    world.emplace<RigidBody>(entity, b);
}

/// Box2D's conditions on a polygon, checked here so that bad input is an error and not Box2D's assertion:
/// 3 to 8 vertices, convex, with area, no two closer than Box2D merges; returned counter-clockwise.
std::vector<Vec2> readPolygon(TableReader& r) {
    const toml::array* list = r.array("vertices", 8);
    if (!list) {
        r.fail("vertices", "a polygon needs 'vertices', 3 to 8 points [[x, y], ...], convex");
    }
    if (list->size() < 3) {
        r.fail("vertices", "a polygon needs 3 to 8 vertices, not " + std::to_string(list->size()));
    }
    std::vector<Vec2> v(list->size());
    for (std::size_t i = 0; i < list->size(); ++i) {
        r.readNumbers(*list->get(i), "vertices", v[i].data(), 2, -kHuge, kHuge);
    }
    double twiceArea = 0.0;
    for (std::size_t i = 0; i < v.size(); ++i) {
        const Vec2& p = v[i];
        const Vec2& q = v[(i + 1) % v.size()];
        twiceArea += p[0] * q[1] - q[0] * p[1];
        if (std::hypot(q[0] - p[0], q[1] - p[1]) < 0.01) {
            r.fail("vertices", "vertices " + std::to_string(i) + " and " +
                                   std::to_string((i + 1) % v.size()) +
                                   " are closer than 1 cm (Box2D would merge them)");
        }
    }
    if (std::abs(twiceArea) < 1e-6) {
        r.fail("vertices", "the polygon has no area");
    }
    if (twiceArea < 0.0) {
        std::reverse(v.begin(), v.end());
    }
    for (std::size_t i = 0; i < v.size(); ++i) {
        const Vec2& a = v[i];
        const Vec2& b = v[(i + 1) % v.size()];
        const Vec2& c = v[(i + 2) % v.size()];
        const double turn = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0]);
        if (turn <= 0.0) {
            r.fail("vertices",
                   "the polygon is not convex at vertex " + std::to_string((i + 1) % v.size()) +
                       " (Box2D takes convex polygons; split a concave one into bodies joined by a "
                       "fixed joint)");
        }
    }
    return v;
}

void loadRigidBody2D(TableReader& r, World& world, Entity entity, const SceneDef&) {
    r.charge("shape", kBodyBytes, r.where());
    RigidBody2D b;
    const std::string shape = r.choice("shape", "box", {"box", "circle", "polygon", "edge"});
    b.shape = shape == "box"       ? Shape2DKind::Box
              : shape == "circle"  ? Shape2DKind::Circle
              : shape == "polygon" ? Shape2DKind::Polygon
                                   : Shape2DKind::Edge;
    switch (b.shape) {
    case Shape2DKind::Box:
        b.halfExtents = r.vector<2>("half_extents", {0.5, 0.5}, 0.01, kHuge);
        break;
    case Shape2DKind::Circle:
        b.radius = r.number("radius", 0.5, 0.01, kHuge);
        break;
    case Shape2DKind::Polygon:
        b.vertices = readPolygon(r);
        break;
    case Shape2DKind::Edge:
        b.from = r.vector<2>("from", {-1.0, 0.0}, -kHuge, kHuge);
        b.to = r.vector<2>("to", {1.0, 0.0}, -kHuge, kHuge);
        if (std::hypot(b.to[0] - b.from[0], b.to[1] - b.from[1]) < 0.01) {
            r.fail("to", "an edge's 'from' and 'to' must be at least 1 cm apart");
        }
        break;
    }
    b.mass = r.number("mass", 0.0, 0.0, 1e9);
    if (b.mass > 0.0 && b.mass < kLightestBody) {
        r.fail("mass", lightestMessage(b.mass));
    }
    if (b.mass > 0.0 && b.shape == Shape2DKind::Edge) {
        r.fail("mass", "an edge has no area to carry a mass: it can only be static (mass = 0)");
    }
    b.friction = r.number("friction", 0.6, 0.0, 100.0);
    b.restitution = r.number("restitution", 0.0, 0.0, 1.0);
    b.canSleep = r.boolean("sleep", true);
    b.angle = r.number("angle", 0.0, -1e6, 1e6);
    b.velocity = r.vector<2>("linear_velocity", {0.0, 0.0}, -1e5, 1e5);
    b.angularVelocity = r.number("angular_velocity", 0.0, -1e5, 1e5);
    if (!b.dynamic() && (b.velocity != Vec2{0.0, 0.0} || b.angularVelocity != 0.0)) {
        r.fail(b.velocity != Vec2{0.0, 0.0} ? "linear_velocity" : "angular_velocity",
               "a static body (mass = 0) cannot move; give it a mass to set its velocity");
    }
    b.color = vec(r.vector<3>("color", {0.62, 0.60, 0.56}, 0.0, 1.0));
    const Vec3 p = world.get<Transform>(entity).position;
    b.position = {p.x, p.y};
    world.emplace<RigidBody2D>(entity, b);
}

// ---- joints

/// A body holding masses takes their springs' pull explicitly, once a step: stable while the step is short
/// beside the period of the body on those springs, omega dt < 2 with omega = sqrt(k / m), k the springs
/// from the masses it holds to the masses it does not, in every network, damping likewise kd dt / m < 2
/// (the springs' other ends taken as fixed: the stiffest they can be). Refuses, with a factor of 2 to
/// spare as for a spring joint, what would blow up. Checked at each anchor with all those before it, so
/// the last of many anchors on one body sees them all.
void refuseStiffAnchors(TableReader& r, World& world, Entity body, double mass, double dt) {
    if (mass <= 0.0) {
        return; // static: nothing moves it
    }
    double k = 0.0, kd = 0.0;
    world.view<const SpringNetwork>().each([&](Entity, const SpringNetwork& net) {
        std::vector<char> held(net.x.size(), 0);
        bool any = false;
        for (const SpringAnchor& a : net.anchors) {
            if (a.body == body) {
                held[a.mass] = 1;
                any = true;
            }
        }
        for (std::size_t i = 0; any && i < net.links.size(); ++i) {
            const SpringLink& l = net.links[i];
            if (held[l.a] != held[l.b]) {
                k += l.k;
                kd += l.kd;
            }
        }
        // an fem body's elements: the block K_ab between a held and a free corner is at most
        // V (|lambda| + 2 mu) |g_a| |g_b| in norm (systems/fem.h), its damping beta times that
        const FemElements& fem = net.fem;
        for (std::size_t e = 0; any && e < fem.tets.size(); ++e) {
            for (std::size_t a = 0; a < 4; ++a) {
                for (std::size_t b = 0; b < 4; ++b) {
                    if (held[fem.tets[e][a]] && !held[fem.tets[e][b]]) {
                        const double kab = fem.volume[e] * (std::abs(fem.lambda) + 2.0 * fem.mu) *
                                           length(fem.gradients[e][a]) * length(fem.gradients[e][b]);
                        k += kab;
                        kd += fem.stiffnessDamping * kab;
                    }
                }
            }
        }
    });
    const double omegaDt = std::sqrt(k / mass) * dt;
    if (omegaDt > 1.0 || kd * dt / mass > 1.0) {
        char text[400];
        std::snprintf(text, sizeof text,
                      "the springs or elements at the masses this body holds (%g N/m, %g N s/m in all) are "
                      "too stiff (or "
                      "too damped) for its %g kg at dt = %g s: it takes their pull explicitly, stable while "
                      "sqrt(k/m) dt < 1 here (it is %.3g); make the body heavier, the springs softer, or the "
                      "step shorter",
                      k, kd, mass, dt, omegaDt);
        r.fail("b", text);
    }
}

/// type = "anchor": a spring network's mass held by a rigid body, 3D or 2D (a = the network, mass = its
/// index, or a list of indices each held where it is; b = the body, pivot = the holding point of a single
/// mass, by default where the mass is).
void loadAnchor(TableReader& r, World& world, const EntityLookup& lookup, double dt) {
    const Entity netEntity = lookup(r, "a", true);
    SpringNetwork* net = world.tryGet<SpringNetwork>(netEntity);
    if (!net) {
        r.fail(
            "a",
            "an anchor's 'a' must name a spring network (springs, rope, cloth or softbody) or an fem body");
    }
    if (!r.has("mass")) {
        r.fail("mass", "an anchor needs 'mass', the index of the held mass (or a list of them)");
    }
    std::vector<std::uint32_t> masses;
    const toml::node* listed = r.node("mass");
    if (listed && listed->is_array()) {
        for (const toml::node& item : *r.array("mass", net->x.size())) {
            // a float is refused before it is read as an integer (1e308 does not fit one)
            const auto i = item.is_integer() ? item.value<std::int64_t>() : std::nullopt;
            if (!i || *i < 0 || static_cast<std::size_t>(*i) >= net->x.size()) {
                r.failAt(item, "'mass' lists mass indices, each a whole number in [0, " +
                                   std::to_string(net->x.size() - 1) + "]");
            }
            masses.push_back(static_cast<std::uint32_t>(*i));
        }
        if (masses.empty()) {
            r.fail("mass", "an anchor's list of masses is empty");
        }
        if (r.has("pivot")) {
            r.fail("pivot", "an anchor of a list of masses holds each where it is: no 'pivot'");
        }
    } else {
        masses.push_back(
            static_cast<std::uint32_t>(r.integer("mass", 0, 0, std::int64_t(net->x.size()) - 1)));
    }
    const Entity bodyEntity = lookup(r, "b", true);
    const RigidBody* body = world.tryGet<RigidBody>(bodyEntity);
    const RigidBody2D* body2 = world.tryGet<RigidBody2D>(bodyEntity);
    if (!body && !body2) {
        r.fail("b", "an anchor's 'b' must name a rigid_body or a rigid_body_2d that holds the mass");
    }
    // a 2D body holds a mass at its point of the plane and the mass's height off the plane (its z)
    const double plane = body2 ? world.get<Transform>(bodyEntity).position.z : 0.0;
    for (std::uint32_t mass : masses) {
        if (net->pinned[mass]) {
            r.fail("mass", "mass " + std::to_string(mass) + " is already pinned" +
                               (std::any_of(net->anchors.begin(), net->anchors.end(),
                                            [&](const SpringAnchor& a) { return a.mass == mass; })
                                    ? " (anchored twice)"
                                    : "; a held mass must be free"));
        }
        const Vec3 at = net->x[mass];
        const Vec3 pivot =
            masses.size() == 1 ? vec(r.vector<3>("pivot", {at.x, at.y, at.z}, -kHuge, kHuge)) : at;
        if (body) {
            net->anchors.push_back({mass, bodyEntity, body->toLocal(pivot)});
        } else {
            const Vec2 local = body2->toLocal({pivot.x, pivot.y});
            net->anchors.push_back({mass, bodyEntity, {local[0], local[1], pivot.z - plane}});
        }
        net->pinned[mass] = 1;
    }
    refuseStiffAnchors(r, world, bodyEntity, body ? (body->dynamic() ? body->mass : 0.0) : body2->mass, dt);
}

void loadJoint(TableReader& r, World& world, const SceneDef& scene, const EntityLookup& lookup) {
    Joint j;
    const std::string type =
        r.choice("type", "point", {"hinge", "point", "fixed", "slider", "spring", "anchor"});
    if (type == "anchor") {
        loadAnchor(r, world, lookup, scene.dt);
        return;
    }
    j.kind = type == "hinge"    ? JointKind::Hinge
             : type == "point"  ? JointKind::Point
             : type == "fixed"  ? JointKind::Fixed
             : type == "slider" ? JointKind::Slider
                                : JointKind::Spring;
    j.a = lookup(r, "a", true);
    j.b = lookup(r, "b", false);
    const RigidBody* a3 = world.tryGet<RigidBody>(j.a);
    const RigidBody2D* a2 = world.tryGet<RigidBody2D>(j.a);
    if (!a3 && !a2) {
        r.fail("a", "'a' must name a rigid body (an entity with rigid_body or rigid_body_2d)");
    }
    j.twoD = a2 != nullptr;
    const RigidBody* b3 = j.b == kNullEntity ? nullptr : world.tryGet<RigidBody>(j.b);
    const RigidBody2D* b2 = j.b == kNullEntity ? nullptr : world.tryGet<RigidBody2D>(j.b);
    if (j.b != kNullEntity) {
        if (j.b == j.a) {
            r.fail("b", "a joint joins two different bodies ('b' omitted: the body and the world)");
        }
        if (j.twoD ? !b2 : !b3) {
            r.fail("b", std::string("'b' must name a ") + (j.twoD ? "rigid_body_2d" : "rigid_body") +
                            " like 'a' (a joint cannot join a 2D body and a 3D one)");
        }
    }
    const bool aMoves = j.twoD ? a2->dynamic() : a3->dynamic();
    const bool bMoves = j.b != kNullEntity && (j.twoD ? b2->dynamic() : b3->dynamic());
    if (!aMoves && !bMoves) {
        r.fail("a", "this joint holds nothing that moves: give 'a' or 'b' a mass");
    }
    const Vec3 aCentre = world.get<Transform>(j.a).position;
    j.pivot = vec(r.vector<3>("pivot", {aCentre.x, aCentre.y, aCentre.z}, -kHuge, kHuge));
    if (j.kind == JointKind::Hinge || j.kind == JointKind::Slider) {
        const Vec3 axis = vec(r.vector<3>("axis", {0.0, 0.0, 1.0}, -kHuge, kHuge));
        if (j.twoD && j.kind == JointKind::Hinge && (axis.x != 0.0 || axis.y != 0.0 || axis.z <= 0.0)) {
            r.fail("axis", "a 2D hinge turns about z: its 'axis' can only be [0, 0, 1] (or left out)");
        }
        const double len = j.twoD && j.kind == JointKind::Slider ? std::hypot(axis.x, axis.y) : length(axis);
        if (len < 1e-9) {
            r.fail("axis",
                   j.twoD ? "a 2D slider's 'axis' must have an x or y part" : "'axis' must not be zero");
        }
        j.axis = axis * (1.0 / length(axis));
        if (r.has("limits")) {
            const auto lim = r.range("limits", {0.0, 0.0}, -kHuge, kHuge);
            j.limited = true;
            j.lower = lim.first;
            j.upper = lim.second;
        }
    } else {
        for (const char* key : {"axis", "limits"}) {
            if (r.has(key)) {
                r.fail(key, "a " + type + " joint takes no '" + key + "' (hinge and slider joints do)");
            }
        }
    }
    if (j.kind == JointKind::Spring) {
        const Vec3 bEnd = j.b == kNullEntity ? j.pivot : world.get<Transform>(j.b).position;
        j.pivotB = vec(r.vector<3>("pivot_b", {bEnd.x, bEnd.y, bEnd.z}, -kHuge, kHuge));
        j.stiffness = r.requiredNumber("stiffness", 0.0, 1e9);
        j.damping = r.number("damping", 0.0, 0.0, 1e9);
        // Box2D measures in the plane: a 2D spring's length leaves out z
        const Vec3 span = j.pivotB - j.pivot;
        j.rest = r.number("rest", j.twoD ? std::hypot(span.x, span.y) : length(span), 0.0, kHuge);
        if (!j.twoD) {
            // Bullet takes the spring as a force, explicitly: stable while the step is short beside the
            // period of the lighter end, omega dt < 2; refuse what would blow up (with a factor of 2 to
            // spare)
            const double mass =
                std::min(a3->dynamic() ? a3->mass : 1e300, b3 && b3->dynamic() ? b3->mass : 1e300);
            const double omegaDt = std::sqrt(j.stiffness / mass) * scene.dt;
            if (omegaDt > 1.0 || j.damping * scene.dt / mass > 1.0) {
                r.fail("stiffness", "this spring is too stiff (or too damped) for the step: with " +
                                        std::to_string(mass) +
                                        " kg at its lighter end and dt = " + std::to_string(scene.dt) +
                                        " s it would blow up (a 3D spring joint is a force taken explicitly, "
                                        "stable while sqrt(k/m) dt < 1 here); lower 'stiffness' or the step");
            }
        }
    } else {
        for (const char* key : {"pivot_b", "stiffness", "damping", "rest"}) {
            if (r.has(key)) {
                r.fail(key,
                       "'" + std::string(key) + "' belongs to spring joints, not to a " + type + " joint");
            }
        }
    }
    const Entity e = world.create();
    world.emplace<Joint>(e, j);
}

// ---- dump and hash

void dumpRigid(const RigidBody& b, JsonWriter& w) {
    const double x[3] = {b.position.x, b.position.y, b.position.z};
    const double q[4] = {b.orientation.x, b.orientation.y, b.orientation.z, b.orientation.w};
    const double v[3] = {b.linearVelocity.x, b.linearVelocity.y, b.linearVelocity.z};
    const double om[3] = {b.angularVelocity.x, b.angularVelocity.y, b.angularVelocity.z};
    w.key("x").beginArray().numbers(x).endArray();
    w.key("q").beginArray().numbers(q).endArray();
    w.key("v").beginArray().numbers(v).endArray();
    w.key("w").beginArray().numbers(om).endArray();
}

void hashRigid(const RigidBody& b, Hasher& h) {
    h.add(b.position);
    h.add(b.orientation);
    h.add(b.linearVelocity);
    h.add(b.angularVelocity);
    h.add(b.sleeping);
    h.add(b.frozen);
}

void dumpRigid2D(const RigidBody2D& b, JsonWriter& w) {
    w.key("x").beginArray().numbers(b.position.data(), 2).endArray();
    w.key("angle").beginArray().value(b.angle).endArray();
    w.key("v").beginArray().numbers(b.velocity.data(), 2).endArray();
}

void hashRigid2D(const RigidBody2D& b, Hasher& h) {
    h.add(b.position);
    h.add(b.angle);
    h.add(b.velocity);
    h.add(b.angularVelocity);
    h.add(b.sleeping);
}

// ---- events

bool isRigid(const World& w, Entity e) {
    return w.has<RigidBody>(e);
}
bool isRigid2D(const World& w, Entity e) {
    return w.has<RigidBody2D>(e);
}

template <class Body>
std::optional<std::string> checkVelocityEvent(const World& w, Entity e, const EventDef& ev,
                                              std::size_t linear, std::size_t withAngular) {
    if (!w.get<Body>(e).dynamic()) {
        return "the body is static (mass = 0) and cannot be pushed";
    }
    if (ev.value.size() != linear && ev.value.size() != withAngular) {
        return linear == 3 ? "needs value = [x, y, z] (or six numbers: linear, then angular)"
                           : "needs value = [x, y] (or three numbers: linear, then angular about z)";
    }
    return std::nullopt;
}

void registerRigidEvents(Catalog& catalog) {
    // impulse: N s at the centre of mass (and, with six numbers, N m s about it)
    catalog.addEventAction({"impulse",
                            "a rigid body",
                            {"value"},
                            isRigid,
                            [](const World& w, Entity e, const EventDef& ev) {
                                return checkVelocityEvent<RigidBody>(w, e, ev, 3, 6);
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                RigidBody& b = w.get<RigidBody>(e);
                                b.impulse += Vec3{ev.value[0], ev.value[1], ev.value[2]};
                                if (ev.value.size() == 6) {
                                    b.angularImpulse += Vec3{ev.value[3], ev.value[4], ev.value[5]};
                                }
                            }});
    catalog.addEventAction({"set_velocity",
                            "a rigid body",
                            {"value"},
                            isRigid,
                            [](const World& w, Entity e, const EventDef& ev) {
                                return checkVelocityEvent<RigidBody>(w, e, ev, 3, 6);
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                RigidBody& b = w.get<RigidBody>(e);
                                b.linearVelocity = {ev.value[0], ev.value[1], ev.value[2]};
                                if (ev.value.size() == 6) {
                                    b.angularVelocity = {ev.value[3], ev.value[4], ev.value[5]};
                                }
                                b.teleported = true;
                            }});
    catalog.addEventAction({"impulse",
                            "a 2D rigid body",
                            {"value"},
                            isRigid2D,
                            [](const World& w, Entity e, const EventDef& ev) {
                                return checkVelocityEvent<RigidBody2D>(w, e, ev, 2, 3);
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                RigidBody2D& b = w.get<RigidBody2D>(e);
                                b.impulse[0] += ev.value[0];
                                b.impulse[1] += ev.value[1];
                                if (ev.value.size() == 3) {
                                    b.angularImpulse += ev.value[2];
                                }
                            }});
    catalog.addEventAction({"set_velocity",
                            "a 2D rigid body",
                            {"value"},
                            isRigid2D,
                            [](const World& w, Entity e, const EventDef& ev) {
                                return checkVelocityEvent<RigidBody2D>(w, e, ev, 2, 3);
                            },
                            [](World& w, Entity e, const EventDef& ev) {
                                RigidBody2D& b = w.get<RigidBody2D>(e);
                                b.velocity = {ev.value[0], ev.value[1]};
                                if (ev.value.size() == 3) {
                                    b.angularVelocity = ev.value[2];
                                }
                                b.teleported = true;
                            }});
}

/// A `set` event on a body's keys (engine/retune.h): its mass, material, sleep and colour, and where it is
/// and how it moves (a teleport); not its shape, nor whether it moves at all.
template <class Body>
Retune bodyRetune(const char* key) {
    auto check = [](const World& bw, Entity b, const World& aw, Entity a) -> std::optional<std::string> {
        const Body &was = bw.get<Body>(b), &now = aw.get<Body>(a);
        if (was.dynamic() != now.dynamic()) {
            return std::string("a body cannot start or stop moving during a run (mass 0 is static)");
        }
        bool sameShape =
            was.shape == now.shape && was.halfExtents == now.halfExtents && was.radius == now.radius;
        if constexpr (std::is_same_v<Body, RigidBody>) {
            // a hull or mesh: each load reads its own copy of the file, so the same file is the same shape
            const bool sameMesh =
                was.mesh == now.mesh || (was.mesh && now.mesh && was.mesh->path == now.mesh->path);
            sameShape = sameShape && was.height == now.height && sameMesh && was.normal == now.normal;
        } else {
            sameShape = sameShape && was.vertices == now.vertices && was.from == now.from && was.to == now.to;
        }
        if (!sameShape) {
            return std::string("a body's shape cannot change during a run; its mass, friction, restitution, "
                               "sleep, colour, place and velocities can");
        }
        return std::nullopt;
    };
    auto patch = [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
        Body& body = w.get<Body>(e);
        const Body &was = bw.get<Body>(b), &now = aw.get<Body>(a);
        body.retuned = body.retuned || was.mass != now.mass || was.friction != now.friction ||
                       was.restitution != now.restitution || was.canSleep != now.canSleep;
        takeChanged(body.mass, was.mass, now.mass);
        takeChanged(body.friction, was.friction, now.friction);
        takeChanged(body.restitution, was.restitution, now.restitution);
        takeChanged(body.canSleep, was.canSleep, now.canSleep);
        takeChanged(body.color, was.color, now.color);
        // place and motion (the transform, orientation or angle, velocities): the body jumps there
        bool moved = was.position != now.position || was.angularVelocity != now.angularVelocity;
        takeChanged(body.position, was.position, now.position);
        takeChanged(body.angularVelocity, was.angularVelocity, now.angularVelocity);
        if constexpr (std::is_same_v<Body, RigidBody>) {
            moved = moved || was.linearVelocity != now.linearVelocity || was.orientation != now.orientation;
            takeChanged(body.linearVelocity, was.linearVelocity, now.linearVelocity);
            takeChanged(body.orientation, was.orientation, now.orientation);
        } else {
            moved = moved || was.velocity != now.velocity || was.angle != now.angle;
            takeChanged(body.velocity, was.velocity, now.velocity);
            takeChanged(body.angle, was.angle, now.angle);
        }
        body.teleported = body.teleported || moved;
    };
    return Retune{{key}, [](const World& w, Entity e) { return w.has<Body>(e); }, check, patch};
}

} // namespace

void registerRigidSystem(Catalog& catalog) {
    catalog.addComponent({"rigid_body", loadRigidBody, {}, true});
    catalog.addComponent({"rigid_body_2d", loadRigidBody2D, {}, true});
    catalog.setJointLoader(loadJoint);
    catalog.addState<RigidBody>("rigid", dumpRigid, hashRigid);
    catalog.addState<RigidBody2D>("rigid2d", dumpRigid2D, hashRigid2D);
    catalog.addRetune(bodyRetune<RigidBody>("rigid_body"));
    catalog.addRetune(bodyRetune<RigidBody2D>("rigid_body_2d"));
    registerRigidEvents(catalog);
}

void syncRigidIn(World& world, const StepContext& ctx) {
    {
        ProfileStage stage(ctx.profiler, "rigid_in.bullet");
        bulletSyncIn(world, ctx);
    }
    ProfileStage stage(ctx.profiler, "rigid_in.box2d");
    box2dSyncIn(world, ctx);
}

void syncRigidOut(World& world, const StepContext& ctx) {
    {
        ProfileStage stage(ctx.profiler, "rigid_out.bullet");
        bulletSyncOut(world, ctx);
    }
    ProfileStage stage(ctx.profiler, "rigid_out.box2d");
    box2dSyncOut(world, ctx);
}

} // namespace tumble
