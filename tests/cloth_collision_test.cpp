// Cloth self-collision: the hierarchy against brute force, and two cloths dropped onto a ball onto each
// other (tests/cloth_contact_test.cpp judges every step of the demos and of random drops).

#include "components/spring_network.h"
#include "systems/bvh.h"
#include "systems/cloth_collision.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace tumble {
namespace {

using Pairs = std::vector<std::array<std::uint32_t, 2>>;

std::vector<Aabb> boxesOf(const std::vector<Triangle>& tris, const std::vector<Vec3>& x) {
    std::vector<Aabb> boxes;
    for (const Triangle& t : tris) {
        boxes.push_back(triangleBox(t, x, {}, 0.01));
    }
    return boxes;
}

Pairs bruteSelf(const std::vector<Aabb>& boxes) {
    Pairs out;
    for (std::uint32_t i = 0; i < boxes.size(); ++i) {
        for (std::uint32_t j = i + 1; j < boxes.size(); ++j) {
            if (boxes[i].overlaps(boxes[j])) {
                out.push_back({i, j});
            }
        }
    }
    return out;
}

Pairs sorted(Pairs p) {
    std::sort(p.begin(), p.end());
    return p;
}

TEST(Bvh, SelfAndCrossQueriesAgreeWithBruteForceBeforeAndAfterRefits) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 5; ++trial) {
        // a random soup of small triangles in a unit cube, and a second one
        std::vector<Vec3> x(300), y(200);
        for (Vec3& p : x) {
            p = {u(rng), u(rng), u(rng)};
        }
        for (Vec3& p : y) {
            p = {u(rng), u(rng), u(rng)};
        }
        std::vector<Triangle> tx, ty;
        for (std::uint32_t i = 0; i + 2 < x.size(); i += 3) {
            // small triangles: corners near the first
            x[i + 1] = x[i] + Vec3{0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)};
            x[i + 2] = x[i] + Vec3{0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)};
            tx.push_back({i, i + 1, i + 2});
        }
        for (std::uint32_t i = 0; i + 2 < y.size(); i += 3) {
            y[i + 1] = y[i] + Vec3{0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)};
            y[i + 2] = y[i] + Vec3{0.1 * u(rng), 0.1 * u(rng), 0.1 * u(rng)};
            ty.push_back({i, i + 1, i + 2});
        }
        Bvh a, b;
        a.build(boxesOf(tx, x));
        b.build(boxesOf(ty, y));
        for (int move = 0; move < 4; ++move) {
            const std::vector<Aabb> bx = boxesOf(tx, x), by = boxesOf(ty, y);
            if (move > 0) {
                a.refit(bx);
                b.refit(by);
            }
            Pairs self, cross;
            a.selfPairs(self);
            a.pairsWith(b, cross);
            EXPECT_EQ(sorted(self), bruteSelf(bx)) << "trial " << trial << " move " << move;
            Pairs brute;
            for (std::uint32_t i = 0; i < bx.size(); ++i) {
                for (std::uint32_t j = 0; j < by.size(); ++j) {
                    if (bx[i].overlaps(by[j])) {
                        brute.push_back({i, j});
                    }
                }
            }
            EXPECT_EQ(sorted(cross), brute) << "trial " << trial << " move " << move;
            EXPECT_GT(self.size() + cross.size(), 0u) << "the test has something to find";
            // move every point a little: the tree is refitted, not rebuilt
            for (Vec3& p : x) {
                p += Vec3{0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)};
            }
            for (Vec3& p : y) {
                p += Vec3{0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)};
            }
        }
    }
}

TEST(Bvh, RefitAsksForARebuildWhenTheTreeLoosens) {
    std::vector<Vec3> x;
    std::vector<Triangle> tris;
    for (std::uint32_t i = 0; i < 64; ++i) {
        x.push_back({double(i), 0, 0});
        x.push_back({double(i) + 0.5, 0, 0});
        x.push_back({double(i), 0.5, 0});
        tris.push_back({3 * i, 3 * i + 1, 3 * i + 2});
    }
    Bvh tree;
    tree.build(boxesOf(tris, x));
    EXPECT_TRUE(tree.refit(boxesOf(tris, x)));
    // scatter the triangles: neighbours in the tree are now far apart
    for (std::uint32_t i = 0; i < 64; ++i) {
        const double shift = double((i * 37) % 64) - double(i);
        for (std::uint32_t k = 0; k < 3; ++k) {
            x[3 * i + k].y += shift;
        }
    }
    EXPECT_FALSE(tree.refit(boxesOf(tris, x)));
}

TEST(ClothCollision, TwoClothsDroppedOnABallStayApart) {
    // two sheets, one above the other, fall onto a ball and onto each other
    std::string text = R"(
[scene]
name = "two"
dt = 0.008333333333
substeps = 2
[[entity]]
name = "floor"
[entity.rigid_body]
shape = "plane"
[[entity]]
name = "ball"
[entity.transform]
position = [0.0, 0.4, 0.0]
[entity.rigid_body]
shape = "sphere"
radius = 0.4
)";
    for (const char* sheet : {"lower", "upper"}) {
        text += std::string("[[entity]]\nname = \"") + sheet + "\"\n[entity.transform]\nposition = [0.1, " +
                (sheet[0] == 'l' ? "1.0" : "1.3") +
                ", 0.05]\n[entity.cloth]\nrows = 20\ncols = 20\nsize = [1.2, 1.2]\nplane = \"xz\"\n"
                "stretch = 3000.0\nshear = 300.0\nbend = 1.0\npin = \"none\"\nthickness = 0.012\n"
                "self_collision = true\n";
    }
    auto sim = test::makeSimulation(text);
    for (int f = 0; f < 120; ++f) {
        sim->runFrame();
    }
    const SpringNetwork& a = test::component<SpringNetwork>(*sim, "lower");
    const SpringNetwork& b = test::component<SpringNetwork>(*sim, "upper");
    int crossings = 0;
    double nearest = 1e300;
    for (const Triangle& s : a.triangles) {
        for (const Triangle& t : b.triangles) {
            crossings += trianglesIntersect(a.x[s[0]], a.x[s[1]], a.x[s[2]], b.x[t[0]], b.x[t[1]], b.x[t[2]]);
        }
    }
    for (const Vec3& p : a.x) {
        for (const Triangle& t : b.triangles) {
            double w[3];
            nearest = std::min(nearest, pointTriangleDistance(p, b.x[t[0]], b.x[t[1]], b.x[t[2]], w));
        }
    }
    EXPECT_EQ(crossings, 0);
    // a crossing stopped within the step is left a tenth of the thickness apart (repulsion restores the
    // thickness over the next steps)
    EXPECT_GE(nearest, 0.09 * 0.012);
    EXPECT_LT(nearest, 0.05) << "the sheets lie on each other: the test had something to prevent";
}

} // namespace
} // namespace tumble
