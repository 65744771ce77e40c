#include "systems/grab_system.h"

#include "components/grab.h"
#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/transform.h"

#include <cmath>
#include <optional>
#include <string>

namespace tumble {

namespace {

/// What a network loaded explicit may take to switch to implicit Euler without a charge at load.
constexpr double kMaxUnchargedBytes = 64.0 * 1024 * 1024;

bool isNetwork(const World& w, Entity e) {
    return w.has<SpringNetwork>(e);
}
bool isBody(const World& w, Entity e) {
    return w.has<RigidBody>(e);
}
bool isBody2D(const World& w, Entity e) {
    return w.has<RigidBody2D>(e);
}
bool isEmitter(const World& w, Entity e) {
    return w.has<ParticleEmitter>(e);
}
bool isGrabbable(const World& w, Entity e) {
    return isNetwork(w, e) || isBody(w, e) || isBody2D(w, e) || isEmitter(w, e);
}

Vec3 targetOf(const EventDef& ev) {
    return {ev.position[0], ev.position[1], ev.position[2]};
}

/// An emitter follows its entity's transform: both move.
void moveEmitter(World& world, Entity e, const Vec3& to) {
    world.get<ParticleEmitter>(e).origin = to;
    if (Transform* t = world.tryGet<Transform>(e)) {
        t->position = to;
    }
}

/// Holds the entity (or moves the hold) with the event's value as the held point.
void hold(World& world, Entity e, const EventDef& ev) {
    Grab grab;
    grab.target = targetOf(ev);
    if (const SpringNetwork* net = world.tryGet<SpringNetwork>(e)) {
        grab.mass = static_cast<std::uint32_t>(ev.value[0]);
        for (std::size_t j = 0; j < net->invMass.size(); ++j) {
            grab.heldMass += net->pinned[j] ? 0.0 : 1.0 / net->invMass[j];
        }
    } else if (isBody(world, e)) {
        grab.local = {ev.value[0], ev.value[1], ev.value[2]};
    } else if (isBody2D(world, e)) {
        grab.local = {ev.value[0], ev.value[1], 0.0};
    } else if (isEmitter(world, e)) {
        moveEmitter(world, e, grab.target);
    }
    // added at once, not through commands(): a drag at the same step, applied next, must find it (events
    // are applied outside any view, so the world is not locked)
    if (Grab* held = world.tryGet<Grab>(e)) {
        *held = grab;
    } else {
        world.emplace<Grab>(e, grab);
    }
}

std::optional<std::string> checkPoint(const EventDef& ev, std::size_t numbers, const char* what) {
    if (ev.value.size() != numbers) {
        return std::string("needs value = ") + what + " and position = [x, y, z], the target";
    }
    for (double d : ev.value) {
        if (!std::isfinite(d)) {
            return std::string("value must be finite numbers");
        }
    }
    return std::nullopt;
}

std::optional<std::string> anyValues(const World&, Entity, const EventDef&) {
    return std::nullopt;
}

void addGrab(Catalog& catalog, const char* needs, bool (*takes)(const World&, Entity),
             std::optional<std::string> (*check)(const World&, Entity, const EventDef&)) {
    catalog.addEventAction({"grab", needs, {"value", "position"}, takes, check, hold});
}

void registerGrabEvents(Catalog& catalog) {
    addGrab(catalog, "a spring network", isNetwork,
            [](const World& w, Entity e, const EventDef& ev) -> std::optional<std::string> {
                const std::size_t n = w.get<SpringNetwork>(e).x.size();
                if (ev.value.size() != 1 || ev.value[0] < 0 || ev.value[0] != std::floor(ev.value[0]) ||
                    ev.value[0] >= static_cast<double>(n)) {
                    return "needs value = i, a mass index in [0, " + std::to_string(n - 1) +
                           "], and position = [x, y, z], the target";
                }
                return std::nullopt;
            });
    addGrab(catalog, "a dynamic rigid body", isBody,
            [](const World& w, Entity e, const EventDef& ev) -> std::optional<std::string> {
                if (!w.get<RigidBody>(e).dynamic()) {
                    return std::string("the body is static (mass = 0) and cannot be held");
                }
                return checkPoint(ev, 3, "[x, y, z], the held point in the body's frame");
            });
    addGrab(catalog, "a dynamic 2D rigid body", isBody2D,
            [](const World& w, Entity e, const EventDef& ev) -> std::optional<std::string> {
                if (!w.get<RigidBody2D>(e).dynamic()) {
                    return std::string("the body is static (mass = 0) and cannot be held");
                }
                return checkPoint(ev, 2, "[x, y], the held point in the body's frame");
            });
    addGrab(catalog, "a particle emitter", isEmitter,
            [](const World&, Entity, const EventDef& ev) { return checkPoint(ev, 0, "nothing"); });

    const char* anything = "a spring network, a rigid body or a particle emitter";
    catalog.addEventAction(
        {"drag", anything, {"position"}, isGrabbable, anyValues, [](World& w, Entity e, const EventDef& ev) {
             // a drag without a hold (released already) moves nothing
             if (Grab* grab = w.tryGet<Grab>(e)) {
                 grab->target = targetOf(ev);
                 if (isEmitter(w, e)) {
                     moveEmitter(w, e, grab->target);
                 }
             }
         }});
    catalog.addEventAction(
        {"release", anything, {}, isGrabbable, anyValues, [](World& w, Entity e, const EventDef&) {
             if (w.has<Grab>(e)) {
                 w.remove<Grab>(e);
             }
         }});
    catalog.addEventAction(
        {"set_integrator",
         "a spring network",
         {"value"},
         isNetwork,
         [](const World& w, Entity e, const EventDef& ev) -> std::optional<std::string> {
             if (ev.value.size() != 1 || ev.value[0] < 0 || ev.value[0] > 4 ||
                 ev.value[0] != std::floor(ev.value[0])) {
                 return std::string(
                     "needs value = k: 0 explicit_euler, 1 midpoint, 2 rk4, 3 symplectic_euler, "
                     "4 implicit_euler");
             }
             // the memory cap is charged at load, by the integrator loaded: implicit Euler's solver costs
             // about 400 B a mass and 270 B a spring more, which a network loaded explicit may take only
             // while it is small
             const SpringNetwork& net = w.get<SpringNetwork>(e);
             if (net.kind == NetworkKind::Fem && ev.value[0] != 3 && ev.value[0] != 4) {
                 return std::string("an fem body is advanced by 3 symplectic_euler or 4 implicit_euler");
             }
             const double extra = double(net.x.size()) * 400.0 + double(net.links.size()) * 270.0;
             if (ev.value[0] == 4 && !net.implicitCharged && extra > kMaxUnchargedBytes) {
                 return "switching to implicit_euler would take about " +
                        std::to_string(int(extra / 1048576.0)) +
                        " MiB that the load did not charge; load the network with integrator = "
                        "\"implicit_euler\" instead";
             }
             return std::nullopt;
         },
         [](World& w, Entity e, const EventDef& ev) {
             w.get<SpringNetwork>(e).integrator = static_cast<Integrator>(static_cast<int>(ev.value[0]));
         }});
}

/// Backward Euler of the mouse spring on one mass of a network.
void pullMass(SpringNetwork& net, const Grab& grab, double omega, double dt) {
    const std::size_t i = grab.mass;
    if (net.frozen || i >= net.x.size() || net.pinned[i]) {
        return;
    }
    const double k = grab.heldMass * omega * omega, c = 2.0 * grab.heldMass * omega;
    // m (v' - v) = dt (k (target - x - dt v') - c v')
    const double a = dt * net.invMass[i];
    net.v[i] = (net.v[i] + (grab.target - net.x[i]) * (a * k)) * (1.0 / (1.0 + a * c + a * dt * k));
}

} // namespace

void pullGrabs(World& world, const StepContext& ctx) {
    const double dt = ctx.dt;
    // a body held away from its centre answers as a lighter one (down to a quarter of its mass for a point
    // on a box's surface): the explicit force stays stable while 4 omega dt <= 1, so long steps get a softer
    // spring
    const double omega = std::min(kGrabOmega, 0.25 / dt);
    const double k = omega * omega, c = omega;
    world.view<const Grab>().each([&](Entity e, const Grab& grab) {
        if (SpringNetwork* net = world.tryGet<SpringNetwork>(e)) {
            pullMass(*net, grab, omega, dt);
        } else if (RigidBody* b = world.tryGet<RigidBody>(e); b && b->dynamic() && !b->frozen) {
            const Vec3 p = b->toWorld(grab.local);
            const Vec3 f = (grab.target - p) * (b->mass * k) - b->velocityAt(p) * (b->mass * c);
            b->impulse += f * dt;
            b->angularImpulse += cross(p - b->position, f * dt);
        } else if (RigidBody2D* b2 = world.tryGet<RigidBody2D>(e); b2 && b2->dynamic()) {
            const double cs = std::cos(b2->angle), sn = std::sin(b2->angle);
            const double rx = cs * grab.local.x - sn * grab.local.y,
                         ry = sn * grab.local.x + cs * grab.local.y;
            const double vx = b2->velocity[0] - b2->angularVelocity * ry,
                         vy = b2->velocity[1] + b2->angularVelocity * rx;
            const double fx = (grab.target.x - b2->position[0] - rx) * b2->mass * k - vx * b2->mass * c;
            const double fy = (grab.target.y - b2->position[1] - ry) * b2->mass * k - vy * b2->mass * c;
            b2->impulse[0] += fx * dt;
            b2->impulse[1] += fy * dt;
            b2->angularImpulse += (rx * fy - ry * fx) * dt;
        }
    });
}

void registerGrabSystem(Catalog& catalog) {
    registerGrabEvents(catalog);
}

} // namespace tumble
