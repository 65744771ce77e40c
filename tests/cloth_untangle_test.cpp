// Cloth that is crossed already comes clean: two sheets passing through each other, a sheet folded through
// itself, and a mass dragged through the sheet by hand, each judged after every step by the tests' own
// reference (tests/contact_reference.h). The contour gradient is checked against finite differences of
// the contour's length computed here.

#include "components/spring_network.h"
#include "engine/profiler.h"
#include "engine/run_report.h"
#include "systems/cloth_collision.h"
#include "systems/cloth_untangle.h"
#include "tests/contact_reference.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

namespace tumble {
namespace {

/// The length of the segment along which two triangles meet, computed directly: the points where each
/// triangle's edges pass through the other's plane inside it (general position assumed).
double segmentLength(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b) {
    std::vector<Vec3> ends;
    auto cut = [&](const std::array<Vec3, 3>& edges, const std::array<Vec3, 3>& tri) {
        const Vec3 n = cross(tri[1] - tri[0], tri[2] - tri[0]);
        for (int k = 0; k < 3; ++k) {
            const Vec3 p = edges[k], q = edges[(k + 1) % 3];
            const double dp = dot(n, p - tri[0]), dq = dot(n, q - tri[0]);
            if (dp * dq >= 0.0) {
                continue;
            }
            const Vec3 x = p + (q - p) * (dp / (dp - dq));
            bool inside = true;
            for (int j = 0; j < 3; ++j) {
                inside = inside && dot(n, cross(tri[(j + 1) % 3] - tri[j], x - tri[j])) >= 0.0;
            }
            if (inside) {
                ends.push_back(x);
            }
        }
    };
    cut(a, b);
    cut(b, a);
    return ends.size() == 2 ? length(ends[1] - ends[0]) : 0.0;
}

TEST(ContourGradient, MatchesFiniteDifferencesOfTheSegmentLength) {
    // two triangles crossing in general position; the gradient is of each triangle moved as a whole, so
    // it is checked against moving each triangle rigidly
    const std::vector<Vec3> x{{0, 0, 0},        {1, 0.1, 0},     {0.2, 0.05, 1},
                              {0.3, -0.5, 0.4}, {0.6, 0.7, 0.3}, {0.1, 0.6, 0.6}};
    const std::vector<Triangle> tris{{0, 1, 2}, {3, 4, 5}};
    const std::vector<std::array<std::uint32_t, 2>> pairs{{0, 1}};
    std::vector<Vec3> grad(x.size());
    const double len = contourGradient(x, tris, pairs, grad);
    auto tri = [&](const std::vector<Vec3>& y, int t) {
        return std::array<Vec3, 3>{y[tris[t][0]], y[tris[t][1]], y[tris[t][2]]};
    };
    ASSERT_GT(len, 0.1);
    EXPECT_NEAR(len, segmentLength(tri(x, 0), tri(x, 1)), 1e-12);
    // the second triangle as a whole: the sum of its corners' shares is the derivative of the length
    // when it translates
    const Vec3 onSecond = grad[3] + grad[4] + grad[5];
    for (int axis = 0; axis < 3; ++axis) {
        const double h = 1e-6;
        std::vector<Vec3> plus = x, minus = x;
        for (int k = 3; k < 6; ++k) {
            (&plus[k].x)[axis] += h;
            (&minus[k].x)[axis] -= h;
        }
        const double numeric =
            (segmentLength(tri(plus, 0), tri(plus, 1)) - segmentLength(tri(minus, 0), tri(minus, 1))) /
            (2.0 * h);
        EXPECT_NEAR((&onSecond.x)[axis], numeric, 1e-6) << "axis " << axis;
    }
    // moving both together changes nothing: the shares cancel
    Vec3 total;
    for (const Vec3& g : grad) {
        total += g;
    }
    EXPECT_NEAR(length(total), 0.0, 1e-12);
    // a pair that does not cross adds nothing
    std::vector<Vec3> apart = x;
    for (int k = 3; k < 6; ++k) {
        apart[k].y += 5.0;
    }
    std::vector<Vec3> none(x.size());
    EXPECT_EQ(contourGradient(apart, tris, pairs, none), 0.0);
    EXPECT_EQ(length(none[0]) + length(none[3]), 0.0);
}

/// A scene of flat sheets lying in xz (placed by the test afterwards), 120 steps a second, over the ground.
struct Sheet {
    std::string name;
    int n;              ///< masses a side
    double width = 1.0; ///< m, along x (1 m along z)
};

std::string sheets(const std::vector<Sheet>& cloths, double thickness) {
    std::ostringstream s;
    s << "[scene]\nname = \"tangle\"\ndt = 0.008333333333\nsubsteps = 1\nframes = 60\n"
      << "[[entity]]\nname = \"floor\"\n[entity.rigid_body]\nshape = \"plane\"\n";
    for (const auto& [name, n, width] : cloths) {
        s << "[[entity]]\nname = \"" << name << "\"\n[entity.transform]\nposition = [0.0, 1.0, 0.0]\n"
          << "[entity.cloth]\nrows = " << n << "\ncols = " << n << "\nsize = [" << width
          << ", 1.0]\nplane = \"xz\"\n"
          << "stretch = 3000.0\nshear = 300.0\nbend = 1.0\npin = \"none\"\nintegrator = \"implicit_euler\"\n"
          << "thickness = " << thickness << "\nself_collision = true\n";
    }
    return s.str();
}

/// Puts a network's masses where `place` says (as loaded: the start of the first step too).
template <class F>
void place(Simulation& sim, const std::string& name, F&& where) {
    SpringNetwork& net = test::component<SpringNetwork>(sim, name);
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        net.x[i] = where(net.x[i]);
    }
    test::component<ClothCollision>(sim, name).previous = net.x;
}

struct Recovery {
    int start = 0;        ///< crossed pairs before the first step
    int cleanAt = -1;     ///< the first step after which none is crossed
    int afterwards = 0;   ///< the most crossed after that
    double fastest = 0.0; ///< m/s, the fastest mass over the run
};

/// Steps the scene, counting crossed pairs by the reference after every step (the audit on, so a crossing
/// between parts that were not tangled would fail the run).
Recovery recover(Simulation& sim, const std::vector<std::string>& cloths, int steps) {
    sim.world().setResource<RunChecks>().contact = true;
    std::vector<test::Surface> surfaces;
    std::vector<const SpringNetwork*> nets;
    for (const std::string& c : cloths) {
        nets.push_back(&test::component<SpringNetwork>(sim, c));
        surfaces.push_back({&nets.back()->x, &nets.back()->triangles});
    }
    Recovery r;
    r.start = test::countCrossings(surfaces);
    for (int k = 1; k <= steps; ++k) {
        sim.beginFrame();
        sim.runStep();
        sim.endFrame(1.0);
        const int crossed = test::countCrossings(surfaces);
        if (crossed == 0 && r.cleanAt < 0) {
            r.cleanAt = k;
        } else if (r.cleanAt >= 0) {
            r.afterwards = std::max(r.afterwards, crossed);
        }
        for (const SpringNetwork* net : nets) {
            for (const Vec3& v : net->v) {
                r.fastest = std::max(r.fastest, std::isfinite(length(v)) ? length(v) : 1e300);
            }
        }
    }
    for (const std::string& failure : sim.world().resource<RunReport>().failures) {
        ADD_FAILURE() << failure;
    }
    return r;
}

/// A sheet lying flat and a narrower one tilted 30 degrees through it (it crosses the first along a line
/// from one of its own sides to the other), raised by `lift` (0: a row of its masses lies exactly in the
/// flat sheet's plane).
void twoSheets(double lift) {
    auto sim = test::makeSimulation(sheets({{"flat", 21}, {"tilted", 15, 0.6}}, 0.02));
    place(*sim, "flat", [](Vec3 p) { return p + Vec3{0.013, 0.0, 0.007}; });
    place(*sim, "tilted", [lift](Vec3 p) {
        const double c = std::cos(0.5236), s = std::sin(0.5236);
        const Vec3 q = p - Vec3{0.0, 1.0, 0.0};
        return Vec3{q.x, 1.0 + lift + s * q.z, c * q.z};
    });
    const Recovery r = recover(*sim, {"flat", "tilted"}, 60);
    EXPECT_GT(r.start, 10);
    EXPECT_GE(r.cleanAt, 1);
    EXPECT_LE(r.cleanAt, 30) << r.start << " pairs crossed at the start";
    EXPECT_EQ(r.afterwards, 0);
    EXPECT_LT(r.fastest, 20.0);
    const ClothContactStats& stats = sim->world().resource<ClothContactStats>();
    EXPECT_EQ(stats.tangled, 0u);
    EXPECT_GE(stats.stepsTangled, 1u);
    // the profile counts the crossed pairs after every step: some at first, none at the end
    bool counted = false;
    for (const CounterStats& c : sim->profiler().counterStats()) {
        if (c.name == "cloth_collision.tangled_pairs") {
            counted = true;
            EXPECT_EQ(c.samples, 60u);
            EXPECT_GE(c.max, 10.0);
            EXPECT_GE(c.nonzero, 1u);
            EXPECT_LE(c.nonzero, 30u);
            EXPECT_EQ(c.last, 0.0);
        }
    }
    EXPECT_TRUE(counted);
}

TEST(ChooseRegions, ARowLyingInTheSheetGoesBackThroughIt) {
    // A strip hangs through a sheet with its top row exactly in the sheet's plane. A point in the plane
    // counts as on the positive side, so the strip's edges from that row down are the cuts, and the row
    // alone (smaller than the rest of the strip) is the region to pass back through: towards the negative
    // side, where the rest of the strip is. (Sent the other way, the row went up a quarter of an edge and
    // came back the next round, over and over.)
    std::vector<Vec3> x = {{-1.0, 0.0, -1.0}, {1.0, 0.0, -1.0}, {1.0, 0.0, 1.0}, {-1.0, 0.0, 1.0}};
    std::vector<Triangle> tris = {{0, 1, 2}, {0, 2, 3}};
    const Vec3 n = cross(x[2] - x[0], x[3] - x[0]) * (1.0 / length(cross(x[2] - x[0], x[3] - x[0])));
    for (int row = 0; row < 4; ++row) {
        for (int col = 0; col < 3; ++col) {
            x.push_back(Vec3{-0.2 + 0.2 * col, 0.0, 0.5} - n * (0.1 * row));
        }
    }
    auto at = [](int row, int col) { return std::uint32_t(4 + 3 * row + col); };
    std::vector<std::array<std::uint32_t, 2>> crossed;
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 2; ++col) {
            tris.push_back({at(row, col), at(row + 1, col), at(row, col + 1)});
            tris.push_back({at(row, col + 1), at(row + 1, col), at(row + 1, col + 1)});
            if (row == 0) {
                crossed.push_back({1, std::uint32_t(tris.size() - 2)});
                crossed.push_back({1, std::uint32_t(tris.size() - 1)});
            }
        }
    }
    VertexGraph graph;
    graph.build(x.size(), tris);
    RegionChoice choice;
    chooseRegions(x, tris, graph, crossed, std::vector<std::uint8_t>(x.size(), 0), choice);
    ASSERT_EQ(choice.chosen, 1u);
    for (int col = 0; col < 3; ++col) {
        EXPECT_NEAR(dot(choice.direction[at(0, col)], n), -1.0, 1e-12) << "column " << col;
        EXPECT_EQ(choice.direction[at(1, col)], Vec3{}); // the rest of the strip stays
    }
}

TEST(Untangle, TwoSheetsPassingThroughEachOther) {
    twoSheets(0.0031);
}

TEST(Untangle, TwoSheetsCrossingExactlyAtARowOfMasses) {
    twoSheets(0.0);
}

TEST(Untangle, SheetFoldedThroughItself) {
    // the far half turned over a rounded fold of radius 5 cm and brought back down at 15 degrees, so that
    // it passes through the near half about 37 cm from the fold
    auto sim = test::makeSimulation(sheets({{"sheet", 25}}, 0.02));
    place(*sim, "sheet", [](Vec3 p) {
        const double r = 0.05, slope = std::tan(0.4363), pi = 3.14159265358979;
        const double d = p.z + 0.013; // past the fold line (z = -0.013)
        if (d <= 0.0) {
            return p;
        }
        if (d < pi * r) {
            return Vec3{p.x, 1.0 + r * (1.0 - std::cos(d / r)), -0.013 + r * std::sin(d / r)};
        }
        return Vec3{p.x, 1.0 + 2.0 * r - slope * (d - pi * r), -0.013 - (d - pi * r)};
    });
    const Recovery r = recover(*sim, {"sheet"}, 60);
    EXPECT_GT(r.start, 10);
    EXPECT_GE(r.cleanAt, 1);
    // clean in 29 steps with the solver's bits of replay format 2, 34 with those of format 3: how long the
    // springs take to stop pulling the part back depends on rounding, so the bound has room for it
    EXPECT_LE(r.cleanAt, 40) << r.start << " pairs crossed at the start";
    EXPECT_EQ(r.afterwards, 0);
    EXPECT_LT(r.fastest, 20.0);
}

TEST(Untangle, MassPulledThroughTheSheetByHand) {
    // two layers (a sheet folded flat over itself, 3 cm apart); after a few steps, one mass of the upper
    // layer is put 4 cm below the lower one by hand, as a viewer dragging it directly would, and the
    // contact told to look (ClothCollision::recheck)
    auto sim = test::makeSimulation(sheets({{"sheet", 21}}, 0.02));
    place(*sim, "sheet", [](Vec3 p) {
        const double r = 0.015, pi = 3.14159265358979;
        const double d = p.z + 0.013;
        if (d <= 0.0) {
            return p;
        }
        if (d < pi * r) {
            return Vec3{p.x, 1.0 + r * (1.0 - std::cos(d / r)), -0.013 + r * std::sin(d / r)};
        }
        return Vec3{p.x, 1.0 + 2.0 * r, -0.013 - (d - pi * r)};
    });
    std::vector<std::string> cloths{"sheet"};
    ASSERT_EQ(recover(*sim, cloths, 5).start, 0);
    SpringNetwork& net = test::component<SpringNetwork>(*sim, "sheet");
    // the mass of the upper layer nearest above the middle of the lower half
    double lowest = 1e300;
    for (const Vec3& p : net.x) {
        lowest = std::min(lowest, p.y);
    }
    std::size_t held = 0;
    double best = 1e300;
    for (std::size_t i = 0; i < net.x.size(); ++i) {
        const double across = std::hypot(net.x[i].x, net.x[i].z + 0.25);
        if (net.x[i].y > lowest + 0.02 && across < best) {
            best = across;
            held = i;
        }
    }
    ASSERT_LT(best, 0.05);
    net.x[held].y -= 0.07;
    test::component<ClothCollision>(*sim, "sheet").previous = net.x;
    test::component<ClothCollision>(*sim, "sheet").recheck = true;
    const Recovery r = recover(*sim, cloths, 40);
    EXPECT_GT(r.start, 0);
    EXPECT_GE(r.cleanAt, 1);
    EXPECT_LE(r.cleanAt, 30) << r.start << " pairs crossed after the drag";
    EXPECT_EQ(r.afterwards, 0);
}

TEST(Untangle, DragEventCannotPullAMassThroughTheSheet) {
    // the same two layers, and the mouse spring (a scripted grab and drag, as the viewer records them)
    // pulling a mass of the upper sheet down through the lower one and the ground below it for half a
    // second: the contact holds it on its side
    std::string text = sheets({{"sheet", 21}}, 0.02);
    auto probe = test::makeSimulation(text);
    const SpringNetwork& flat = test::component<SpringNetwork>(*probe, "sheet");
    std::size_t held = 0;
    for (std::size_t i = 0; i < flat.x.size(); ++i) {
        if (length(flat.x[i] - Vec3{0.0, 1.0, 0.0}) < length(flat.x[held] - Vec3{0.0, 1.0, 0.0})) {
            held = i;
        }
    }
    // a second sheet 3 cm under the first, and the grab on the upper one's middle mass
    text = sheets({{"sheet", 21}, {"under", 21}}, 0.02) +
           "[[event]]\nframe = 10\nentity = \"sheet\"\naction = \"grab\"\n" + "value = [" +
           std::to_string(held) + "]\nposition = [0.0, 1.0, 0.0]\n" +
           "[[event]]\nframe = 11\nentity = \"sheet\"\naction = \"drag\"\nposition = [0.0, -0.3, 0.0]\n" +
           "[[event]]\nframe = 70\nentity = \"sheet\"\naction = \"release\"\n";
    auto sim = test::makeSimulation(text);
    place(*sim, "under", [](Vec3 p) { return p + Vec3{0.011, -0.03, 0.007}; });
    const Recovery r = recover(*sim, {"sheet", "under"}, 100);
    EXPECT_EQ(r.start, 0);
    EXPECT_EQ(r.cleanAt, 1);
    EXPECT_EQ(r.afterwards, 0);
    EXPECT_LT(r.fastest, 20.0);
}

} // namespace
} // namespace tumble
