// Force fields: what each kind does to a point mass, and gusts that follow the scene seed.

#include "components/force_field.h"
#include "components/spring_network.h"
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

TEST(ForceField, PointAttractorPullsWithInverseSquare) {
    ForceField point;
    point.kind = FieldKind::Point;
    point.strength = {10.0, 0.0, 0.0};
    point.origin = {0.0, 0.0, 0.0};
    const Vec3 near = fieldForce(point, {2.0, 0.0, 0.0}, {}, 1.0);
    const Vec3 far = fieldForce(point, {4.0, 0.0, 0.0}, {}, 1.0);
    EXPECT_LT(near.x, 0.0) << "towards the origin";
    EXPECT_NEAR(near.x / far.x, 4.0, 0.02) << "inverse square (softened within 0.1 m)";
    EXPECT_NEAR(fieldForce(point, {2.0, 0.0, 0.0}, {}, 3.0).x, 3.0 * near.x, 1e-12) << "per kilogram";
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
