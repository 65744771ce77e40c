// Continuous collision queries (systems/ccd.h): hard cases with answers worked out by hand, and random
// motions checked against brute force (the distance sampled densely over the step): a contact the samples
// see must be found, no later than the first sample that sees it.

#include "systems/ccd.h"
#include "systems/cloth_collision.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace tumble {
namespace {

struct Motion {
    Vec3 start[4];
    Vec3 end[4];
};

/// A unit right triangle in the plane z = 0, still; the vertex moves from `from` to `to`.
Motion vertexOverTriangle(const Vec3& from, const Vec3& to, double scale = 1.0) {
    Motion m;
    m.start[0] = from * scale;
    m.end[0] = to * scale;
    const Vec3 tri[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int k = 0; k < 3; ++k) {
        m.start[k + 1] = m.end[k + 1] = tri[k] * scale;
    }
    return m;
}

TEST(Ccd, VertexThroughTheFaceIsFoundWhereItCrosses) {
    // from z = 1 to z = -3: the plane at t = 1/4
    const Motion m = vertexOverTriangle({0.25, 0.25, 1.0}, {0.25, 0.25, -3.0});
    const CcdResult r = vertexTriangleCcd(m.start, m.end, 0.0);
    ASSERT_TRUE(r.hit);
    EXPECT_NEAR(r.toi, 0.25, 1e-5);
    EXPECT_LE(r.toi, 0.25);
    EXPECT_FALSE(r.capped);
}

TEST(Ccd, VertexPassingBesideTheFaceIsNotAContact) {
    // through the plane outside the triangle (beyond its hypotenuse), and above it without crossing
    EXPECT_FALSE(vertexTriangleCcd(vertexOverTriangle({0.6, 0.6, 1.0}, {0.6, 0.6, -1.0}).start,
                                   vertexOverTriangle({0.6, 0.6, 1.0}, {0.6, 0.6, -1.0}).end, 0.0)
                     .hit);
    const Motion above = vertexOverTriangle({-1.0, 0.2, 0.01}, {2.0, 0.2, 0.01});
    EXPECT_FALSE(vertexTriangleCcd(above.start, above.end, 0.005).hit);
    EXPECT_TRUE(vertexTriangleCcd(above.start, above.end, 0.02).hit) << "within the distance asked for";
}

TEST(Ccd, CoplanarMotionIsFoundAtTheEdge) {
    // the vertex slides in the triangle's own plane from outside into it: the cubic of the old test is zero
    // throughout, so it saw nothing; the contact is where it reaches the edge x = 0, at t = 1/3
    const Motion m = vertexOverTriangle({-1.0, 0.25, 0.0}, {2.0, 0.25, 0.0});
    const CcdResult r = vertexTriangleCcd(m.start, m.end, 0.0);
    ASSERT_TRUE(r.hit);
    EXPECT_NEAR(r.toi, 1.0 / 3.0, 1e-5);
    EXPECT_LE(r.toi, 1.0 / 3.0 + 1e-12);
}

TEST(Ccd, VertexGrazingAnEdgeTouchesIt) {
    // the vertex crosses the line of the edge from (0,0,0) to (1,0,0) exactly at (0.5, 0, 0), at t = 1/2
    const Motion m = vertexOverTriangle({0.5, -0.5, 0.5}, {0.5, 0.5, -0.5});
    const CcdResult r = vertexTriangleCcd(m.start, m.end, 0.0);
    ASSERT_TRUE(r.hit);
    EXPECT_NEAR(r.toi, 0.5, 1e-5);
    // a hair outside the edge (it crosses the plane at y = -1e-4): no contact at distance 0
    const Motion miss = vertexOverTriangle({0.5, -0.5001, 0.5}, {0.5, 0.4999, -0.5});
    EXPECT_FALSE(vertexTriangleCcd(miss.start, miss.end, 0.0).hit);
}

TEST(Ccd, ContactAtTheStartAndAtTheEndOfTheStep) {
    const Motion atStart = vertexOverTriangle({0.2, 0.2, 0.0}, {0.2, 0.2, 1.0});
    const CcdResult a = vertexTriangleCcd(atStart.start, atStart.end, 0.0);
    ASSERT_TRUE(a.hit);
    EXPECT_EQ(a.toi, 0.0);
    const Motion atEnd = vertexOverTriangle({0.2, 0.2, 1.0}, {0.2, 0.2, 0.0});
    const CcdResult b = vertexTriangleCcd(atEnd.start, atEnd.end, 0.0);
    ASSERT_TRUE(b.hit);
    EXPECT_NEAR(b.toi, 1.0, 1e-5);
}

TEST(Ccd, ParallelEdgesMeetingSideBySide) {
    // two parallel edges along x, 1 apart in y, closing at unit speed each: they meet at t = 1/2
    Motion m;
    m.start[0] = {0, 0, 0};
    m.start[1] = {1, 0, 0};
    m.start[2] = {0.5, 1, 0};
    m.start[3] = {1.5, 1, 0};
    for (int k = 0; k < 4; ++k) {
        m.end[k] = m.start[k] + Vec3{0.0, k < 2 ? 1.0 : -1.0, 0.0};
    }
    const CcdResult r = edgeEdgeCcd(m.start, m.end, 0.0);
    ASSERT_TRUE(r.hit);
    EXPECT_NEAR(r.toi, 0.5, 1e-5);
    // the same, but apart along x (their ends do not overlap): never closer than 0.5
    for (int k = 2; k < 4; ++k) {
        m.start[k].x += 1.0;
        m.end[k].x += 1.0;
    }
    EXPECT_FALSE(edgeEdgeCcd(m.start, m.end, 0.4).hit);
    EXPECT_TRUE(edgeEdgeCcd(m.start, m.end, 0.6).hit);
}

TEST(Ccd, CrossingEdgesAtEveryScale) {
    // an edge along x at z = 1 moving down through an edge along y at z = 0: contact at t = 1/2
    for (double scale : {1e-6, 1e-3, 1.0, 1e3, 1e6}) {
        Motion m;
        m.start[0] = Vec3{-1, 0, 1} * scale;
        m.start[1] = Vec3{1, 0, 1} * scale;
        m.end[0] = Vec3{-1, 0, -1} * scale;
        m.end[1] = Vec3{1, 0, -1} * scale;
        m.start[2] = m.end[2] = Vec3{0, -1, 0} * scale;
        m.start[3] = m.end[3] = Vec3{0, 1, 0} * scale;
        const CcdResult r = edgeEdgeCcd(m.start, m.end, 0.0);
        ASSERT_TRUE(r.hit) << scale;
        EXPECT_NEAR(r.toi, 0.5, 1e-5) << scale;
        // and far from the origin: coordinates 1e4 times the motion
        const Vec3 far{1e4 * scale, -2e4 * scale, 3e4 * scale};
        for (int k = 0; k < 4; ++k) {
            m.start[k] += far;
            m.end[k] += far;
        }
        const CcdResult f = edgeEdgeCcd(m.start, m.end, 0.0);
        ASSERT_TRUE(f.hit) << scale;
        EXPECT_NEAR(f.toi, 0.5, 1e-4) << scale;
        const Motion v = vertexOverTriangle({0.25, 0.25, 1.0}, {0.25, 0.25, -1.0}, scale);
        const CcdResult vt = vertexTriangleCcd(v.start, v.end, 0.0);
        ASSERT_TRUE(vt.hit) << scale;
        EXPECT_NEAR(vt.toi, 0.5, 1e-5) << scale;
    }
}

TEST(Ccd, TriangleSweepingOverAStillVertex) {
    // the triangle moves and rotates; the vertex stays: the face reaches it at t = 0.4 (all move linearly)
    Motion m;
    m.start[0] = m.end[0] = {0.3, 0.3, 0.0};
    const Vec3 tri[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int k = 0; k < 3; ++k) {
        m.start[k + 1] = tri[k] + Vec3{0, 0, -0.4};
        m.end[k + 1] = tri[k] + Vec3{0, 0, 0.6};
    }
    const CcdResult r = vertexTriangleCcd(m.start, m.end, 0.0);
    ASSERT_TRUE(r.hit);
    EXPECT_NEAR(r.toi, 0.4, 1e-5);
}

/// Distance of the query's primitives at time t (the closest-point routines, not the search).
double distanceAt(const Motion& m, bool vertexTriangle, double t) {
    Vec3 x[4];
    for (int k = 0; k < 4; ++k) {
        x[k] = m.start[k] + (m.end[k] - m.start[k]) * t;
    }
    if (vertexTriangle) {
        double w[3];
        return pointTriangleDistance(x[0], x[1], x[2], x[3], w);
    }
    double s = 0.0, u = 0.0;
    return segmentDistance(x[0], x[1], x[2], x[3], s, u);
}

TEST(Ccd, NeverLaterThanBruteForceOnRandomMotions) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int contacts = 0, misses = 0, capped = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        const bool vt = trial % 2 == 0;
        Motion m;
        for (int k = 0; k < 4; ++k) {
            m.start[k] = {u(rng), u(rng), u(rng)};
            m.end[k] = m.start[k] + Vec3{u(rng), u(rng), u(rng)} * 0.7;
        }
        // sometimes flatten the motion into one plane, where the cubic's roots are lost
        if (trial % 5 == 0) {
            for (int k = 0; k < 4; ++k) {
                m.start[k].z = m.end[k].z = 0.0;
            }
        }
        const double distance = 0.01;
        const CcdResult r =
            vt ? vertexTriangleCcd(m.start, m.end, distance) : edgeEdgeCcd(m.start, m.end, distance);
        double first = -1.0;
        const int samples = 2000;
        for (int s = 0; s <= samples; ++s) {
            const double t = double(s) / samples;
            if (distanceAt(m, vt, t) < distance) {
                first = t;
                break;
            }
        }
        if (first >= 0.0) {
            ++contacts;
            ASSERT_TRUE(r.hit) << "trial " << trial << ": brute force touches at t = " << first;
            EXPECT_LE(r.toi, first + 1e-9) << "trial " << trial;
        } else {
            misses += !r.hit;
        }
        capped += r.capped;
        if (r.hit && !r.capped) {
            // what it reports is real: within sqrt(3) * distance (the box test is per coordinate) and the
            // tolerance, at the time it reports
            EXPECT_LT(distanceAt(m, vt, r.toi), std::sqrt(3.0) * distance + 2e-3)
                << "trial " << trial << (r.capped ? " capped" : "");
        }
    }
    EXPECT_GT(contacts, 300) << "the random motions must meet often enough to test something";
    EXPECT_GT(misses, 300);
    // a capped query answers early (safe, but a contact where there may be none): hard cases only
    EXPECT_LT(capped, 15);
}

} // namespace
} // namespace tumble
