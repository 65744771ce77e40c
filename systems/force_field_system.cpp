#include "systems/force_field_system.h"

#include "components/name.h"
#include "components/transform.h"
#include "engine/random.h"
#include "engine/scene.h"

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

bool within(const ForceField& f, const Vec3& d) {
    return f.radius <= 0.0 || dot(d, d) <= f.radius * f.radius;
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
        f.strength = {r.number("strength", 1.0, -1e6, 1e6), 0.0, 0.0};
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

Vec3 fieldForce(const ForceField& f, const Vec3& x, const Vec3& v, double mass) {
    switch (f.kind) {
    case FieldKind::Wind:
        return (f.current - v) * f.coefficient;
    case FieldKind::Drag:
        return v * -f.strength.x;
    case FieldKind::Vortex: {
        const Vec3 d = x - f.origin;
        const Vec3 radial = d - f.axis * dot(d, f.axis);
        if (!within(f, radial)) {
            return {};
        }
        // the pull towards the axis that keeps a body turning at omega on its circle, plus the air's drag
        // towards turning at omega (coefficient 0: a pure central force, which conserves the radius)
        const double omega = f.strength.x;
        const Vec3 air = cross(f.axis, radial) * omega;
        return radial * (-omega * omega * mass) + (air - v) * f.coefficient;
    }
    case FieldKind::Point: {
        const Vec3 d = f.origin - x;
        if (!within(f, d)) {
            return {};
        }
        const double r2 = dot(d, d) + 0.01; // softened within 0.1 m
        return d * (f.strength.x * mass / (r2 * std::sqrt(r2)));
    }
    }
    return {};
}

double fieldDamping(const ForceField& f, const Vec3& x) {
    switch (f.kind) {
    case FieldKind::Wind:
        return f.coefficient;
    case FieldKind::Drag:
        return f.strength.x;
    case FieldKind::Vortex: {
        const Vec3 d = x - f.origin;
        return within(f, d - f.axis * dot(d, f.axis)) ? f.coefficient : 0.0;
    }
    case FieldKind::Point:
        return 0.0;
    }
    return 0.0;
}

void registerForceFieldSystem(Catalog& catalog) {
    catalog.addComponent({"force_field", loadForceField});
    catalog.addSystem(Phase::Fixed, "force_fields", updateForceFields);
}

} // namespace tumble
