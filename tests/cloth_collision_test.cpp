// Cloth self-collision: the hierarchy against brute force, and cloths that fold onto themselves (the pile
// and drape_sphere demos) checked afterwards by exact tests over every pair: no two triangles that share no
// corner intersect, and no mass comes closer than half the thickness to a triangle that is not its
// neighbour on the surface.

#include "components/spring_network.h"
#include "systems/bvh.h"
#include "systems/cloth_collision.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

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

/// The worst of the exact checks over a cloth: intersecting pairs of triangles that share no corner, and
/// the nearest approach of a mass to a triangle none of whose corners shares a triangle with it.
struct Check {
    int intersections = 0;
    double nearest = 1e300;
};

Check checkCloth(const SpringNetwork& net) {
    // neighbours on the surface: masses that share a triangle
    std::vector<std::set<std::uint32_t>> linked(net.x.size());
    for (const Triangle& tri : net.triangles) {
        for (std::uint32_t a : tri) {
            for (std::uint32_t b : tri) {
                linked[a].insert(b);
            }
        }
    }
    Check c;
    const auto& t = net.triangles;
    for (std::size_t i = 0; i < t.size(); ++i) {
        for (std::size_t j = i + 1; j < t.size(); ++j) {
            bool share = false;
            for (std::uint32_t a : t[i]) {
                share = share || a == t[j][0] || a == t[j][1] || a == t[j][2];
            }
            if (!share && trianglesIntersect(net.x[t[i][0]], net.x[t[i][1]], net.x[t[i][2]], net.x[t[j][0]],
                                             net.x[t[j][1]], net.x[t[j][2]])) {
                ++c.intersections;
            }
        }
    }
    for (std::uint32_t p = 0; p < net.x.size(); ++p) {
        for (const Triangle& tri : t) {
            bool near = false;
            for (std::uint32_t k : tri) {
                near = near || k == p || linked[p].count(k) > 0;
            }
            if (!near) {
                double w[3];
                const double d = pointTriangleDistance(net.x[p], net.x[tri[0]], net.x[tri[1]], net.x[tri[2]], w);
                c.nearest = std::min(c.nearest, d);
            }
        }
    }
    return c;
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
    auto sim = test::simulate(text);
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
    EXPECT_GE(nearest, 0.5 * 0.012);
    EXPECT_LT(nearest, 0.05) << "the sheets lie on each other: the test had something to prevent";
}

class FoldingDemo : public ::testing::TestWithParam<std::pair<const char*, int>> {};

TEST_P(FoldingDemo, NoTwoSheetsPassThroughOrTouchEachOther) {
    const auto [demo, frames] = GetParam();
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + demo + ".toml";
    auto sim = test::simulate(test::readFile(path));
    const SpringNetwork& net = test::component<SpringNetwork>(*sim, "sheet");
    int worstIntersections = 0;
    double nearest = 1e300;
    for (int f = 1; f <= frames; ++f) {
        sim->runFrame();
        if (f % 40 == 0 || f == frames) {
            const Check c = checkCloth(net);
            worstIntersections = std::max(worstIntersections, c.intersections);
            nearest = std::min(nearest, c.nearest);
        }
    }
    EXPECT_EQ(worstIntersections, 0) << demo;
    EXPECT_GE(nearest, 0.5 * net.thickness) << demo;
    const ClothCollision& cc = test::component<ClothCollision>(*sim, "sheet");
    EXPECT_FALSE(cc.tree.empty());
}

INSTANTIATE_TEST_SUITE_P(Cloth, FoldingDemo,
                         ::testing::Values(std::pair{"pile", 240}, std::pair{"drape_sphere", 240}),
                         [](const auto& param) { return std::string(param.param.first); });

} // namespace
} // namespace tumble
