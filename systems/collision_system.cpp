#include "systems/collision_system.h"

#include "components/particles.h"
#include "components/spring_network.h"
#include "components/transform.h"
#include "engine/scene.h"

#include <algorithm>
#include <cmath>

namespace tumble {

namespace {

constexpr double kHuge = 1e9;
// projections per step: a point wedged between two bodies converges towards their corner by the square of
// the cosine of the wedge angle each pass; eight passes bring a 60 degree wedge within 1e-6 of it
constexpr int kContactPasses = 8;

/// Distance and normal of a point relative to an axis-aligned box of half extents h centred at 0.
double boxDistance(const Vec3& d, const Vec3& h, Vec3& normal) {
    const double q[3] = {std::abs(d.x) - h.x, std::abs(d.y) - h.y, std::abs(d.z) - h.z};
    const double sign[3] = {d.x < 0 ? -1.0 : 1.0, d.y < 0 ? -1.0 : 1.0, d.z < 0 ? -1.0 : 1.0};
    const Vec3 outside{std::max(q[0], 0.0) * sign[0], std::max(q[1], 0.0) * sign[1],
                       std::max(q[2], 0.0) * sign[2]};
    const double out = length(outside);
    if (out > 0.0) {
        normal = outside * (1.0 / out);
        return out;
    }
    // inside: out through the nearest face
    const int axis = q[0] >= q[1] && q[0] >= q[2] ? 0 : q[1] >= q[2] ? 1 : 2;
    normal = Vec3{axis == 0 ? sign[0] : 0.0, axis == 1 ? sign[1] : 0.0, axis == 2 ? sign[2] : 0.0};
    return q[axis];
}

void loadRigidBody(TableReader& r, World& world, Entity entity, const SceneDef&) {
    RigidBody b;
    const std::string shape =
        r.choice("shape", "box", {"plane", "box", "sphere", "capsule", "cylinder", "convex", "mesh"});
    if (shape == "convex" || shape == "mesh") {
        r.fail("shape", "shape '" + shape + "' needs the rigid-body bridge, which is not in this build yet");
    }
    b.shape = shape == "plane"     ? ShapeKind::Plane
              : shape == "box"     ? ShapeKind::Box
              : shape == "sphere"  ? ShapeKind::Sphere
              : shape == "capsule" ? ShapeKind::Capsule
                                   : ShapeKind::Cylinder;
    if (b.shape == ShapeKind::Plane) {
        const auto n = r.vector<3>("normal", {0.0, 1.0, 0.0}, -kHuge, kHuge);
        const Vec3 normal{n[0], n[1], n[2]};
        if (length(normal) < 1e-12) {
            r.fail("normal", "'normal' of a plane must not be zero");
        }
        b.normal = normal * (1.0 / length(normal));
    }
    if (b.shape == ShapeKind::Box) {
        const auto h = r.vector<3>("half_extents", {0.5, 0.5, 0.5}, 1e-6, kHuge);
        b.halfExtents = {h[0], h[1], h[2]};
    }
    if (b.shape == ShapeKind::Sphere || b.shape == ShapeKind::Capsule || b.shape == ShapeKind::Cylinder) {
        b.radius = r.number("radius", 0.5, 1e-6, kHuge);
    }
    if (b.shape == ShapeKind::Capsule || b.shape == ShapeKind::Cylinder) {
        b.height = r.number("height", 1.0, 0.0, kHuge);
    }
    b.mass = r.number("mass", 0.0, 0.0, 1e9);
    if (b.mass > 0.0) {
        r.fail("mass",
               "dynamic rigid bodies (mass > 0) need the Bullet bridge, which is not in this build yet; "
               "mass = 0 makes a static collider");
    }
    b.friction = r.number("friction", 0.6, 0.0, 100.0);
    b.restitution = r.number("restitution", 0.0, 0.0, 1.0);
    const bool plane = b.shape == ShapeKind::Plane;
    const auto color =
        r.vector<3>("color", plane ? std::array{0.55, 0.57, 0.52} : std::array{0.62, 0.60, 0.56}, 0.0, 1.0);
    b.color = {color[0], color[1], color[2]};
    b.position = world.get<Transform>(entity).position;
    world.emplace<RigidBody>(entity, b);
}

} // namespace

double signedDistance(const RigidBody& body, const Vec3& p, Vec3& normal) {
    const Vec3 d = p - body.position;
    switch (body.shape) {
    case ShapeKind::Plane:
        normal = body.normal;
        return dot(d, body.normal);
    case ShapeKind::Sphere: {
        const double len = length(d);
        normal = len > 1e-12 ? d * (1.0 / len) : Vec3{0.0, 1.0, 0.0};
        return len - body.radius;
    }
    case ShapeKind::Box:
        return boxDistance(d, body.halfExtents, normal);
    case ShapeKind::Capsule: {
        // closest point on the axis segment, then a sphere about it
        const double half = 0.5 * body.height;
        const Vec3 axisPoint{0.0, std::clamp(d.y, -half, half), 0.0};
        const Vec3 e = d - axisPoint;
        const double len = length(e);
        normal = len > 1e-12 ? e * (1.0 / len) : Vec3{1.0, 0.0, 0.0};
        return len - body.radius;
    }
    case ShapeKind::Cylinder: {
        // a rectangle in (radial, y): outside, the distance to its nearest point; inside, to the nearer of
        // the curved side and the flat end
        const double radial = std::sqrt(d.x * d.x + d.z * d.z);
        const Vec3 outward = radial > 1e-12 ? Vec3{d.x / radial, 0.0, d.z / radial} : Vec3{1.0, 0.0, 0.0};
        const Vec3 upward{0.0, d.y < 0.0 ? -1.0 : 1.0, 0.0};
        const double side = radial - body.radius, end = std::abs(d.y) - 0.5 * body.height;
        if (side > 0.0 || end > 0.0) {
            const double a = std::max(side, 0.0), b = std::max(end, 0.0);
            const double dist = std::sqrt(a * a + b * b);
            normal = (outward * a + upward * b) * (1.0 / dist);
            return dist;
        }
        normal = side > end ? outward : upward;
        return std::max(side, end);
    }
    }
    return 1e300;
}

void collideSprings(World& world, const StepContext&) {
    const Pool<RigidBody>* bodies = world.findPool<RigidBody>();
    if (!bodies || bodies->size() == 0) {
        return;
    }
    world.view<SpringNetwork>().each([&](Entity, SpringNetwork& net) {
        if (net.frozen) {
            return;
        }
        for (std::size_t i = 0; i < net.x.size(); ++i) {
            if (net.pinned[i]) {
                continue;
            }
            // a few passes, so that a mass wedged between two bodies ends up outside both
            for (int pass = 0; pass < kContactPasses; ++pass) {
                bool moved = false;
                for (const RigidBody& body : bodies->values()) {
                    Vec3 n;
                    const double d = body.mass > 0.0 ? 1e300 : signedDistance(body, net.x[i], n);
                    if (d >= net.thickness) {
                        continue;
                    }
                    moved = true;
                    net.x[i] += n * (net.thickness - d);
                    const double vn = dot(net.v[i], n);
                    if (vn >= 0.0) {
                        continue; // already leaving the surface
                    }
                    // the velocity into the surface stops (or bounces by restitution); sliding loses to
                    // friction
                    const double mu = std::sqrt(body.friction * net.friction); // combined as Bullet does
                    Vec3 vt = net.v[i] - n * vn;
                    const double speed = length(vt);
                    const double slowdown = mu * -vn;
                    vt = speed <= slowdown ? Vec3{} : vt * (1.0 - slowdown / speed);
                    net.v[i] = vt - n * (vn * body.restitution);
                }
                if (!moved) {
                    break;
                }
            }
        }
    });
}

void collideParticles(World& world, const StepContext&) {
    const Pool<RigidBody>* bodies = world.findPool<RigidBody>();
    if (!bodies || bodies->size() == 0) {
        return;
    }
    world.view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) {
        if (!e.def.collide) {
            return;
        }
        ParticlePool& p = e.pool;
        for (std::uint32_t i = 0; i < p.count; ++i) {
            Vec3 x{p.px[i], p.py[i], p.pz[i]};
            Vec3 v{p.vx[i], p.vy[i], p.vz[i]};
            // a few passes, so that a particle wedged between two bodies ends up outside both
            bool touched = false;
            for (int pass = 0; pass < kContactPasses; ++pass) {
                bool moved = false;
                for (const RigidBody& body : bodies->values()) {
                    Vec3 n;
                    const double d = body.mass > 0.0 ? 1.0 : signedDistance(body, x, n);
                    if (d >= 0.0) {
                        continue;
                    }
                    moved = touched = true;
                    x -= n * d;
                    // the normal speed reversed by restitution, the sliding slowed by friction
                    const double vn = dot(v, n);
                    if (vn < 0.0) {
                        const double mu = std::sqrt(body.friction * e.def.friction);
                        const double bounce =
                            std::max(body.restitution, e.def.restitution); // as Box2D mixes it
                        Vec3 vt = v - n * vn;
                        const double speed = length(vt);
                        const double slowdown = mu * -vn * (1.0 + bounce);
                        vt = speed <= slowdown ? Vec3{} : vt * (1.0 - slowdown / speed);
                        v = vt - n * (vn * bounce);
                    }
                }
                if (!moved) {
                    break;
                }
            }
            if (!touched) {
                continue;
            }
            // stored in float, the point may round a hair inside a surface: nudge it out along the normals,
            // by steps that start near a float's resolution at that distance from the origin and double
            const double resolution = 1e-7 * std::max({1.0, std::abs(x.x), std::abs(x.y), std::abs(x.z)});
            for (int k = 0; k < 12; ++k) {
                bool inside = false;
                for (const RigidBody& body : bodies->values()) {
                    Vec3 n;
                    const Vec3 stored{float(x.x), float(x.y), float(x.z)};
                    if (body.mass == 0.0 && signedDistance(body, stored, n) < 0.0) {
                        x += n * (resolution * double(2 << k));
                        inside = true;
                    }
                }
                if (!inside) {
                    break;
                }
            }
            p.px[i] = float(x.x);
            p.py[i] = float(x.y);
            p.pz[i] = float(x.z);
            p.vx[i] = float(v.x);
            p.vy[i] = float(v.y);
            p.vz[i] = float(v.z);
        }
    });
}

void registerCollisionSystem(Catalog& catalog) {
    catalog.addComponent({"rigid_body", loadRigidBody});
    catalog.addSystem(Phase::Fixed, "collisions", [](World& world, const StepContext& ctx) {
        collideSprings(world, ctx);
        collideParticles(world, ctx);
    });
}

} // namespace tumble
