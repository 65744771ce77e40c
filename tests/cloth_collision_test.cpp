// Cloth self-collision: the geometric predicates against hand-made cases and references written here, the
// hierarchy against brute force, and two cloths dropped onto a ball onto each other
// (tests/cloth_contact_test.cpp judges every step of the demos and of random drops).

#include "components/spring_network.h"
#include "systems/bvh.h"
#include "systems/cloth_collision.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace tumble {
namespace {

using Pairs = std::vector<std::array<std::uint32_t, 2>>;

// ---- references written here, by other methods than the code under test

double pointSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double len2 = dot(ab, ab);
    const double t = len2 > 0.0 ? std::clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
    return length(p - (a + ab * t));
}

/// Point to triangle: the distance to the plane where the point's projection falls inside (signs of the
/// three sub-triangles' areas), else the nearest of the three edges.
double pointTriangleReference(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 n = cross(b - a, c - a);
    const double nn = dot(n, n);
    const Vec3 q = p - n * (dot(p - a, n) / nn);
    const bool inside = dot(cross(b - a, q - a), n) >= 0.0 && dot(cross(c - b, q - b), n) >= 0.0 &&
                        dot(cross(a - c, q - c), n) >= 0.0;
    if (inside) {
        return std::abs(dot(p - a, n)) / std::sqrt(nn);
    }
    return std::min({pointSegment(p, a, b), pointSegment(p, b, c), pointSegment(p, c, a)});
}

/// Segment to segment: the lines' closest points if both fall on the segments, else the nearest of the four
/// endpoint-to-segment distances (one of them is the minimum whenever an end is involved).
double segmentReference(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
    double best = std::min({pointSegment(p0, q0, q1), pointSegment(p1, q0, q1), pointSegment(q0, p0, p1),
                            pointSegment(q1, p0, p1)});
    const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = q0 - p0;
    const double a = dot(d1, d1), b = dot(d1, d2), e = dot(d2, d2), det = a * e - b * b;
    if (det > 1e-12 * a * e) {
        // d1 s - d2 t = r in the least-squares sense: [a -b; b -e] [s t] = [d1.r d2.r]
        const double s = (dot(d1, r) * e - b * dot(d2, r)) / det, t = (b * dot(d1, r) - a * dot(d2, r)) / det;
        if (s >= 0.0 && s <= 1.0 && t >= 0.0 && t <= 1.0) {
            best = std::min(best, length((p0 + d1 * s) - (q0 + d2 * t)));
        }
    }
    return best;
}

TEST(ClothGeometry, PointTriangleDistanceByHandAndAgainstTheReference) {
    const Vec3 a{0, 0, 0}, b{3, 0, 0}, c{0, 3, 0};
    double w[3];
    // above the inside: the height, with the projection's weights
    EXPECT_DOUBLE_EQ(pointTriangleDistance({1, 1, 2}, a, b, c, w), 2.0);
    EXPECT_NEAR(w[0], 1.0 / 3.0, 1e-15);
    EXPECT_NEAR(w[1], 1.0 / 3.0, 1e-15);
    EXPECT_NEAR(w[2], 1.0 / 3.0, 1e-15);
    // in the plane, beyond the long edge; beyond a corner; on the triangle
    EXPECT_NEAR(pointTriangleDistance({2, 2, 0}, a, b, c, w), std::sqrt(0.5), 1e-15);
    EXPECT_NEAR(pointTriangleDistance({-1, -2, 0}, a, b, c, w), std::sqrt(5.0), 1e-15);
    EXPECT_EQ(w[0], 1.0);
    EXPECT_EQ(pointTriangleDistance({0.5, 0.5, 0}, a, b, c, w), 0.0);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    auto any = [&] { return Vec3{u(rng), u(rng), u(rng)}; };
    for (int trial = 0; trial < 20000; ++trial) {
        const Vec3 ta = any(), tb = any(),
                   tc = trial % 7 == 0 ? ta + (any() - ta) * 1e-3 : any();                    // some slivers
        const Vec3 p = trial % 5 == 0 ? ta + (tb - ta) * u(rng) + (tc - ta) * u(rng) : any(); // some in-plane
        const double d = pointTriangleDistance(p, ta, tb, tc, w);
        const double scale = length(tb - ta) + length(tc - ta) + length(p - ta);
        ASSERT_NEAR(d, pointTriangleReference(p, ta, tb, tc), 1e-9 * scale) << "trial " << trial;
        // the weights name a point of the triangle at that distance
        ASSERT_NEAR(w[0] + w[1] + w[2], 1.0, 1e-12);
        for (double wi : w) {
            ASSERT_GE(wi, -1e-12);
        }
        ASSERT_NEAR(length(p - (ta * w[0] + tb * w[1] + tc * w[2])), d, 1e-12 * scale);
    }
}

TEST(ClothGeometry, SegmentDistanceByHandAndAgainstTheReference) {
    double s = 0.0, t = 0.0;
    // crossing at right angles, 0.3 apart
    EXPECT_NEAR(segmentDistance({-1, 0, 0}, {1, 0, 0}, {0, -1, 0.3}, {0, 1, 0.3}, s, t), 0.3, 1e-15);
    EXPECT_NEAR(s, 0.5, 1e-15);
    EXPECT_NEAR(t, 0.5, 1e-15);
    // parallel and overlapping, 0.2 apart (in one plane); collinear and overlapping; collinear with a gap
    EXPECT_NEAR(segmentDistance({0, 0, 0}, {2, 0, 0}, {1, 0.2, 0}, {3, 0.2, 0}, s, t), 0.2, 1e-15);
    EXPECT_NEAR(segmentDistance({0, 0, 0}, {2, 0, 0}, {1, 0, 0}, {3, 0, 0}, s, t), 0.0, 1e-15);
    EXPECT_NEAR(segmentDistance({0, 0, 0}, {2, 0, 0}, {2.5, 0, 0}, {3, 0, 0}, s, t), 0.5, 1e-15);
    // end to middle; a segment that is a point
    EXPECT_NEAR(segmentDistance({0, 0, 0}, {2, 0, 0}, {1, 1, 0}, {1, 3, 0}, s, t), 1.0, 1e-15);
    EXPECT_NEAR(segmentDistance({0, 0, 0}, {2, 0, 0}, {1, 1, 1}, {1, 1, 1}, s, t), std::sqrt(2.0), 1e-15);
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    auto any = [&] { return Vec3{u(rng), u(rng), u(rng)}; };
    for (int trial = 0; trial < 20000; ++trial) {
        Vec3 p0 = any(), p1 = any(), q0 = any();
        // some parallel or nearly parallel pairs, some in one plane
        Vec3 q1 = trial % 4 == 0 ? q0 + (p1 - p0) * u(rng) + (trial % 8 == 0 ? any() * 1e-9 : Vec3{}) : any();
        if (trial % 6 == 1) {
            q1.z = q0.z = p0.z = p1.z;
        }
        const double d = segmentDistance(p0, p1, q0, q1, s, t);
        const double scale = length(p1 - p0) + length(q1 - q0) + length(q0 - p0);
        ASSERT_NEAR(d, segmentReference(p0, p1, q0, q1), 1e-9 * scale) << "trial " << trial;
        ASSERT_GE(s, 0.0);
        ASSERT_LE(s, 1.0);
        ASSERT_GE(t, 0.0);
        ASSERT_LE(t, 1.0);
        ASSERT_NEAR(length((p0 + (p1 - p0) * s) - (q0 + (q1 - q0) * t)), d, 1e-12 * scale);
    }
}

TEST(ClothGeometry, TriangleIntersectionByHand) {
    const Vec3 a{0, 0, 0}, b{2, 0, 0}, c{0, 2, 0};
    auto meets = [&](const Vec3& p, const Vec3& q, const Vec3& r) {
        return trianglesIntersect(a, b, c, p, q, r);
    };
    // in one plane: overlapping, one inside the other, apart, touching at a corner, touching along an edge
    EXPECT_TRUE(meets({1, 1, 0}, {3, 1, 0}, {1, 3, 0}));
    EXPECT_TRUE(meets({0.2, 0.2, 0}, {0.5, 0.2, 0}, {0.2, 0.5, 0}));
    EXPECT_FALSE(meets({1.1, 1.1, 0}, {3, 1.1, 0}, {1.1, 3, 0}));
    EXPECT_TRUE(meets({2, 0, 0}, {3, 0, 0}, {3, 1, 0}));
    EXPECT_TRUE(meets({0, 0, 0}, {2, 0, 0}, {1, -1, 0}));
    // across the plane: piercing the inside, passing beside, an edge through the inside, a corner touching
    EXPECT_TRUE(meets({0.5, 0.5, -1}, {0.5, 0.5, 1}, {3, 3, 0}));
    EXPECT_FALSE(meets({1.5, 1.5, -1}, {1.5, 1.5, 1}, {3, 3, 0}));
    EXPECT_TRUE(meets({0.5, 0.5, 0}, {0.5, 0.5, 1}, {1, 2, 1}));
    EXPECT_FALSE(meets({0.5, 0.5, 1e-12}, {0.5, 0.5, 1}, {1, 2, 1})) << "a near miss is a miss";
    // parallel planes
    EXPECT_FALSE(meets({0, 0, 0.01}, {2, 0, 0.01}, {0, 2, 0.01}));
}

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
