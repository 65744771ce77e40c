// Cloth contact judged after every step by the tests' own reference (tests/contact_reference.h): no two
// triangles that share no vertex intersect, and no mass ends deeper than its thickness inside a collider;
// over every self-colliding demo and over seeded random drops of one to three cloths onto a ball, a box or
// the bare ground. The reference itself is checked first, against hand-made cases and against CGAL.

#include "components/spring_network.h"
#include "engine/run_report.h"
#include "systems/cloth_collision.h"
#include "tests/contact_reference.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <random>
#include <sstream>
#include <tuple>

namespace tumble {
namespace {

bool meet(std::array<Vec3, 3> a, std::array<Vec3, 3> b) {
    return test::referenceTrianglesMeet(a.data(), b.data());
}

TEST(ContactReference, HandMadeCases) {
    const std::array<Vec3, 3> base{Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0, 1, 0}};
    // an edge through the face, and the same lifted clear of it
    EXPECT_TRUE(meet(base, {Vec3{0.2, 0.2, -1}, Vec3{0.2, 0.2, 1}, Vec3{1, 1, 1}}));
    EXPECT_FALSE(meet(base, {Vec3{0.2, 0.2, 0.5}, Vec3{0.2, 0.2, 1}, Vec3{1, 1, 1}}));
    // parallel planes a hair apart
    EXPECT_FALSE(meet(base, {Vec3{0, 0, 1e-9}, Vec3{1, 0, 1e-9}, Vec3{0, 1, 1e-9}}));
    // touching corner to face, and corner to corner
    EXPECT_TRUE(meet(base, {Vec3{0.25, 0.25, 0}, Vec3{0.25, 0.25, 1}, Vec3{1, 1, 1}}));
    EXPECT_TRUE(meet(base, {Vec3{1, 0, 0}, Vec3{2, 0, 1}, Vec3{2, 1, 0}}));
    // coplanar: overlapping, one inside the other, apart
    EXPECT_TRUE(meet(base, {Vec3{0.5, 0.5, 0}, Vec3{-0.5, 0.5, 0}, Vec3{0.5, -0.5, 0}}));
    EXPECT_TRUE(meet(base, {Vec3{0.1, 0.1, 0}, Vec3{0.2, 0.1, 0}, Vec3{0.1, 0.2, 0}}));
    EXPECT_TRUE(meet({Vec3{0.1, 0.1, 0}, Vec3{0.2, 0.1, 0}, Vec3{0.1, 0.2, 0}}, base));
    EXPECT_FALSE(meet(base, {Vec3{0.6, 0.6, 0}, Vec3{1.6, 0.6, 0}, Vec3{0.6, 1.6, 0}}));
    // edges crossing in the gap between them (two quads folded into each other)
    EXPECT_TRUE(meet(base, {Vec3{0.3, -0.5, 0.5}, Vec3{0.3, 0.5, -0.5}, Vec3{0.3, 2, 2}}));
}

TEST(ContactReference, AgreesWithCgalOnRandomTriangles) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int meeting = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        std::array<Vec3, 3> a, b;
        for (int k = 0; k < 3; ++k) {
            a[k] = {u(rng), u(rng), u(rng)};
            b[k] = Vec3{u(rng), u(rng), u(rng)} + Vec3{0.8, 0.0, 0.0};
        }
        if (trial % 4 == 0) {
            for (int k = 0; k < 3; ++k) {
                a[k].z = b[k].z = 0.25; // coplanar pairs
            }
        }
        const bool reference = meet(a, b);
        meeting += reference;
        ASSERT_EQ(reference, trianglesIntersect(a[0], a[1], a[2], b[0], b[1], b[2])) << "trial " << trial;
    }
    EXPECT_GT(meeting, 2000);
    EXPECT_LT(meeting, 18000);
}

/// The colliders of the test scenes, analytically: the depth of p inside them (<= 0 outside).
struct Colliders {
    bool ground = true;
    bool ball = false;
    Vec3 ballCentre;
    double ballRadius = 0.0;
    bool box = false;
    Vec3 boxCentre, boxHalf;

    double depth(const Vec3& p) const {
        double d = ground ? -p.y : -1e300;
        if (ball) {
            d = std::max(d, ballRadius - length(p - ballCentre));
        }
        if (box) {
            const Vec3 q = p - boxCentre;
            d = std::max(d, std::min({boxHalf.x - std::abs(q.x), boxHalf.y - std::abs(q.y),
                                      boxHalf.z - std::abs(q.z)}));
        }
        return d;
    }
};

struct Outcome {
    int worstCrossings = 0;
    int stepOfFirst = -1;
    double deepest = -1e300; ///< m inside a collider, the worst over the run, less the thickness
    std::uint64_t steps = 0;
};

/// Runs the scene step by step and judges every step; `atEnd` is shown the simulation when it has run.
Outcome judge(const std::string& text, const std::vector<std::string>& cloths, const Colliders& colliders,
              int frames, const std::function<void(Simulation&)>& atEnd = {}) {
    auto sim = test::makeSimulation(text);
    std::vector<const SpringNetwork*> nets;
    std::vector<test::Surface> surfaces;
    for (const std::string& c : cloths) {
        nets.push_back(&test::component<SpringNetwork>(*sim, c));
        surfaces.push_back({&nets.back()->x, &nets.back()->triangles});
    }
    Outcome o;
    for (int f = 0; f < frames; ++f) {
        sim->beginFrame();
        for (int s = 0; s < sim->scene().substeps; ++s) {
            sim->runStep();
            const int crossings = test::countCrossings(surfaces);
            if (crossings > o.worstCrossings) {
                o.worstCrossings = crossings;
            }
            if (crossings > 0 && o.stepOfFirst < 0) {
                o.stepOfFirst = int(sim->step());
            }
            for (const SpringNetwork* net : nets) {
                for (const Vec3& p : net->x) {
                    o.deepest = std::max(o.deepest, colliders.depth(p) - net->thickness);
                }
            }
        }
        sim->endFrame(1.0);
    }
    o.steps = sim->step();
    EXPECT_TRUE(sim->world().resource<RunReport>().failures.empty());
    if (atEnd) {
        atEnd(*sim);
    }
    return o;
}

class RandomDrop : public ::testing::TestWithParam<int> {};

TEST_P(RandomDrop, NeverCrossesAfterAnyStep) {
    // 20 seeds unless TUMBLE_DROP_COUNT says fewer (the sanitizer build runs one)
    int count = 20;
    if (const char* env = std::getenv("TUMBLE_DROP_COUNT")) {
        count = std::max(1, std::atoi(env));
    }
    const int seed = GetParam();
    if (seed > count) {
        GTEST_SKIP() << "TUMBLE_DROP_COUNT=" << count;
    }
    {
        std::mt19937 rng(std::uint32_t(seed) * 7919u);
        auto uniform = [&](double lo, double hi) {
            return std::uniform_real_distribution<double>(lo, hi)(rng);
        };
        auto integer = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
        Colliders col;
        std::ostringstream s;
        s.precision(17);
        // frames of 1/60 s in two steps, as the demos run cloth (at one step a frame, a cloth falling 5 cm a
        // step crumples onto a box with up to a million candidate pairs, and the fail-safe took seconds a
        // step)
        s << "[scene]\nname = \"drop" << seed << "\"\ndt = 0.008333333333\nsubsteps = 2\nseed = " << seed
          << "\n[[entity]]\nname = \"floor\"\n[entity.rigid_body]\nshape = \"plane\"\n";
        const int what = seed % 3; // 0: bare ground, 1: a ball, 2: a box
        if (what == 1) {
            col.ball = true;
            col.ballRadius = uniform(0.2, 0.4);
            col.ballCentre = {uniform(-0.1, 0.1), col.ballRadius, uniform(-0.1, 0.1)};
            s << "[[entity]]\nname = \"ball\"\n[entity.transform]\nposition = [" << col.ballCentre.x << ", "
              << col.ballCentre.y << ", " << col.ballCentre.z
              << "]\n[entity.rigid_body]\nshape = \"sphere\"\nradius = " << col.ballRadius << "\n";
        } else if (what == 2) {
            col.box = true;
            col.boxHalf = {uniform(0.15, 0.3), uniform(0.1, 0.25), uniform(0.15, 0.3)};
            col.boxCentre = {uniform(-0.1, 0.1), col.boxHalf.y, uniform(-0.1, 0.1)};
            s << "[[entity]]\nname = \"table\"\n[entity.transform]\nposition = [" << col.boxCentre.x << ", "
              << col.boxCentre.y << ", " << col.boxCentre.z
              << "]\n[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [" << col.boxHalf.x << ", "
              << col.boxHalf.y << ", " << col.boxHalf.z << "]\n";
        }
        const int clothCount = integer(1, 3);
        std::vector<std::string> names;
        for (int c = 0; c < clothCount; ++c) {
            const int n = integer(10, 40);
            const double size = uniform(0.8, 1.4);
            const double spacing = size / (n - 1);
            const double thickness = uniform(0.3, 0.9) * spacing;
            names.push_back("cloth" + std::to_string(c));
            s << "[[entity]]\nname = \"" << names.back() << "\"\n[entity.transform]\nposition = ["
              << uniform(-0.25, 0.25) << ", " << 0.9 + 0.25 * c + uniform(0.0, 0.1) << ", "
              << uniform(-0.25, 0.25) << "]\n[entity.cloth]\nrows = " << n << "\ncols = " << n << "\nsize = ["
              << size << ", " << size
              << "]\nplane = \"xz\"\nstretch = 3000.0\nshear = 300.0\nbend = " << uniform(0.1, 5.0)
              << "\npin = \"none\"\nintegrator = \"implicit_euler\"\nthickness = " << thickness
              << "\nself_collision = true\n";
        }
        // kept, so that a failure can be run again: tumble run FILE --check-contact
        const std::string file = test::writeTemp("drop_" + std::to_string(seed) + ".toml", s.str());
        const Outcome o = judge(s.str(), names, col, 240);
        EXPECT_EQ(o.worstCrossings, 0)
            << "seed " << seed << ": first at step " << o.stepOfFirst << " (" << file << ")";
        EXPECT_LE(o.deepest, 1e-9) << "seed " << seed << ": a mass deeper than its thickness in a collider ("
                                   << file << ")";
        EXPECT_EQ(o.steps, 480u);
    }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomDrop, ::testing::Range(1, 21));

class SelfCollidingDemo : public ::testing::TestWithParam<const char*> {};

TEST_P(SelfCollidingDemo, NeverCrossesAfterAnyStep) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + GetParam() + ".toml";
    const std::string text = test::readFile(path);
    auto sim = test::makeSimulation(text);
    std::vector<std::string> names;
    sim->world().view<const Name, SpringNetwork>().each([&](Entity, const Name& n, SpringNetwork& net) {
        if (net.selfCollision) {
            names.push_back(n.value);
        }
    });
    ASSERT_FALSE(names.empty());
    Colliders col; // the demos' colliders are checked by the collision tests; here the ground
    const Outcome o = judge(text, names, col, int(sim->scene().frames));
    EXPECT_EQ(o.worstCrossings, 0) << "first at step " << o.stepOfFirst;
    EXPECT_LE(o.deepest, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Demos, SelfCollidingDemo,
                         ::testing::Values("pile", "drape_sphere", "tablecloth", "twist"),
                         [](const auto& param) { return std::string(param.param); });

// ---- finite-element bodies in cloth contact --------------------------------------------------------------

/// A cloth of 24 x 24 masses (1.2 m, 0.02 m thick) dropped from 0.25 m above a soft fem block (0.6 x 0.3 x
/// 0.6 m, its bottom pinned to the ground), the block's surface in contact or not.
std::string clothOnBlock(bool blockInContact) {
    return std::string(R"(
[scene]
name = "cloth_on_block"
dt = 0.008333333333
substeps = 2
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "block"
[entity.transform]
position = [0.0, 0.15, 0.0]
[entity.fem]
mesh = "box"
size = [0.6, 0.3, 0.6]
resolution = [4, 2, 4]
young = 2.0e4
density = 200.0
pin = "bottom"
thickness = 0.01
self_collision = )") +
           (blockInContact ? "true" : "false") + R"(
[[entity]]
name = "cloth"
[entity.transform]
position = [0.02, 0.55, -0.03]
[entity.cloth]
rows = 24
cols = 24
size = [1.2, 1.2]
plane = "xz"
stretch = 3000.0
shear = 300.0
bend = 1.0
pin = "none"
integrator = "implicit_euler"
thickness = 0.02
self_collision = true
)";
}

/// The lowest point of the net's masses.
double lowestOf(const SpringNetwork& net) {
    double y = 1e300;
    for (const Vec3& p : net.x) {
        y = std::min(y, p.y);
    }
    return y;
}

/// Whether an fem body's tetrahedra all keep their rest orientation (contact moves only the surface's
/// nodes: it must not turn an element inside out).
bool upright(const SpringNetwork& net) {
    for (const auto& t : net.fem.tets) {
        const Vec3 a = net.x[t[1]] - net.x[t[0]], b = net.x[t[2]] - net.x[t[0]],
                   c = net.x[t[3]] - net.x[t[0]];
        if (!(dot(a, cross(b, c)) > 0.0)) {
            return false;
        }
    }
    return true;
}

/// What contact did over the run: no step may have ended held still (every cap reached).
void expectContactSettled(Simulation& sim) {
    EXPECT_EQ(sim.world().resource<ClothContactStats>().stepsHeldStill, 0u);
}

/// The highest point of the net's masses within `reach` of the vertical axis through the origin.
double highestNear(const SpringNetwork& net, double reach) {
    double top = -1e300;
    for (const Vec3& p : net.x) {
        if (std::abs(p.x) < reach && std::abs(p.z) < reach) {
            top = std::max(top, p.y);
        }
    }
    return top;
}

TEST(FemContact, AClothDroppedOnAnFemBlockRestsOnItsSurfaceWithoutCrossingIt) {
    double blockTop = 0.0, clothOver = 0.0, clothLowest = 0.0;
    const Outcome o = judge(clothOnBlock(true), {"cloth", "block"}, Colliders{}, 90, [&](Simulation& sim) {
        const auto& block = test::component<SpringNetwork>(sim, "block");
        const auto& cloth = test::component<SpringNetwork>(sim, "cloth");
        blockTop = highestNear(block, 0.2);
        double lowest = 1e300;
        for (const Vec3& p : cloth.x) {
            if (std::abs(p.x) < 0.2 && std::abs(p.z) < 0.2) {
                lowest = std::min(lowest, p.y);
            }
        }
        clothLowest = lowest;
        clothOver = highestNear(cloth, 0.2);
        EXPECT_TRUE(upright(block));
        expectContactSettled(sim);
    });
    EXPECT_EQ(o.worstCrossings, 0) << "first at step " << o.stepOfFirst;
    // it lies on the block's top (0.3 m, pressed a little by the cloth), a thickness or so above it
    EXPECT_GT(blockTop, 0.25);
    EXPECT_GT(clothLowest, blockTop - 0.005);
    EXPECT_LT(clothOver, blockTop + 0.06);
    // the same block left out of contact: the cloth falls through it to the ground, crossing its surface
    const Outcome through =
        judge(clothOnBlock(false), {"cloth", "block"}, Colliders{}, 90, [&](Simulation& sim) {
            EXPECT_LT(highestNear(test::component<SpringNetwork>(sim, "cloth"), 0.2), 0.1);
        });
    EXPECT_GT(through.worstCrossings, 0);
}

/// A soft fem cube (0.2 m, 2 cells a side) dropped turning from 0.2 m above the block of clothOnBlock.
std::string cubeOnBlock(bool cubeInContact) {
    const std::string block = clothOnBlock(true);
    return block.substr(0, block.find("[[entity]]\nname = \"cloth\"")) + R"(
[[entity]]
name = "cube"
[entity.transform]
position = [0.05, 0.6, -0.04]
[entity.fem]
mesh = "box"
size = [0.2, 0.2, 0.2]
resolution = [2, 2, 2]
young = 5.0e4
density = 300.0
angular_velocity = [0.5, 0.0, 0.8]
thickness = 0.01
self_collision = )" +
           (cubeInContact ? "true" : "false") + "\n";
}

TEST(FemContact, AnFemCubeDroppedOnAnFemBlockRestsOnItWithoutCrossingIt) {
    double cubeLowest = 0.0, blockTop = 0.0;
    const Outcome o = judge(cubeOnBlock(true), {"cube", "block"}, Colliders{}, 90, [&](Simulation& sim) {
        cubeLowest = lowestOf(test::component<SpringNetwork>(sim, "cube"));
        // the top's middle node, under the cube: pressed the most
        blockTop = highestNear(test::component<SpringNetwork>(sim, "block"), 0.1);
        EXPECT_TRUE(upright(test::component<SpringNetwork>(sim, "cube")));
        EXPECT_TRUE(upright(test::component<SpringNetwork>(sim, "block")));
        expectContactSettled(sim);
    });
    EXPECT_EQ(o.worstCrossings, 0) << "first at step " << o.stepOfFirst;
    // on the block's top, about a thickness above it (it fell 0.2 m onto it)
    EXPECT_GT(blockTop, 0.28);
    EXPECT_GT(cubeLowest, blockTop - 0.002);
    EXPECT_LT(cubeLowest, blockTop + 0.03);
    // the cube out of contact falls through the block to the ground
    judge(cubeOnBlock(false), {"cube", "block"}, Colliders{}, 90,
          [&](Simulation& sim) { EXPECT_LT(lowestOf(test::component<SpringNetwork>(sim, "cube")), 0.05); });
}

TEST(FemContact, AnFemBallDroppedIntoAPinnedClothIsCaughtByIt) {
    const std::string text = R"(
[scene]
name = "ball_in_cloth"
dt = 0.008333333333
substeps = 2
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "ball"
[entity.transform]
position = [0.03, 1.0, -0.02]
[entity.fem]
mesh = "sphere"
radius = 0.2
resolution = 4
young = 5.0e4
density = 60.0
thickness = 0.01
self_collision = true
[[entity]]
name = "net"
[entity.transform]
position = [0.0, 0.5, 0.0]
[entity.cloth]
rows = 20
cols = 20
size = [1.2, 1.2]
plane = "xz"
stretch = 5000.0
shear = 500.0
bend = 1.0
pin = "corners"
integrator = "implicit_euler"
thickness = 0.02
self_collision = true
)";
    double ballLowest = 0.0, clothLowest = 0.0;
    const Outcome o = judge(text, {"ball", "net"}, Colliders{}, 120, [&](Simulation& sim) {
        ballLowest = lowestOf(test::component<SpringNetwork>(sim, "ball"));
        clothLowest = lowestOf(test::component<SpringNetwork>(sim, "net"));
        EXPECT_TRUE(upright(test::component<SpringNetwork>(sim, "ball")));
        expectContactSettled(sim);
    });
    EXPECT_EQ(o.worstCrossings, 0) << "first at step " << o.stepOfFirst;
    // lying in the sagging cloth: above its lowest point, within a few centimetres of it, above the ground
    EXPECT_GT(ballLowest, clothLowest + 0.01);
    EXPECT_LT(ballLowest, clothLowest + 0.06);
    EXPECT_GT(ballLowest, 0.15);
}

// ---- the candidate lists keep their promise -------------------------------------------------------------

/// The tests' own distances, written another way than the code under test's: the closest point of the
/// triangle's plane when it falls inside the triangle, else the nearest of its three sides.
double pointSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double len2 = dot(ab, ab);
    const double t = len2 > 0.0 ? std::clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
    return length(p - (a + ab * t));
}

double pointTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 u = b - a, v = c - a, w = p - a;
    const double uu = dot(u, u), uv = dot(u, v), vv = dot(v, v), wu = dot(w, u), wv = dot(w, v);
    const double det = uu * vv - uv * uv;
    if (det > 1e-30 * uu * vv) {
        const double s = (vv * wu - uv * wv) / det, t = (uu * wv - uv * wu) / det;
        if (s >= 0.0 && t >= 0.0 && s + t <= 1.0) {
            return length(p - (a + u * s + v * t));
        }
    }
    return std::min({pointSegment(p, a, b), pointSegment(p, b, c), pointSegment(p, c, a)});
}

/// The closest points of the two lines when both fall within the segments, else the nearest of an end of
/// one to the other segment (the distance is convex in the two parameters, so its minimum over the square
/// is at the lines' closest points or on the square's sides).
double segmentSegment(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
    const double a = dot(d1, d1), e = dot(d2, d2), b = dot(d1, d2), c = dot(d1, r), f = dot(d2, r);
    const double det = a * e - b * b;
    if (det > 1e-12 * a * e) {
        const double s = (b * f - c * e) / det, t = (a * f - b * c) / det;
        if (s >= 0.0 && s <= 1.0 && t >= 0.0 && t <= 1.0) {
            return length((p0 + d1 * s) - (q0 + d2 * t));
        }
    }
    return std::min({pointSegment(p0, q0, q1), pointSegment(p1, q0, q1), pointSegment(q0, p0, p1),
                     pointSegment(q1, p0, p1)});
}

TEST(ClothCandidates, EveryPairCloserThanTheThicknessIsKept) {
    // Two small cloths over a ball, one onto the other: the lists are gathered in full and in part (the
    // masses of a sheet sliding off the ball leave their margins a few at a time). The lists promise that
    // a pair left out stays farther apart than its thickness while each of its masses is within its margin
    // of where its pairs were gathered: the masses of the two sides can close the distance by their margins,
    // so, where they were gathered, every pair closer than its thickness plus the largest margin of each side
    // must be a candidate. Checked after every step, by brute force over all pairs, with the tests' own
    // distances.
    std::string text = R"([scene]
name = "candidates"
dt = 0.008333333333
substeps = 2
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "ball"
[entity.transform]
position = [0.05, 0.25, 0.0]
[entity.rigid_body]
shape = "sphere"
radius = 0.25
)";
    // (name, height, masses a side, size, thickness: 0.6 of the spacing)
    for (const auto& [name, y, n, size, h] :
         {std::tuple{"lower", 0.7, 14, 0.8, 0.037}, {"upper", 0.9, 12, 0.7, 0.025}}) {
        std::ostringstream cloth;
        cloth << "[[entity]]\nname = \"" << name << "\"\n[entity.transform]\nposition = [0.05, " << y
              << ", 0.02]\n[entity.cloth]\nrows = " << n << "\ncols = " << n << "\nsize = [" << size << ", "
              << size << "]\nplane = \"xz\"\nstretch = 3000.0\nshear = 300.0\nbend = 0.5\npin = \"none\"\n"
              << "integrator = \"implicit_euler\"\nthickness = " << h << "\nself_collision = true\n";
        text += cloth.str();
    }
    auto sim = test::makeSimulation(text);
    std::size_t close = 0, missed = 0;
    std::vector<std::array<std::uint32_t, 2>> edges;
    for (int f = 0; f < 120; ++f) {
        sim->beginFrame();
        for (int step = 0; step < sim->scene().substeps; ++step) {
            sim->runStep();
            ClothCandidates c = clothCandidates(sim->world());
            ASSERT_FALSE(c.gathered.empty());
            std::sort(c.vertexTriangle.begin(), c.vertexTriangle.end());
            std::sort(c.edgeEdge.begin(), c.edgeEdge.end());
            const std::vector<Vec3>& g = c.gathered;
            for (std::uint32_t t = 0; t < c.triangles.size(); ++t) {
                const Triangle& tri = c.triangles[t];
                for (std::uint32_t p = 0; p < g.size(); ++p) {
                    if (p == tri[0] || p == tri[1] || p == tri[2]) {
                        continue;
                    }
                    const double reach = 0.5 * (c.thickness[p] + c.thickness[tri[0]]) + c.margin[p] +
                                         std::max({c.margin[tri[0]], c.margin[tri[1]], c.margin[tri[2]]});
                    if (pointTriangle(g[p], g[tri[0]], g[tri[1]], g[tri[2]]) < reach) {
                        ++close;
                        const std::array<std::uint32_t, 2> key{p, t};
                        if (!std::binary_search(c.vertexTriangle.begin(), c.vertexTriangle.end(), key)) {
                            ADD_FAILURE()
                                << "step " << sim->step() << ": vertex " << p << " and triangle " << t;
                            ++missed;
                        }
                    }
                }
            }
            edges.clear();
            for (const Triangle& tri : c.triangles) {
                for (int k = 0; k < 3; ++k) {
                    edges.push_back({std::min(tri[k], tri[(k + 1) % 3]), std::max(tri[k], tri[(k + 1) % 3])});
                }
            }
            std::sort(edges.begin(), edges.end());
            edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
            for (std::size_t i = 0; i < edges.size(); ++i) {
                const auto [a0, a1] = edges[i];
                for (std::size_t j = i + 1; j < edges.size(); ++j) {
                    const auto [b0, b1] = edges[j];
                    if (a0 == b0 || a0 == b1 || a1 == b0 || a1 == b1) {
                        continue;
                    }
                    const double reach = 0.5 * (c.thickness[a0] + c.thickness[b0]) +
                                         std::max(c.margin[a0], c.margin[a1]) +
                                         std::max(c.margin[b0], c.margin[b1]);
                    if (segmentSegment(g[a0], g[a1], g[b0], g[b1]) < reach) {
                        ++close;
                        const std::array<std::uint32_t, 4> key{a0, a1, b0, b1};
                        if (!std::binary_search(c.edgeEdge.begin(), c.edgeEdge.end(), key)) {
                            ADD_FAILURE() << "step " << sim->step() << ": edges " << a0 << "-" << a1
                                          << " and " << b0 << "-" << b1;
                            ++missed;
                        }
                    }
                    if (missed > 20) {
                        FAIL() << "more than 20 pairs missed";
                    }
                }
            }
        }
        sim->endFrame(1.0);
    }
    EXPECT_EQ(missed, 0u);
    EXPECT_GT(close, 10000u); // the layers were in contact for most of the run: the check was not vacuous
    std::printf("pairs within reach: %zu over the run\n", close);
}

} // namespace
} // namespace tumble
