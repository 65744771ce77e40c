// Cloth, soft bodies and ropes as built by the builders: structure, statics, contact with colliders, wind.

#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/spring_network.h"
#include "engine/name.h"
#include "engine/random.h"
#include "engine/run_report.h"
#include "systems/collision_system.h"
#include "systems/spring_builders.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace tumble {
namespace {

using test::makeSimulation;

SpringNetwork& network(Simulation& sim, const std::string& name) {
    return test::component<SpringNetwork>(sim, name);
}

double maxSpeed(const SpringNetwork& net) {
    double s = 0.0;
    for (const Vec3& v : net.v) {
        s = std::max(s, length(v));
    }
    return s;
}

TEST(ClothBuilder, CountsOfMassesSpringsAndTriangles) {
    ClothDef def;
    def.rows = 35;
    def.cols = 35;
    const SpringNetwork net = buildCloth(def);
    EXPECT_EQ(net.x.size(), 35u * 35u);
    EXPECT_EQ(net.triangles.size(), 2u * 34u * 34u) << "2312 triangles: the classic curtain";
    // stretch 2 * 35 * 34, shear 2 * 34 * 34, bend 2 * 35 * 33
    EXPECT_EQ(net.links.size(), 2u * 35u * 34u + 2u * 34u * 34u + 2u * 35u * 33u);
    // every link joins distinct masses at its rest length
    for (const SpringLink& s : net.links) {
        ASSERT_NE(s.a, s.b);
        EXPECT_NEAR(length(net.x[s.b] - net.x[s.a]), s.rest, 1e-12);
    }
}

TEST(ClothBuilder, GridIsCentredAndTrianglesFaceTheCamera) {
    ClothDef def;
    def.centre = {1.0, 2.0, 3.0};
    def.rows = 5;
    def.cols = 7;
    def.size = {3.0, 2.0};
    const SpringNetwork net = buildCloth(def);
    Vec3 mean;
    for (const Vec3& p : net.x) {
        mean += p * (1.0 / static_cast<double>(net.x.size()));
    }
    EXPECT_NEAR(length(mean - def.centre), 0.0, 1e-12);
    EXPECT_NEAR(net.x[6].x - net.x[0].x, 3.0, 1e-12) << "width along the columns";
    EXPECT_NEAR(net.x[0].y - net.x[28].y, 2.0, 1e-12) << "row 0 at the top";
    for (const auto& t : net.triangles) {
        EXPECT_GT(cross(net.x[t[1]] - net.x[t[0]], net.x[t[2]] - net.x[t[0]]).z, 0.0);
    }
}

TEST(ClothBuilder, PinPresets) {
    std::vector<std::uint32_t> pins;
    ASSERT_TRUE(clothPinPreset("top-corners", 4, 5, pins));
    EXPECT_EQ(pins, (std::vector<std::uint32_t>{0, 4}));
    ASSERT_TRUE(clothPinPreset("top-row", 4, 3, pins));
    EXPECT_EQ(pins, (std::vector<std::uint32_t>{0, 1, 2}));
    ASSERT_TRUE(clothPinPreset("left-edge", 3, 4, pins));
    EXPECT_EQ(pins, (std::vector<std::uint32_t>{0, 4, 8}));
    EXPECT_FALSE(clothPinPreset("top-middle", 3, 4, pins));
}

TEST(Cloth, HangingClothAtRestHoldsItsWeightAtThePins) {
    auto sim = makeSimulation(R"(
[scene]
name = "hang"
dt = 0.01
[[entity]]
name = "cloth"
[entity.transform]
position = [0, 2, 0]
[entity.cloth]
rows = 12
cols = 12
size = [1.0, 1.0]
mass = 0.5
stretch = 2000.0
shear = 200.0
bend = 20.0
damping = 2.0
drag = 0.2
pin = "top-row"
solver_precision = "double"
cg_tolerance = 1e-10
)");
    const std::vector<Vec3> start = network(*sim, "cloth").x;
    for (int i = 0; i < 3000 && (i < 100 || maxSpeed(network(*sim, "cloth")) > 1e-6); ++i) {
        sim->runFrame();
    }
    const SpringNetwork& net = network(*sim, "cloth");
    ASSERT_LT(maxSpeed(net), 1e-6) << "the cloth came to rest";
    // the pins have not moved
    for (std::uint32_t i = 0; i < 12; ++i) {
        EXPECT_EQ(net.x[i], start[i]);
    }
    // the springs' pull on the pins carries the weight of everything below them
    double up = 0.0;
    for (const SpringLink& s : net.links) {
        const Vec3 d = net.x[s.b] - net.x[s.a];
        const double len = length(d);
        const Vec3 onA = d * (s.k * (len - s.rest) / len);
        up += net.pinned[s.a] ? onA.y : 0.0;
        up += net.pinned[s.b] ? -onA.y : 0.0;
    }
    const double weight = 0.5 * (144.0 - 12.0) / 144.0 * 9.81;
    EXPECT_NEAR(-up, weight, 0.01 * weight) << "the pins are pulled down by the hanging weight";
}

TEST(SoftBody, JellyComesToRestOnTheGroundWithNoVertexBelowIt) {
    auto sim = makeSimulation(R"(
[scene]
name = "jelly"
dt = 0.005
[[entity]]
name = "ground"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "jelly"
[entity.transform]
position = [0, 1.0, 0]
[entity.softbody]
size = [0.5, 0.5, 0.5]
resolution = [5, 5, 5]
mass = 2.0
stiffness = 3000.0
damping = 1.0
thickness = 0.01
)");
    double lowest = 1e9;
    for (int i = 0; i < 1200; ++i) {
        sim->runFrame();
        for (const Vec3& p : network(*sim, "jelly").x) {
            lowest = std::min(lowest, p.y);
        }
    }
    const SpringNetwork& net = network(*sim, "jelly");
    EXPECT_GE(lowest, -1e-9) << "no vertex ever went below the ground";
    EXPECT_LT(maxSpeed(net), 0.05) << "at rest after 6 s";
    double top = -1e9, bottom = 1e9;
    for (const Vec3& p : net.x) {
        top = std::max(top, p.y);
        bottom = std::min(bottom, p.y);
    }
    EXPECT_NEAR(bottom, 0.01, 0.005) << "resting on the ground, at its thickness";
    EXPECT_GT(top - bottom, 0.35) << "the jelly keeps most of its 0.5 m height";
    EXPECT_TRUE(sim->world().resource<RunReport>().failures.empty());
}

TEST(Collisions, ShapesReportDistanceAndNormal) {
    Vec3 n;
    RigidBody plane;
    plane.shape = ShapeKind::Plane;
    EXPECT_DOUBLE_EQ(signedDistance(plane, {3, 2, 1}, n), 2.0);
    EXPECT_EQ(n, (Vec3{0, 1, 0}));
    RigidBody sphere;
    sphere.shape = ShapeKind::Sphere;
    sphere.radius = 1.0;
    sphere.position = {0, 1, 0};
    EXPECT_DOUBLE_EQ(signedDistance(sphere, {0, 3, 0}, n), 1.0);
    EXPECT_DOUBLE_EQ(signedDistance(sphere, {0.5, 1, 0}, n), -0.5);
    EXPECT_EQ(n, (Vec3{1, 0, 0}));
    RigidBody box;
    box.shape = ShapeKind::Box;
    box.halfExtents = {1, 2, 3};
    EXPECT_DOUBLE_EQ(signedDistance(box, {0, 5, 0}, n), 3.0);
    EXPECT_EQ(n, (Vec3{0, 1, 0}));
    EXPECT_DOUBLE_EQ(signedDistance(box, {0.9, 0, 0}, n), -0.1) << "inside: out through the nearest face";
    EXPECT_EQ(n, (Vec3{1, 0, 0}));
    EXPECT_NEAR(signedDistance(box, {4, 6, 0}, n), 5.0, 1e-12) << "off a corner: 3-4-5";
    RigidBody capsule;
    capsule.shape = ShapeKind::Capsule;
    capsule.radius = 0.5;
    capsule.height = 2.0;
    EXPECT_DOUBLE_EQ(signedDistance(capsule, {0, 2.5, 0}, n), 1.0) << "above the cap";
    EXPECT_DOUBLE_EQ(signedDistance(capsule, {2, 0.3, 0}, n), 1.5) << "beside the straight part";
    RigidBody cylinder;
    cylinder.shape = ShapeKind::Cylinder;
    cylinder.radius = 1.0;
    cylinder.height = 2.0;
    EXPECT_DOUBLE_EQ(signedDistance(cylinder, {0, 3, 0}, n), 2.0);
    EXPECT_DOUBLE_EQ(signedDistance(cylinder, {3, 0, 0}, n), 2.0);
    RigidBody wide;
    wide.shape = ShapeKind::Cylinder;
    wide.radius = 5.0;
    wide.height = 20.0;
    EXPECT_DOUBLE_EQ(signedDistance(wide, {0.5, 0, 0}, n), -4.5)
        << "deep inside: out through the curved side";
    EXPECT_EQ(n, (Vec3{1, 0, 0}));
    EXPECT_DOUBLE_EQ(signedDistance(wide, {0.5, 9.5, 0}, n), -0.5) << "near the top: out through the end";
    EXPECT_EQ(n, (Vec3{0, 1, 0}));
}

TEST(Collisions, AmongManyBodiesNothingEndsInsideAny) {
    // 60 static bodies of every bounded shape at random turns, 0.8 m apart on a grid (no two touching, so
    // that nothing is wedged), more than the few tried one by one (the bodies near each point come from a
    // hierarchy of their boxes), a shower of particles and a cloth
    // falling through them: after every step no particle is inside any body and no mass of the cloth within
    // half its thickness of one, judged against every body one by one
    std::string text = "[scene]\nname = \"many\"\ndt = 0.01\n";
    Rng rng(12);
    const char* shapes[] = {"box", "sphere", "capsule", "cylinder"};
    for (int k = 0; k < 60; ++k) {
        const double a = rng.uniform(0, 3.14), c = std::cos(a / 2), s = std::sin(a / 2);
        Vec3 axis{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
        axis = axis * (1.0 / length(axis));
        const char* size = k % 4 == 0   ? "half_extents = [0.3, 0.1, 0.2]"
                           : k % 4 == 1 ? "radius = 0.15"
                                        : "radius = 0.15\nheight = 0.3";
        char buf[512];
        std::snprintf(buf, sizeof buf,
                      "[[entity]]\nname = \"b%d\"\n[entity.transform]\nposition = [%.6f, %.6f, %.6f]\n"
                      "[entity.rigid_body]\nshape = \"%s\"\n%s\norientation = [%.9f, %.9f, %.9f, %.9f]\n",
                      k, -1.6 + 0.8 * (k % 5), 0.5 + 0.8 * (k / 20), -1.2 + 0.8 * ((k / 5) % 4),
                      shapes[k % 4], size, axis.x * s, axis.y * s, axis.z * s, c);
        text += buf;
    }
    text += "[[entity]]\nname = \"shower\"\n[entity.transform]\nposition = [0, 3, 0]\n[entity.emitter]\n"
            "rate = 20000.0\nshape = \"box\"\nhalf_extents = [1.5, 0.1, 1.5]\ndirection = [0, -1, 0]\n"
            "speed = [1.0, 3.0]\nlifetime = [3.0, 3.0]\nmax_particles = 20000\nrestitution = 0.3\n"
            "[[entity]]\nname = \"sheet\"\n[entity.transform]\nposition = [0, 2.8, 0]\n[entity.cloth]\n"
            "rows = 20\ncols = 20\nsize = [3.0, 3.0]\nplane = \"xz\"\nthickness = 0.01\n";
    {
        FILE* f = std::fopen("/tmp/many.toml", "w");
        std::fputs(text.c_str(), f);
        std::fclose(f);
    }
    auto sim = makeSimulation(text);
    for (int step = 0; step < 120; ++step) {
        sim->runFrame();
        const ParticlePool& p = test::component<ParticleEmitter>(*sim, "shower").pool;
        const SpringNetwork& net = network(*sim, "sheet");
        sim->world().view<const RigidBody>().each([&](Entity, const RigidBody& body) {
            Vec3 n;
            for (std::uint32_t i = 0; i < p.count; ++i) {
                ASSERT_GE(signedDistance(body, {p.px[i], p.py[i], p.pz[i]}, n), -1e-6) << "step " << step;
            }
            for (std::size_t i = 0; i < net.x.size(); ++i) {
                // (a mass wedged between two bodies at a sharp angle is left a little short of the
                // thickness by the passes' cap, as before the hierarchy: never inside)
                ASSERT_GE(signedDistance(body, net.x[i], n), 0.5 * net.thickness) << "step " << step;
            }
        });
    }
}

class DrapeOver : public ::testing::TestWithParam<std::string> {};

TEST_P(DrapeOver, ClothNeverSinksIntoTheCollider) {
    // a flat cloth dropped onto a shape: after every step, no free vertex is inside it beyond a millimetre
    auto sim = makeSimulation(R"(
[scene]
name = "drape"
dt = 0.005
[[entity]]
name = "table"
[entity.rigid_body]
)" + GetParam() + R"(
[[entity]]
name = "cloth"
[entity.transform]
position = [0.1, 1.2, 0.05]
[entity.cloth]
rows = 15
cols = 15
size = [1.5, 1.5]
plane = "xz"
pin = "none"
thickness = 0.01
stretch = 3000.0
)");
    RigidBody body;
    sim->world().view<const RigidBody>().each([&](Entity, const RigidBody& b) { body = b; });
    for (int i = 0; i < 400; ++i) {
        sim->runFrame();
        for (const Vec3& p : network(*sim, "cloth").x) {
            Vec3 n;
            ASSERT_GT(signedDistance(body, p, n), -1e-3) << "frame " << i;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Shapes, DrapeOver,
                         ::testing::Values("shape = \"sphere\"\nradius = 0.5",
                                           "shape = \"box\"\nhalf_extents = [0.4, 0.5, 0.4]",
                                           "shape = \"capsule\"\nradius = 0.3\nheight = 0.6",
                                           "shape = \"cylinder\"\nradius = 0.4\nheight = 1.0",
                                           "shape = \"plane\"\nnormal = [0, 1, 0]"),
                         [](const ::testing::TestParamInfo<std::string>& p) {
                             return p.param.substr(9, p.param.find('"', 9) - 9);
                         });

TEST(Cloth, WindBillowsACurtainDownwind) {
    auto sim = makeSimulation(R"(
[scene]
name = "curtain"
dt = 0.0166666667
seed = 3
[[entity]]
name = "curtain"
[entity.transform]
position = [0, 2, 0]
[entity.cloth]
rows = 15
cols = 15
size = [2.0, 2.0]
pin = "top-row"
[[entity]]
name = "wind"
[entity.force_field]
kind = "wind"
strength = [0.0, 0.0, 4.0]
gust = 0.5
)");
    for (int i = 0; i < 120; ++i) {
        sim->runFrame();
    }
    const SpringNetwork& net = network(*sim, "curtain");
    double meanZ = 0.0;
    for (const Vec3& p : net.x) {
        meanZ += p.z / static_cast<double>(net.x.size());
    }
    EXPECT_GT(meanZ, 0.1) << "blown downwind";
    EXPECT_LT(net.x.back().y, 2.0) << "still hanging";
}

TEST(Rope, PinnedRopeSwingsBelowItsPin) {
    auto sim = makeSimulation(R"(
[scene]
name = "rope"
dt = 0.002
[[entity]]
name = "rope"
[entity.transform]
position = [0, 2, 0]
[entity.rope]
segments = 10
length = 1.0
mass = 0.5
stiffness = 5000.0
damping = 1.0
pin = "first"
)");
    for (int i = 0; i < 500; ++i) {
        sim->runFrame();
    }
    const SpringNetwork& net = network(*sim, "rope");
    EXPECT_EQ(net.x[0], (Vec3{0, 2, 0}));
    EXPECT_LT(net.x.back().y, 2.0) << "the free end fell";
    EXPECT_LT(length(net.x.back() - net.x[0]), 1.05) << "springs keep it near its length";
}

TEST(Rope, AtRestThePinHoldsTheRopesWeight) {
    // a rope of 11 equal masses (0.5 kg in all) with bend springs, hanging from its first mass, damped (its
    // springs and a drag on its swing) until it stops: the pull of the springs on the pin is the weight of
    // the 10 free masses, 10/11 of 0.5 kg times g, to a thousandth
    auto sim = makeSimulation(R"(
[scene]
name = "rope"
dt = 0.005
[[entity]]
name = "rope"
[entity.transform]
position = [0, 2, 0]
[entity.rope]
segments = 10
length = 1.0
direction = [0.6, -0.8, 0.0]
mass = 0.5
stiffness = 2000.0
bend = 50.0
damping = 3.0
drag = 0.2
pin = "first"
integrator = "implicit_euler"
solver_precision = "double"
cg_tolerance = 1e-12
)");
    for (int i = 0; i < 20000 && (i < 100 || maxSpeed(network(*sim, "rope")) > 1e-7); ++i) {
        sim->runFrame();
    }
    const SpringNetwork& net = network(*sim, "rope");
    ASSERT_LT(maxSpeed(net), 1e-7) << "the rope came to rest";
    Vec3 pull;
    for (const SpringLink& s : net.links) {
        const Vec3 d = net.x[s.b] - net.x[s.a];
        const double len = length(d);
        const Vec3 onA = d * (s.k * (len - s.rest) / len);
        pull += net.pinned[s.a] ? onA : Vec3{};
        pull -= net.pinned[s.b] ? onA : Vec3{};
    }
    const double weight = 0.5 * 10.0 / 11.0 * 9.81;
    EXPECT_NEAR(-pull.y, weight, 1e-3 * weight);
    EXPECT_NEAR(pull.x, 0.0, 1e-3 * weight) << "straight down below the pin at rest";
}

} // namespace
} // namespace tumble
