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

#include <cmath>
#include <cstdlib>
#include <random>
#include <sstream>

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
            d = std::max(d, std::min({boxHalf.x - std::abs(q.x), boxHalf.y - std::abs(q.y), boxHalf.z - std::abs(q.z)}));
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

/// Runs the scene step by step and judges every step.
Outcome judge(const std::string& text, const std::vector<std::string>& cloths, const Colliders& colliders, int frames) {
    auto sim = test::simulate(text);
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
        auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
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
              << col.ballCentre.y << ", " << col.ballCentre.z << "]\n[entity.rigid_body]\nshape = \"sphere\"\nradius = "
              << col.ballRadius << "\n";
        } else if (what == 2) {
            col.box = true;
            col.boxHalf = {uniform(0.15, 0.3), uniform(0.1, 0.25), uniform(0.15, 0.3)};
            col.boxCentre = {uniform(-0.1, 0.1), col.boxHalf.y, uniform(-0.1, 0.1)};
            s << "[[entity]]\nname = \"table\"\n[entity.transform]\nposition = [" << col.boxCentre.x << ", "
              << col.boxCentre.y << ", " << col.boxCentre.z << "]\n[entity.rigid_body]\nshape = \"box\"\nhalf_extents = ["
              << col.boxHalf.x << ", " << col.boxHalf.y << ", " << col.boxHalf.z << "]\n";
        }
        const int clothCount = integer(1, 3);
        std::vector<std::string> names;
        for (int c = 0; c < clothCount; ++c) {
            const int n = integer(10, 40);
            const double size = uniform(0.8, 1.4);
            const double spacing = size / (n - 1);
            const double thickness = uniform(0.3, 0.9) * spacing;
            names.push_back("cloth" + std::to_string(c));
            s << "[[entity]]\nname = \"" << names.back() << "\"\n[entity.transform]\nposition = [" << uniform(-0.25, 0.25)
              << ", " << 0.9 + 0.25 * c + uniform(0.0, 0.1) << ", " << uniform(-0.25, 0.25) << "]\n[entity.cloth]\nrows = "
              << n << "\ncols = " << n << "\nsize = [" << size << ", " << size
              << "]\nplane = \"xz\"\nstretch = 3000.0\nshear = 300.0\nbend = " << uniform(0.1, 5.0)
              << "\npin = \"none\"\nintegrator = \"implicit_euler\"\nthickness = " << thickness
              << "\nself_collision = true\n";
        }
        // kept, so that a failure can be run again: tumble run FILE --check-contact
        const std::string file = test::writeTemp("drop_" + std::to_string(seed) + ".toml", s.str());
        const Outcome o = judge(s.str(), names, col, 240);
        EXPECT_EQ(o.worstCrossings, 0) << "seed " << seed << ": first at step " << o.stepOfFirst << " (" << file << ")";
        EXPECT_LE(o.deepest, 1e-9) << "seed " << seed << ": a mass deeper than its thickness in a collider (" << file
                                   << ")";
        EXPECT_EQ(o.steps, 480u);
    }
}

INSTANTIATE_TEST_SUITE_P(Seeds, RandomDrop, ::testing::Range(1, 21));

class SelfCollidingDemo : public ::testing::TestWithParam<const char*> {};

TEST_P(SelfCollidingDemo, NeverCrossesAfterAnyStep) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + GetParam() + ".toml";
    const std::string text = test::readFile(path);
    auto sim = test::simulate(text);
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

INSTANTIATE_TEST_SUITE_P(Demos, SelfCollidingDemo, ::testing::Values("pile", "drape_sphere", "tablecloth", "twist"),
                         [](const auto& param) { return std::string(param.param); });

} // namespace
} // namespace tumble
