// Rigid bodies through both bridges, tested against physics: free fall against y0 - g t^2 / 2, coming to
// rest on the floor at the right height, a pendulum on a point joint with the period of a physical
// pendulum, joints that hold their distances, the same bits twice, bodies and joints removed with their
// entities, and springs and particles meeting moving bodies.

#include "components/joint.h"
#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "systems/box2d_bridge.h"
#include "systems/bullet_bridge.h"
#include "systems/collision_system.h"
#include "systems/obj_mesh.h"
#include "tests/raw_engines.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>

namespace tumble {
namespace {

constexpr double kG = 9.81;

std::string scene(double dt, const std::string& rest) {
    char step[32];
    std::snprintf(step, sizeof step, "%.17g", dt);
    return std::string("[scene]\nname = \"t\"\ndt = ") + step + "\ngravity = [0, -9.81, 0]\n" + rest;
}

void runFrames(Simulation& sim, int frames) {
    for (int i = 0; i < frames; ++i) {
        sim.runFrame();
    }
}

/// Height and vertical speed of a body after `frames` steps of free fall from y0 = 10 at rest.
struct Fall {
    double y, vy;
};

Fall fall3D(double dt, int frames) {
    auto sim = test::makeSimulation(scene(dt, R"(
[[entity]]
name = "ball"
[entity.transform]
position = [0, 10, 0]
[entity.rigid_body]
shape = "sphere"
radius = 0.2
mass = 2.0
)"));
    runFrames(*sim, frames);
    const RigidBody& b = test::component<RigidBody>(*sim, "ball");
    return {b.position.y, b.linearVelocity.y};
}

Fall fall2D(double dt, int frames) {
    auto sim = test::makeSimulation(scene(dt, R"(
[[entity]]
name = "disc"
[entity.transform]
position = [0, 10, 0]
[entity.rigid_body_2d]
shape = "circle"
radius = 0.2
mass = 2.0
)"));
    runFrames(*sim, frames);
    const RigidBody2D& b = test::component<RigidBody2D>(*sim, "disc");
    return {b.position[1], b.velocity[1]};
}

TEST(RigidBodies, FreeFallFollowsTheParabolaInBothEngines) {
    // both engines take semi-implicit Euler steps: v is exact, y is below the parabola by g t dt / 2, an
    // error that halves with dt
    for (auto fall : {fall3D, fall2D}) {
        const double t = 1.0;
        const double tolerance = 1e-4; // both engines compute in float
        double previousError = 0.0;
        for (int k = 0; k < 3; ++k) {
            const int frames = 60 << k;
            const double dt = t / frames;
            const Fall f = fall(dt, frames);
            EXPECT_NEAR(f.vy, -kG * t, tolerance * 10);
            const double error = (10.0 - 0.5 * kG * t * t) - f.y;
            EXPECT_NEAR(error, 0.5 * kG * t * dt, tolerance * 10) << "dt " << dt;
            if (k > 0) {
                EXPECT_NEAR(previousError / error, 2.0, 0.01) << "first order in dt";
            }
            previousError = error;
        }
    }
}

TEST(RigidBodies, ABoxComesToRestOnTheFloorAtItsHalfHeight) {
    auto sim = test::makeSimulation(scene(1.0 / 60.0, R"(
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "crate"
[entity.transform]
position = [0, 3, 0]
[entity.rigid_body]
shape = "box"
half_extents = [0.4, 0.25, 0.3]
mass = 5.0
[[entity]]
name = "ground2d"
[entity.rigid_body_2d]
shape = "edge"
from = [-5, 0]
to = [5, 0]
[[entity]]
name = "crate2d"
[entity.transform]
position = [0, 3, 0]
[entity.rigid_body_2d]
shape = "box"
half_extents = [0.4, 0.25]
mass = 5.0
)"));
    runFrames(*sim, 300);
    const RigidBody& b = test::component<RigidBody>(*sim, "crate");
    EXPECT_NEAR(b.position.y, 0.25, 0.005);
    EXPECT_LT(length(b.linearVelocity), 1e-3);
    EXPECT_TRUE(b.sleeping) << "at rest for seconds, Bullet puts it to sleep";
    const RigidBody2D& b2 = test::component<RigidBody2D>(*sim, "crate2d");
    // Box2D keeps a skin of b2_polygonRadius (1 cm) round the box and round the edge, less its 5 mm slop
    EXPECT_NEAR(b2.position[1], 0.25 + 2 * 0.01 - 0.005, 0.002);
    EXPECT_LT(std::hypot(b2.velocity[0], b2.velocity[1]), 1e-3);
}

/// Times of upward zero crossings of x(t), linearly interpolated.
std::vector<double> crossings(const std::vector<double>& x, double dt) {
    std::vector<double> out;
    for (std::size_t i = 1; i < x.size(); ++i) {
        if (x[i - 1] < 0.0 && x[i] >= 0.0) {
            out.push_back((double(i) - 1.0 + x[i - 1] / (x[i - 1] - x[i])) * dt);
        }
    }
    return out;
}

TEST(RigidBodies, APendulumOnAPointJointSwingsWithThePhysicalPendulumsPeriod) {
    // a ball of radius r on a massless link of length L: T = 2 pi sqrt(I_pivot / (m g L)),
    // I_pivot = 2/5 m r^2 + m L^2 (a disc in 2D: 1/2 m r^2 + m L^2); amplitude 0.1 rad
    const double L = 1.0, r = 0.1, theta = 0.1, dt = 1.0 / 120.0;
    const std::string at =
        "[" + std::to_string(L * std::sin(theta)) + ", " + std::to_string(5.0 - L * std::cos(theta)) + ", 0]";
    for (bool twoD : {false, true}) {
        auto sim = test::makeSimulation(
            scene(dt, "[[entity]]\nname = \"bob\"\n[entity.transform]\nposition = " + at +
                          (twoD ? "\n[entity.rigid_body_2d]\nshape = \"circle\"\n"
                                : "\n[entity.rigid_body]\nshape = \"sphere\"\n") +
                          "radius = " + std::to_string(r) +
                          "\nmass = 1.0\nsleep = false\n"
                          "[[joint]]\ntype = \"point\"\na = \"bob\"\npivot = [0, 5, 0]\n"));
        std::vector<double> x;
        double worstStretch = 0.0;
        for (int i = 0; i < 8 * 120; ++i) {
            sim->runFrame();
            const Vec3 p = twoD ? Vec3{test::component<RigidBody2D>(*sim, "bob").position[0],
                                       test::component<RigidBody2D>(*sim, "bob").position[1], 0.0}
                                : test::component<RigidBody>(*sim, "bob").position;
            x.push_back(p.x);
            worstStretch = std::max(worstStretch, std::abs(length(p - Vec3{0, 5, 0}) - L));
        }
        const double inertia = (twoD ? 0.5 : 0.4) * r * r + L * L;
        const double expected = 2.0 * std::numbers::pi * std::sqrt(inertia / (kG * L));
        const std::vector<double> t = crossings(x, dt);
        ASSERT_GE(t.size(), 3u) << (twoD ? "Box2D" : "Bullet");
        const double measured = (t.back() - t.front()) / double(t.size() - 1);
        EXPECT_NEAR(measured, expected, 0.02 * expected) << (twoD ? "Box2D" : "Bullet");
        EXPECT_LT(worstStretch, 0.01 * L) << "the joint holds its distance";
    }
}

TEST(RigidBodies, ABallOnAPointJointSwingsForAMinuteWithSleepOn) {
    // a Bullet ball (20 cm across) on a 1 m point joint released at 5 degrees, at 60 steps a second, sleep
    // on as a user leaves it: its top speed, 0.27 m/s, is under Bullet's own sleep threshold (0.8 m/s),
    // which froze it at a turning point after 2 s. With the scene's thresholds it swings for the whole
    // minute, with the physical pendulum's period, corrected for the amplitude: T = 2 pi sqrt(I / (m g L)) (1
    // + t^2/16 + 11 t^4/3072), within 1%
    const double L = 1.0, r = 0.1, theta = 5.0 * std::numbers::pi / 180.0, dt = 1.0 / 60.0;
    const std::string at =
        "[" + std::to_string(L * std::sin(theta)) + ", " + std::to_string(5.0 - L * std::cos(theta)) + ", 0]";
    auto sim = test::makeSimulation(
        scene(dt, "[[entity]]\nname = \"bob\"\n[entity.transform]\nposition = " + at +
                      "\n[entity.rigid_body]\nshape = \"sphere\"\nradius = " + std::to_string(r) +
                      "\nmass = 1.0\n[[joint]]\ntype = \"point\"\na = \"bob\"\n"
                      "pivot = [0, 5, 0]\n"));
    std::vector<double> x;
    double lastSwing = 0.0;
    for (int i = 0; i < 60 * 60; ++i) {
        sim->runFrame();
        const RigidBody& b = test::component<RigidBody>(*sim, "bob");
        ASSERT_FALSE(b.sleeping) << "asleep after " << (i + 1) * dt << " s";
        x.push_back(b.position.x);
        if (i >= 59 * 60) {
            lastSwing = std::max(lastSwing, std::abs(b.position.x));
        }
    }
    // still swinging in the last second (Bullet's joint takes a little of the swing: 15% over the minute)
    EXPECT_GT(lastSwing, 0.7 * L * std::sin(theta)) << "still swinging in the last second";
    const double inertia = 0.4 * r * r + L * L;
    const double expected = 2.0 * std::numbers::pi * std::sqrt(inertia / (kG * L)) *
                            (1.0 + theta * theta / 16.0 + 11.0 * std::pow(theta, 4) / 3072.0);
    const std::vector<double> t = crossings(x, dt);
    ASSERT_GE(t.size(), 28u) << "30 periods of 2 s in the minute";
    const double measured = (t.back() - t.front()) / double(t.size() - 1);
    EXPECT_NEAR(measured, expected, 0.01 * expected);
}

TEST(RigidBodies, AStackOfAThousandBoxesFallsAsleep) {
    // 10 x 10 columns of 10 boxes at rest on a plane (their contacts jitter every box at up to 0.15 m/s
    // while none leaves its place by more than a few centimetres): every box is asleep within 5 s (Bullet
    // then skips them: the step's cost drops, the profile's `bullet` row shows it)
    auto sim = test::makeSimulation(raw::stackScene(10, 10));
    int asleepAt = -1;
    for (int i = 0; i < 300 && asleepAt < 0; ++i) {
        sim->runFrame();
        bool all = true;
        sim->world().view<const RigidBody>().each(
            [&](Entity, const RigidBody& b) { all = all && (!b.dynamic() || b.sleeping); });
        asleepAt = all ? i + 1 : -1;
    }
    EXPECT_GT(asleepAt, 0) << "not all asleep after 5 s";
}

TEST(RigidBodies, HingesHoldAChainTogether) {
    // five planks hinged end to end, the first to the world, left to fall and swing
    // Bullet corrects a joint's drift by a fraction of it each step (ERP 0.2), so a fast swing opens a
    // hinge by an amount that falls faster than dt: the peak gap here was 4.6 cm at 1/60 s, 1.5 cm at
    // 1/120 s, 0.5 cm at 1/240 s; more solver iterations did not change it. Chains want 120 Hz or more.
    const double hdt = 1.0 / 120.0;
    std::string text = scene(hdt, R"(
[[entity]]
name = "plank"
repeat = { count = 5, offset = [1.0, 0, 0] }
[entity.transform]
position = [0.5, 5, 0]
[entity.rigid_body]
shape = "box"
half_extents = [0.5, 0.05, 0.2]
mass = 1.0
[[joint]]
type = "hinge"
a = "plank_0"
pivot = [0, 5, 0]
axis = [0, 0, 1]
)");
    for (int i = 0; i < 4; ++i) {
        text += "[[joint]]\ntype = \"hinge\"\na = \"plank_" + std::to_string(i) + "\"\nb = \"plank_" +
                std::to_string(i + 1) + "\"\npivot = [" + std::to_string(i + 1) + ", 5, 0]\n";
    }
    auto sim = test::makeSimulation(text);
    double worst = 0.0;
    for (int f = 0; f < int(3.0 / hdt); ++f) {
        sim->runFrame();
        for (int i = 0; i < 4; ++i) {
            // the right end of plank i and the left end of plank i + 1 are the same hinge
            const RigidBody& a = test::component<RigidBody>(*sim, "plank_" + std::to_string(i));
            const RigidBody& b = test::component<RigidBody>(*sim, "plank_" + std::to_string(i + 1));
            worst = std::max(worst, length(a.toWorld({0.5, 0, 0}) - b.toWorld({-0.5, 0, 0})));
        }
    }
    EXPECT_LT(worst, 0.02);
    const RigidBody& last = test::component<RigidBody>(*sim, "plank_4");
    EXPECT_LT(last.position.y, 4.0) << "the chain swung down";
    EXPECT_NEAR(last.orientation.x, 0.0, 1e-6) << "hinges about z keep it in the xy plane";
}

/// A body of 1 kg hanging from the world on a spring joint (k = 100 N/m, rest 1 m), released from its rest
/// length: it oscillates about rest + m g / k with period 2 pi sqrt(m / k).
TEST(RigidBodies, ASpringJointOscillatesWithItsPeriodInBothEngines) {
    const double k = 100.0, m = 1.0, dt = 1.0 / 240.0;
    for (bool twoD : {false, true}) {
        auto sim = test::makeSimulation(
            scene(dt, std::string("[[entity]]\nname = \"bob\"\n[entity.transform]\n"
                                  "position = [0, 4, 0]\n") +
                          (twoD ? "[entity.rigid_body_2d]\nshape = \"circle\"\n"
                                : "[entity.rigid_body]\nshape = \"sphere\"\n") +
                          "radius = 0.1\nmass = 1.0\nsleep = false\n"
                          "[[joint]]\ntype = \"spring\"\na = \"bob\"\npivot_b = [0, 5, 0]\n"
                          "stiffness = 100.0\n"));
        std::vector<double> y;
        for (int i = 0; i < 4 * 240; ++i) {
            sim->runFrame();
            const double h = twoD ? test::component<RigidBody2D>(*sim, "bob").position[1]
                                  : test::component<RigidBody>(*sim, "bob").position.y;
            y.push_back(h - (4.0 - m * kG / k)); // about the equilibrium
        }
        const std::vector<double> t = crossings(y, dt);
        ASSERT_GE(t.size(), 3u) << (twoD ? "Box2D" : "Bullet");
        const double measured = (t.back() - t.front()) / double(t.size() - 1);
        const double expected = 2.0 * std::numbers::pi * std::sqrt(m / k);
        EXPECT_NEAR(measured, expected, 0.02 * expected) << (twoD ? "Box2D" : "Bullet");
        const auto [lo, hi] = std::minmax_element(y.begin(), y.end());
        EXPECT_NEAR(*hi, m * kG / k, 0.1 * m * kG / k) << "it turns back at its rest length";
        EXPECT_NEAR(*lo, -m * kG / k, 0.1 * m * kG / k) << "and as far below the equilibrium";
    }
}

TEST(RigidBodies, ASliderKeepsItsBodyOnItsAxisAndAWeldKeepsTheirPoses) {
    for (bool twoD : {false, true}) {
        const std::string body =
            twoD ? "[entity.rigid_body_2d]\nshape = \"box\"\nhalf_extents = [0.2, 0.2]\n"
                 : "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.2, 0.2, 0.2]\n";
        auto sim = test::makeSimulation(scene(
            1.0 / 60.0, "[[entity]]\nname = \"car\"\n[entity.transform]\nposition = [0, 2, 0]\n" + body +
                            "mass = 1.0\nsleep = false\n" +
                            "[[entity]]\nname = \"load\"\n[entity.transform]\nposition = [0.5, 2, 0]\n" +
                            body + "mass = 1.0\nsleep = false\n" +
                            "[[joint]]\ntype = \"slider\"\na = \"car\"\naxis = [1, 1, 0]\n"
                            "[[joint]]\ntype = \"fixed\"\na = \"car\"\nb = \"load\"\n"
                            "pivot = [0.25, 2, 0]\n"));
        runFrames(*sim, 60);
        Vec3 car, load;
        if (twoD) {
            const RigidBody2D& c = test::component<RigidBody2D>(*sim, "car");
            const RigidBody2D& l = test::component<RigidBody2D>(*sim, "load");
            car = {c.position[0], c.position[1], 0};
            load = {l.position[0], l.position[1], 0};
        } else {
            car = test::component<RigidBody>(*sim, "car").position;
            load = test::component<RigidBody>(*sim, "load").position;
        }
        // gravity slides the pair down the 45-degree axis: x and y - 2 fall together
        EXPECT_LT(car.y, 1.0) << (twoD ? "Box2D" : "Bullet");
        EXPECT_NEAR(car.x, car.y - 2.0, 0.02) << (twoD ? "Box2D" : "Bullet") << ": on the axis";
        EXPECT_NEAR(load.x - car.x, 0.5, 0.02) << (twoD ? "Box2D" : "Bullet") << ": welded";
        EXPECT_NEAR(load.y - car.y, 0.0, 0.02) << (twoD ? "Box2D" : "Bullet") << ": welded";
    }
}

TEST(RigidBodies, JointLimitsAreTheTurnAndTravelOfARelativeToBInBothEngines) {
    // a lever from a hinge at (0, 2) out to +x: gravity turns it clockwise about +z (a negative angle)
    // until its limit of -0.3 rad; a block on a vertical slider falls until its travel reaches -0.5 m
    for (bool twoD : {false, true}) {
        const std::string lever =
            twoD ? "[entity.rigid_body_2d]\nshape = \"box\"\nhalf_extents = [0.5, 0.05]\n"
                 : "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.5, 0.05, 0.05]\n";
        auto sim = test::makeSimulation(scene(
            1.0 / 120.0, "[[entity]]\nname = \"lever\"\n[entity.transform]\nposition = [0.5, 2, 0]\n" +
                             lever + "mass = 1.0\nsleep = false\n" +
                             "[[entity]]\nname = \"block\"\n[entity.transform]\nposition = [5, 2, 0]\n" +
                             lever + "mass = 1.0\nsleep = false\n" +
                             "[[joint]]\ntype = \"hinge\"\na = \"lever\"\npivot = [0, 2, 0]\n"
                             "limits = [-0.3, 0.3]\n"
                             "[[joint]]\ntype = \"slider\"\na = \"block\"\naxis = [0, 1, 0]\n"
                             "limits = [-0.5, 0.0]\n"));
        runFrames(*sim, 240);
        double angle = 0.0, blockY = 0.0;
        if (twoD) {
            angle = test::component<RigidBody2D>(*sim, "lever").angle;
            blockY = test::component<RigidBody2D>(*sim, "block").position[1];
        } else {
            const Quat q = test::component<RigidBody>(*sim, "lever").orientation;
            angle = 2.0 * std::atan2(q.z, q.w);
            blockY = test::component<RigidBody>(*sim, "block").position.y;
        }
        EXPECT_NEAR(angle, -0.3, 0.02) << (twoD ? "Box2D" : "Bullet");
        EXPECT_NEAR(blockY, 1.5, 0.02) << (twoD ? "Box2D" : "Bullet");
    }
}

const char* kPile = R"(
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "rock"
scatter = { count = 30, min = [-1, 1, -1], max = [1, 4, 1] }
[entity.rigid_body]
shape = "convex"
mesh = "assets/meshes/rock_2.obj"
mass = 2.0
[[entity]]
name = "floor2d"
[entity.rigid_body_2d]
shape = "edge"
from = [-5, 0]
to = [5, 0]
[[entity]]
name = "box2d"
scatter = { count = 20, min = [-1, 1, 0], max = [1, 6, 0] }
[entity.rigid_body_2d]
shape = "box"
half_extents = [0.2, 0.2]
mass = 1.0
)";

TEST(RigidBodies, AMeshNamedFromTheProjectRootIsFoundWhateverTheAssetsPathEndsWith) {
    // "assets/meshes/..." is looked for beside the scenario, then under the assets folder's parent; a
    // TUMBLE_ASSETS ending in a slash made that parent the assets folder itself (nothing found)
    const std::string scenario = test::tempPath("mesh_lookup") + "/scene.toml";
    const char* before = std::getenv("TUMBLE_ASSETS");
    const std::string kept = before ? before : "";
    for (const std::string end : {"", "/", "//"}) {
        ::setenv("TUMBLE_ASSETS", (std::string(TUMBLE_SOURCE_DIR) + "/assets" + end).c_str(), 1);
        EXPECT_EQ(findMeshFile("assets/meshes/rock_2.obj", scenario),
                  std::string(TUMBLE_SOURCE_DIR) + "/assets/meshes/rock_2.obj")
            << "TUMBLE_ASSETS ending in '" << end << "'";
    }
    if (before) {
        ::setenv("TUMBLE_ASSETS", kept.c_str(), 1);
    } else {
        ::unsetenv("TUMBLE_ASSETS");
    }
}

TEST(RigidBodies, TheSameSceneGivesTheSameBitsTwice) {
    std::vector<std::uint64_t> hashes[2];
    for (auto& h : hashes) {
        auto sim = test::makeSimulation(scene(1.0 / 60.0, kPile));
        for (int f = 0; f < 120; ++f) {
            sim->runFrame();
            h.push_back(sim->hash());
        }
    }
    EXPECT_EQ(hashes[0], hashes[1]);
    EXPECT_NE(hashes[0][10], hashes[0][100]) << "the pile moved";
}

TEST(RigidBodies, DestroyingAnEntityRemovesItsBodyAndJoints) {
    auto sim = test::makeSimulation(scene(1.0 / 60.0, R"(
[[entity]]
name = "a"
[entity.transform]
position = [0, 5, 0]
[entity.rigid_body]
shape = "sphere"
mass = 1.0
[[entity]]
name = "b"
[entity.transform]
position = [1, 5, 0]
[entity.rigid_body]
shape = "sphere"
mass = 1.0
[[entity]]
name = "a2"
[entity.transform]
position = [0, 5, 0]
[entity.rigid_body_2d]
shape = "circle"
mass = 1.0
[[entity]]
name = "b2"
[entity.transform]
position = [1, 5, 0]
[entity.rigid_body_2d]
shape = "circle"
mass = 1.0
[[joint]]
type = "point"
a = "a"
b = "b"
pivot = [0.5, 5, 0]
[[joint]]
type = "point"
a = "a2"
b = "b2"
pivot = [0.5, 5, 0]
)"));
    runFrames(*sim, 5);
    const BulletWorld& bullet = sim->world().resource<BulletWorld>();
    const Box2DWorld& box2d = sim->world().resource<Box2DWorld>();
    EXPECT_EQ(bullet.bodyCount(), 2u);
    EXPECT_EQ(bullet.constraintCount(), 1u);
    EXPECT_EQ(box2d.bodyCount(), 2u);
    EXPECT_EQ(box2d.jointCount(), 1u);
    std::vector<Entity> doomed;
    sim->world().view<const Name>().each([&](Entity e, const Name& n) {
        if (n.value == "b" || n.value == "a2") {
            doomed.push_back(e);
        }
    });
    for (Entity e : doomed) {
        sim->world().destroy(e);
    }
    runFrames(*sim, 5);
    EXPECT_EQ(bullet.bodyCount(), 1u);
    EXPECT_EQ(bullet.constraintCount(), 0u);
    EXPECT_EQ(box2d.bodyCount(), 1u);
    EXPECT_EQ(box2d.jointCount(), 0u);
    EXPECT_LT(test::component<RigidBody>(*sim, "a").position.y, 4.9) << "the survivor falls freely";
}

TEST(RigidBodies, AnImpulseEventChangesVelocityByJOverM) {
    auto sim = test::makeSimulation(scene(1.0 / 60.0, R"(
[[entity]]
name = "puck"
[entity.rigid_body]
shape = "sphere"
mass = 4.0
[[entity]]
name = "puck2d"
[entity.rigid_body_2d]
shape = "circle"
mass = 4.0
[[event]]
frame = 0
entity = "puck"
action = "impulse"
value = [8.0, 0.0, 0.0]
[[event]]
frame = 0
entity = "puck2d"
action = "impulse"
value = [8.0, 0.0]
)"));
    sim->runFrame();
    EXPECT_NEAR(test::component<RigidBody>(*sim, "puck").linearVelocity.x, 2.0, 1e-9);
    EXPECT_NEAR(test::component<RigidBody2D>(*sim, "puck2d").velocity[0], 2.0, 1e-5);
}

TEST(RigidBodies, ClothDrapesOverAFallingCrateAndWeighsOnIt) {
    auto sim = test::makeSimulation(scene(1.0 / 60.0, R"(
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "crate"
[entity.transform]
position = [0, 1.5, 0]
[entity.rigid_body]
shape = "box"
half_extents = [0.5, 0.5, 0.5]
mass = 2.0
[[entity]]
name = "sheet"
[entity.transform]
position = [0, 2.5, 0]
[entity.cloth]
rows = 15
cols = 15
size = [2.0, 2.0]
plane = "xz"
mass = 1.0
stretch = 3000.0
shear = 300.0
bend = 10.0
integrator = "implicit_euler"
thickness = 0.02
pin = "none"
)"));
    runFrames(*sim, 240);
    const RigidBody& crate = test::component<RigidBody>(*sim, "crate");
    const SpringNetwork& sheet = test::component<SpringNetwork>(*sim, "sheet");
    EXPECT_NEAR(crate.position.y, 0.5, 0.01) << "the crate fell and stands on the floor";
    double worst = 0.0;
    for (const Vec3& x : sheet.x) {
        ASSERT_TRUE(isFinite(x));
        Vec3 n;
        worst = std::min(worst, signedDistance(crate, x, n));
    }
    EXPECT_GT(worst, -0.01) << "no mass deep inside the crate";
    // the sheet's middle mass (row 7, column 7 of 15) lies on the crate's top, a thickness above it
    EXPECT_NEAR(sheet.x[7 * 15 + 7].y, 1.0 + 0.02, 0.01) << "the sheet lies on the crate's top";
    EXPECT_LT(sheet.x[0].y, 0.5) << "its corners hang down the sides";
}

TEST(RigidBodies, ACrateHangsFromARopeThatStretchesByItsWeight) {
    // a rope of 10 links (k = 20000 N/m each) pinned at the top, its last mass anchored to a 10 kg crate's
    // top. At rest link j (from the top) carries the crate and the rope masses below it:
    // T_j = (M + (10 - j) m) g, and the crate sits lower by sum_j T_j / k.
    auto sim = test::makeSimulation(scene(1.0 / 60.0, R"(
[[entity]]
name = "rope"
[entity.transform]
position = [0, 4, 0]
[entity.rope]
segments = 10
length = 2.0
direction = [0, -1, 0]
mass = 0.55
stiffness = 20000.0
damping = 20.0
pin = "first"
integrator = "implicit_euler"
cg_tolerance = 1e-8
solver_precision = "double"
[[entity]]
name = "crate"
[entity.transform]
position = [0, 1.75, 0]
[entity.rigid_body]
shape = "box"
half_extents = [0.25, 0.25, 0.25]
mass = 10.0
[[joint]]
type = "anchor"
a = "rope"
mass = 10
b = "crate"
)"));
    runFrames(*sim, 600);
    const RigidBody& crate = test::component<RigidBody>(*sim, "crate");
    const SpringNetwork& rope = test::component<SpringNetwork>(*sim, "rope");
    const double m = 0.55 / 11.0, M = 10.0, k = 20000.0;
    double stretch = 0.0;
    for (int j = 0; j < 10; ++j) {
        stretch += (M + (10 - j) * m) * kG / k;
    }
    EXPECT_NEAR(crate.position.y, 1.75 - stretch, 0.05 * stretch) << "stretch " << stretch;
    EXPECT_LT(length(crate.linearVelocity), 1e-3);
    EXPECT_LT(length(rope.x[10] - crate.toWorld({0, 0.25, 0})), 1e-3) << "the rope's end is on the crate";
}

TEST(RigidBodies, ABoxPulledThroughItsCentreAsItSlidesAcrossThePullNeverTurns) {
    // no gravity: a box held at its centre by a stretched spring (200 N along +y) slides along x at 3 m/s and
    // swings round the spring's pin; the pull always passes through its centre and turns nothing (the 3D
    // twin of the 2D test). Seen to fail: the lever taken to where the held point will be at the step's
    // end, from the centre where it is at its start (a false turn of v dt x f a step)
    auto sim = test::makeSimulation(test::slideAcrossAPull(R"(
[entity.rigid_body]
shape = "box"
half_extents = [0.2, 0.2, 0.2]
mass = 1.0
linear_velocity = [3, 0, 0]
)"));
    double turning = 0.0, swept = 0.0;
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
        const RigidBody& box = test::component<RigidBody>(*sim, "box");
        turning = std::max(turning, length(box.angularVelocity));
        swept = std::max(swept, std::abs(box.position.x));
    }
    EXPECT_GT(swept, 0.5) << "it slides across the pull";
    EXPECT_LT(turning, 1e-9) << "rad/s";
}

TEST(RigidBodies, ParticlesBounceOffAMovingPaddle) {
    // zero gravity; a paddle rising at 2 m/s, particles falling onto it at 3 m/s, restitution 1: they leave
    // at 2 * 2 + 3 = 7 m/s upwards (the elastic bounce off a moving wall)
    auto sim = test::makeSimulation(R"(
[scene]
name = "t"
gravity = [0, 0, 0]
[[entity]]
name = "paddle"
[entity.rigid_body]
shape = "box"
half_extents = [2, 0.1, 2]
mass = 1000.0
linear_velocity = [0, 2, 0]
restitution = 1.0
friction = 0.0
[[entity]]
name = "drops"
[entity.transform]
position = [0, 1.0, 0]
[entity.emitter]
shape = "point"
burst = 10
direction = [0, -1, 0]
spread_deg = 0.0
speed = [3.0, 3.0]
lifetime = [10.0, 10.0]
restitution = 1.0
friction = 0.0
)");
    runFrames(*sim, 30);
    const ParticlePool& p = test::component<ParticleEmitter>(*sim, "drops").pool;
    ASSERT_EQ(p.count, 10u);
    for (std::uint32_t i = 0; i < p.count; ++i) {
        EXPECT_NEAR(p.vy[i], 7.0, 1e-3);
    }
}

TEST(RigidBodies, TheBulletBridgeGivesRawBulletsBitsStepAfterStep) {
    // 4 x 4 columns of 4 boxes, 300 steps (long enough to settle): the same bodies in raw Bullet, made in the
    // same order with the same settings, must end every step with the same bits
    auto sim = test::makeSimulation(raw::stackScene(4, 4, false));
    raw::BulletStack stack(4, 4);
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
        stack.step();
        ASSERT_EQ(raw::bulletState(*sim), stack.state()) << "after step " << i + 1;
    }
}

TEST(RigidBodies, TheBox2DBridgeGivesRawBox2DsBitsStepAfterStep) {
    auto sim = test::makeSimulation(raw::pyramidScene(10));
    raw::Box2DPyramid pyramid(10);
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
        pyramid.step();
        ASSERT_EQ(raw::box2dState(*sim), pyramid.state()) << "after step " << i + 1;
    }
}

} // namespace
} // namespace tumble
