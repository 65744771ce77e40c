#include "systems/force_field_system.h"

#include "engine/name.h"
#include "engine/random.h"
#include "engine/retune.h"
#include "engine/scene.h"
#include "engine/transform.h"

#include <cmath>
#include <numbers>

namespace tumble {

namespace {

constexpr double kHuge = 1e9;
// gust frequencies, Hz: incommensurate, so the pattern does not visibly repeat
constexpr double kGustHz[3] = {0.23, 0.59, 1.37};

/// Smooth gust factor in [-1, 1] at time t.
double gustAt(const ForceField& f, double t) {
    double g = 0.0;
    for (std::size_t i = 0; i < 3; ++i) {
        g += std::sin(2.0 * std::numbers::pi * kGustHz[i] * t + f.gustPhase[i]);
    }
    return g / 3.0;
}

void loadForceField(TableReader& r, World& world, Entity entity, const SceneDef& scene) {
    ForceField f;
    const std::string kind = r.choice("kind", "wind", {"wind", "drag", "vortex", "point"});
    f.origin = world.get<Transform>(entity).position;
    if (kind == "wind") {
        f.kind = FieldKind::Wind;
        const auto s = r.vector<3>("strength", {1.0, 0.0, 0.0}, -1e4, 1e4);
        f.strength = {s[0], s[1], s[2]};
        f.gust = r.number("gust", 0.0, 0.0, 1.0);
    } else {
        f.kind = kind == "drag" ? FieldKind::Drag : kind == "vortex" ? FieldKind::Vortex : FieldKind::Point;
        // drag only takes energy away; a vortex turns either way; a negative point field repels
        f.strength = {r.number("strength", 1.0, f.kind == FieldKind::Drag ? 0.0 : -1e6, 1e6), 0.0, 0.0};
    }
    f.coefficient = r.number("coefficient", 1.0, 0.0, 1e6);
    if (f.kind == FieldKind::Vortex) {
        const auto a = r.vector<3>("axis", {0.0, 1.0, 0.0}, -kHuge, kHuge);
        const Vec3 axis{a[0], a[1], a[2]};
        if (length(axis) < 1e-12) {
            r.fail("axis", "'axis' of a vortex must not be zero");
        }
        f.axis = axis * (1.0 / length(axis));
    }
    if (f.kind == FieldKind::Vortex || f.kind == FieldKind::Point) {
        f.radius = r.number("radius", 0.0, 0.0, kHuge);
    }
    // gust phases from a stream of this field's own
    Rng rng(streamSeed(scene.seed, "gust:" + world.get<Name>(entity).value));
    for (double& phase : f.gustPhase) {
        phase = rng.uniform(0.0, 2.0 * std::numbers::pi);
    }
    f.current = f.strength;
    world.emplace<ForceField>(entity, f);
}

} // namespace

void updateForceFields(World& world, const StepContext& ctx) {
    world.view<ForceField, const Transform>().each([&](Entity, ForceField& f, const Transform& t) {
        f.origin = t.position;
        f.current =
            f.kind == FieldKind::Wind ? f.strength * (1.0 + f.gust * gustAt(f, ctx.time)) : f.strength;
    });
}

void registerForceFieldSystem(Catalog& catalog) {
    catalog.addComponent({"force_field", loadForceField});
    // a `set` event on a field's keys (engine/retune.h): any of its settings
    catalog.addRetune(Retune{
        {"force_field"},
        [](const World& w, Entity e) { return w.has<ForceField>(e); },
        [](const World&, Entity, const World&, Entity) -> std::optional<std::string> { return std::nullopt; },
        [](World& w, Entity e, const World& bw, Entity b, const World& aw, Entity a) {
            ForceField& f = w.get<ForceField>(e);
            const ForceField &was = bw.get<ForceField>(b), &now = aw.get<ForceField>(a);
            takeChanged(f.kind, was.kind, now.kind);
            takeChanged(f.strength, was.strength, now.strength);
            takeChanged(f.gust, was.gust, now.gust);
            takeChanged(f.coefficient, was.coefficient, now.coefficient);
            takeChanged(f.axis, was.axis, now.axis);
            takeChanged(f.radius, was.radius, now.radius);
        }});
}

} // namespace tumble
