#include "systems/spring_system.h"

#include "components/transform.h"
#include "engine/scene.h"

#include <cmath>
#include <string>

namespace tumble {

namespace {

constexpr double kHugeCoordinate = 1e9; // m
constexpr std::size_t kMaxMasses = 1u << 20;

/// Gravity, springs and drag on every mass, into net.force.
void accumulateForces(SpringNetwork& net, const Vec3& gravity) {
    const std::size_t n = net.x.size();
    net.force.assign(n, Vec3{});
    for (std::size_t i = 0; i < n; ++i) {
        if (!net.pinned[i]) {
            net.force[i] = gravity * (1.0 / net.invMass[i]) - net.v[i] * net.drag;
        }
    }
    for (const SpringLink& s : net.links) {
        const Vec3 d = net.x[s.b] - net.x[s.a];
        const double len = length(d);
        if (len <= 1e-12) {
            continue; // coincident masses: no direction to push along
        }
        const Vec3 dir = d * (1.0 / len);
        const double stretch = len - s.rest;
        const double closing = dot(net.v[s.b] - net.v[s.a], dir);
        const Vec3 f = dir * (s.k * stretch + s.kd * closing); // on a, towards b when stretched
        net.force[s.a] += f;
        net.force[s.b] -= f;
    }
}

void stepSymplecticEuler(SpringNetwork& net, const Vec3& gravity, double dt) {
    accumulateForces(net, gravity);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        if (net.pinned[i]) {
            continue;
        }
        net.v[i] += net.force[i] * (dt * net.invMass[i]);
        net.x[i] += net.v[i] * dt;
    }
}

Integrator parseIntegrator(TableReader& r) {
    const std::string name =
        r.choice("integrator", "symplectic_euler",
                 {"explicit_euler", "midpoint", "rk4", "symplectic_euler", "implicit_euler"});
    if (name != "symplectic_euler") {
        r.fail("integrator", "integrator '" + name +
                                 "' is part of the scenario format but not implemented in this build yet; "
                                 "use symplectic_euler");
    }
    return Integrator::SymplecticEuler;
}

Vec3 readVec3(TableReader& r, const toml::node& n, std::string_view key) {
    double v[3];
    r.readNumbers(n, key, v, 3, -kHugeCoordinate, kHugeCoordinate);
    return {v[0], v[1], v[2]};
}

/// [entity.springs]: masses and links given explicitly (CONTRACT.md).
void loadSprings(TableReader& r, World& world, Entity entity, const SceneDef&) {
    SpringNetwork net;
    net.integrator = parseIntegrator(r);
    const double stiffness = r.number("stiffness", 100.0, 0.0, 1e12);
    const double damping = r.number("damping", 0.0, 0.0, 1e9);
    net.drag = r.number("drag", 0.0, 0.0, 1e9);
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
    world.emplace<SpringNetwork>(entity, std::move(net));
}

void dumpSprings(const SpringNetwork& net, JsonWriter& w) {
    w.key("integrator").value("symplectic_euler");
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

void hashSprings(const SpringNetwork& net, Hasher& h) {
    h.add(net.x);
    h.add(net.v);
    h.add(net.invMass);
    h.add(net.pinned);
    h.add(net.links);
    h.add(net.drag);
    h.add(net.integrator);
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
            return "mass index " + std::to_string(d) + " is not a whole number in [0, " +
                   std::to_string(n - 1) + "]";
        }
    }
    return std::nullopt;
}

bool hasSprings(const World& w, Entity e) {
    return w.has<SpringNetwork>(e);
}

} // namespace

void integrateSprings(World& world, const StepContext& ctx) {
    const auto& g = world.resource<SceneDef>().gravity;
    const Vec3 gravity{g[0], g[1], g[2]};
    world.view<SpringNetwork>().each(
        [&](Entity, SpringNetwork& net) { stepSymplecticEuler(net, gravity, ctx.dt); });
}

void registerSpringSystem(Catalog& catalog) {
    catalog.addComponent({"springs", loadSprings});
    catalog.addState<SpringNetwork>("springs", dumpSprings, hashSprings);

    // impulse: a momentum change J shared by the free masses (each gets dv = J / their total mass)
    catalog.addEventAction({"impulse",
                            "a spring network",
                            {"value"},
                            hasSprings,
                            needsVector,
                            [](World& w, Entity e, const EventDef& ev) {
                                auto& net = w.get<SpringNetwork>(e);
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
                            }});
    catalog.addEventAction({"set_velocity",
                            "a spring network",
                            {"value"},
                            hasSprings,
                            needsVector,
                            [](World& w, Entity e, const EventDef& ev) {
                                auto& net = w.get<SpringNetwork>(e);
                                for (std::size_t i = 0; i < net.v.size(); ++i) {
                                    if (!net.pinned[i]) {
                                        net.v[i] = {ev.value[0], ev.value[1], ev.value[2]};
                                    }
                                }
                            }});
    catalog.addEventAction({"pin",
                            "a spring network",
                            {"value"},
                            hasSprings,
                            needsIndices,
                            [](World& w, Entity e, const EventDef& ev) {
                                auto& net = w.get<SpringNetwork>(e);
                                for (double d : ev.value) {
                                    const auto i = static_cast<std::size_t>(d);
                                    net.pinned[i] = 1;
                                    net.v[i] = {};
                                }
                            }});
    catalog.addEventAction({"unpin",
                            "a spring network",
                            {"value"},
                            hasSprings,
                            needsIndices,
                            [](World& w, Entity e, const EventDef& ev) {
                                auto& net = w.get<SpringNetwork>(e);
                                for (double d : ev.value) {
                                    net.pinned[static_cast<std::size_t>(d)] = 0;
                                }
                            }});
    catalog.addSystem(Phase::Fixed, "springs", integrateSprings);
}

} // namespace tumble
