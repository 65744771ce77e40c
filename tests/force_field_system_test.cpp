// Force fields: what each kind does to a point mass (the attractor against its formula, and its energy kept
// along a fall), and gusts that follow the scene seed.

#include "components/force_field.h"
#include "components/spring_network.h"
#include "engine/random.h"
#include "systems/field_forces.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tumble {
namespace {

using test::makeSimulation;

TEST(ForceField, WindPushesTowardsTheAirSpeedAndDragOpposesMotion) {
    ForceField wind;
    wind.kind = FieldKind::Wind;
    wind.current = {3.0, 0.0, 0.0};
    wind.coefficient = 0.5;
    EXPECT_EQ(fieldForce(wind, {}, {1.0, 0.0, 0.0}, 2.0), (Vec3{1.0, 0.0, 0.0})) << "0.5 (3 - 1)";
    EXPECT_EQ(fieldForce(wind, {}, {3.0, 0.0, 0.0}, 2.0), (Vec3{})) << "no force moving with the air";
    ForceField drag;
    drag.kind = FieldKind::Drag;
    drag.strength = {0.2, 0.0, 0.0};
    EXPECT_EQ(fieldForce(drag, {}, {0.0, -5.0, 0.0}, 1.0), (Vec3{0.0, 1.0, 0.0}));
    EXPECT_EQ(fieldDamping(drag, {}), 0.2);
}

TEST(ForceField, VortexTurnsAboutItsAxisWithinItsRadius) {
    ForceField vortex;
    vortex.kind = FieldKind::Vortex;
    vortex.strength = {2.0, 0.0, 0.0}; // rad/s
    vortex.axis = {0.0, 1.0, 0.0};
    vortex.radius = 3.0;
    vortex.coefficient = 1.0;
    // at (1, 5, 0): the pull -m omega^2 r = (-4, 0, 0) for 1 kg, and the air moving along
    // axis x r = (0, 1, 0) x (1, 0, 0) = (0, 0, -1) at 2 m/s drags a body at rest towards it
    const Vec3 f = fieldForce(vortex, {1.0, 5.0, 0.0}, {}, 1.0);
    EXPECT_NEAR(f.x, -4.0, 1e-15);
    EXPECT_NEAR(f.y, 0.0, 1e-15);
    EXPECT_NEAR(f.z, -2.0, 1e-15);
    // moving with the air at 2 m/s, only the central pull remains
    const Vec3 g = fieldForce(vortex, {1.0, 5.0, 0.0}, {0.0, 0.0, -2.0}, 1.0);
    EXPECT_NEAR(g.z, 0.0, 1e-15);
    EXPECT_NEAR(g.x, -4.0, 1e-15);
    EXPECT_EQ(fieldForce(vortex, {4.0, 0.0, 0.0}, {}, 1.0), (Vec3{})) << "outside the radius";
}

TEST(ForceField, PointAttractorPullsWithItsFormula) {
    // strength.x m / d^2 towards the origin, softened within 0.1 m (Plummer: F = s m d / (|d|^2 +
    // 0.1^2)^(3/2)), nothing beyond `radius`: at random points from 1 cm to 10 m in every direction
    ForceField point;
    point.kind = FieldKind::Point;
    point.strength = {10.0, 0.0, 0.0};
    point.origin = {0.3, -0.2, 1.0};
    point.radius = 8.0;
    Rng rng(4);
    for (int trial = 0; trial < 1000; ++trial) {
        Vec3 dir{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
        dir = dir * (1.0 / length(dir));
        const double r = std::pow(10.0, rng.uniform(-2.0, 1.0)), m = rng.uniform(0.1, 5.0);
        const Vec3 x = point.origin + dir * r;
        const Vec3 f = fieldForce(point, x, {rng.uniform(-1, 1), 0.0, 0.0}, m);
        const Vec3 expected = r > 8.0 ? Vec3{} : dir * (-10.0 * m * r / std::pow(r * r + 0.01, 1.5));
        ASSERT_NEAR(length(f - expected), 0.0, 1e-12 * std::max(1.0, length(expected))) << "r = " << r;
    }
}

TEST(ForceField, GustsVaryTheWindAndFollowTheSeed) {
    const std::string scene = R"(
[scene]
name = "gusts"
[[entity]]
name = "wind"
[entity.force_field]
kind = "wind"
strength = [4.0, 0.0, 0.0]
gust = 0.5
)";
    auto run = [&](const std::string& seed) {
        auto sim = makeSimulation(scene, {"scene.seed=" + seed});
        std::vector<double> speeds;
        for (int i = 0; i < 300; ++i) {
            sim->runFrame();
            sim->world().view<const ForceField>().each(
                [&](Entity, const ForceField& f) { speeds.push_back(f.current.x); });
        }
        return speeds;
    };
    const auto a = run("1"), b = run("1"), c = run("2");
    EXPECT_EQ(a, b) << "the same seed, the same gusts";
    EXPECT_NE(a, c) << "another seed, other gusts";
    double lo = 1e9, hi = -1e9;
    for (double s : a) {
        lo = std::min(lo, s);
        hi = std::max(hi, s);
        ASSERT_GE(s, 4.0 * 0.5 - 1e-12);
        ASSERT_LE(s, 4.0 * 1.5 + 1e-12);
    }
    EXPECT_GT(hi - lo, 1.0) << "gusts of +-50% move the wind speed noticeably over 5 s";
}

TEST(ForceField, AFallIntoAPointAttractorKeepsItsEnergy) {
    // from rest at 2 m towards an attractor of strength 5 (RK4, 1/600 s steps) down to 0.5 m: kinetic plus
    // potential energy, U = -s m / sqrt(r^2 + 0.1^2) (the softened potential of the force), stays what it
    // was within 1e-7 of the potential's depth there (a force of the wrong power of r would not)
    auto sim = makeSimulation(R"(
[scene]
name = "fall"
gravity = [0, 0, 0]
dt = 0.0016666666666666668
[[entity]]
name = "sun"
[entity.force_field]
kind = "point"
strength = 5.0
[[entity]]
name = "pebble"
[entity.springs]
integrator = "rk4"
masses = [ { x = [2, 0, 0], m = 0.7 } ]
)");
    auto energy = [](const SpringNetwork& n) {
        const double r = length(n.x[0]);
        return 0.5 * 0.7 * dot(n.v[0], n.v[0]) - 5.0 * 0.7 / std::sqrt(r * r + 0.01);
    };
    const SpringNetwork* net = nullptr;
    sim->world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& n) { net = &n; });
    const double start = energy(*net);
    int steps = 0;
    while (length(net->x[0]) > 0.5 && steps < 10000) {
        sim->runFrame();
        ++steps;
        ASSERT_NEAR(energy(*net), start, 1e-7 * 5.0 * 0.7 / 0.5) << "step " << steps;
    }
    EXPECT_LT(steps, 10000) << "it fell";
    EXPECT_GT(-net->v[0].x, 3.0) << "and gathered speed";
}

TEST(ForceField, AMassFallsIntoAPointAttractor) {
    auto sim = makeSimulation(R"(
[scene]
name = "orbit"
gravity = [0, 0, 0]
[[entity]]
name = "sun"
[entity.force_field]
kind = "point"
strength = 5.0
[[entity]]
name = "pebble"
[entity.springs]
integrator = "rk4"
masses = [ { x = [2, 0, 0] } ]
)");
    for (int i = 0; i < 30; ++i) {
        sim->runFrame();
    }
    const SpringNetwork* net = nullptr;
    sim->world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& n) { net = &n; });
    EXPECT_LT(net->x[0].x, 2.0);
    EXPECT_LT(net->v[0].x, 0.0) << "moving towards the attractor";
    EXPECT_NEAR(net->x[0].y, 0.0, 1e-12);
}

} // namespace
} // namespace tumble
