// Height-field water against physics: a crest travels at the wave speed; without damping the
// wave energy stays bounded; a step beyond the CFL limit is taken in stable substeps; a floating box
// settles at the draft its density predicts.

#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "components/water.h"
#include "engine/run_report.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace tumble {
namespace {

std::string pool(double dt, const std::string& water, const std::string& rest = "") {
    char step[32];
    std::snprintf(step, sizeof step, "%.17g", dt);
    return std::string("[scene]\nname = \"w\"\ndt = ") + step +
           "\n[[entity]]\nname = \"pond\"\n[entity.water]\n" + water + rest;
}

/// Wave energy: kinetic (1/2) v^2 and potential (1/2) c^2 |grad h|^2, summed over the grid (per unit
/// density and area).
double energy(const Water& w) {
    double e = 0.0;
    const double c2 = w.waveSpeed * w.waveSpeed;
    for (int k = 0; k < w.nz; ++k) {
        for (int i = 0; i < w.nx; ++i) {
            const std::size_t n = std::size_t(k) * w.nx + i;
            e += 0.5 * w.v[n] * w.v[n];
            if (i + 1 < w.nx) {
                const double s = (w.h[n + 1] - w.h[n]) / w.dx();
                e += 0.5 * c2 * s * s;
            }
            if (k + 1 < w.nz) {
                const double s = (w.h[n + std::size_t(w.nx)] - w.h[n]) / w.dz();
                e += 0.5 * c2 * s * s;
            }
        }
    }
    return e * w.dx() * w.dz();
}

/// Where the highest point of the surface along x is, between x0 and x1 (m), refined by the parabola
/// through the highest node and its two neighbours (the grid's middle row).
double crestBetween(const Water& w, double x0, double x1) {
    const std::size_t row = std::size_t(w.nz / 2) * w.nx;
    int best = -1;
    for (int i = 1; i + 1 < w.nx; ++i) {
        if (w.nodeX(i) >= x0 && w.nodeX(i) <= x1 && (best < 0 || w.h[row + i] > w.h[row + best])) {
            best = i;
        }
    }
    const double a = w.h[row + best - 1], b = w.h[row + best], c = w.h[row + best + 1];
    return w.nodeX(best) + 0.5 * (a - c) / (a - 2.0 * b + c) * w.dx();
}

TEST(Water, ACrestTravelsAtTheWaveSpeed) {
    // a channel 40 m long and 10 cm wide (5 cm cells, c = 2 m/s, reflecting sides): a bump splits into two
    // crests that run at c each way; the one running right is found at 3 s and at 6 s, and the distance
    // between over the time between is its speed, within 2% of c (a wave 10% slow fails; the scheme's
    // dispersion for a bump 40 cells wide is far below that). The crest running left comes back from the
    // end at -20 m, behind where the search starts.
    const double c = 2.0;
    auto sim =
        test::makeSimulation(pool(1.0 / 240.0, "cells = [801, 3]\nsize = [40.0, 0.1]\nwave_speed = 2.0\n",
                                  "[[event]]\nframe = 0\nentity = \"pond\"\naction = \"disturb\"\n"
                                  "position = [-15, 0, 0]\nradius = 1.0\namount = 0.1\n"));
    const Water& w = test::component<Water>(*sim, "pond");
    double crest[2] = {0.0, 0.0};
    for (int at = 0; at < 2; ++at) {
        for (int f = 0; f < 240 * 3; ++f) {
            sim->runFrame();
        }
        // right of where the crest running left could be (it left at the same speed)
        crest[at] = crestBetween(w, -15.0 + 0.5 * c * 3.0 * (at + 1), 20.0);
    }
    EXPECT_NEAR(crest[0], -15.0 + c * 3.0, 0.1) << "the crest at 3 s";
    EXPECT_NEAR((crest[1] - crest[0]) / 3.0, c, 0.02 * c);
}

TEST(Water, WithoutDampingTheWaveEnergyStaysBounded) {
    auto sim =
        test::makeSimulation(pool(1.0 / 60.0, "cells = [64, 64]\nsize = [8.0, 8.0]\nwave_speed = 2.0\n",
                                  "[[event]]\nframe = 0\nentity = \"pond\"\naction = \"disturb\"\n"
                                  "position = [1, 0, -0.5]\nradius = 0.6\namount = 0.1\n"));
    sim->runFrame();
    const Water& w = test::component<Water>(*sim, "pond");
    const double start = energy(w);
    ASSERT_GT(start, 0.0);
    // symplectic Euler keeps a nearby energy: measured at whole steps it wanders within a band, and that
    // band neither grows nor shrinks over thousands of steps
    double early = 0.0, late = 0.0, lo = start;
    for (int f = 0; f < 3000; ++f) {
        sim->runFrame();
        const double e = energy(w);
        lo = std::min(lo, e);
        (f < 500 ? early : late) = std::max(f < 500 ? early : late, e);
    }
    EXPECT_LT(late, 1.02 * early);
    EXPECT_GT(late, 0.98 * early);
    EXPECT_GT(lo, 0.8 * start);
}

TEST(Water, AStepBeyondTheCflLimitIsTakenInStableSubsteps) {
    // c = 5 m/s, 5 cm cells, dt = 1/60 s: a Courant number of 2.4, far past the limit of 1
    auto sim =
        test::makeSimulation(pool(1.0 / 60.0, "cells = [81, 81]\nsize = [4.0, 4.0]\nwave_speed = 5.0\n",
                                  "[[event]]\nframe = 0\nentity = \"pond\"\naction = \"disturb\"\n"
                                  "position = [0, 0, 0]\nradius = 0.3\namount = 0.05\n"));
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
    }
    const Water& w = test::component<Water>(*sim, "pond");
    EXPECT_GE(w.substeps, 3u);
    double highest = 0.0;
    for (double h : w.h) {
        ASSERT_TRUE(std::isfinite(h));
        highest = std::max(highest, std::abs(h));
    }
    EXPECT_LT(highest, 0.05) << "no growth: the bump only spreads";
    const RunReport& report = sim->world().resource<RunReport>();
    ASSERT_EQ(report.notes.size(), 1u);
    EXPECT_NE(report.notes[0].find("CFL"), std::string::npos) << report.notes[0];
    EXPECT_TRUE(report.failures.empty());
}

TEST(Water, AFloatingBoxSettlesAtTheDraftItsDensityPredicts) {
    // a 0.6 m cube of 400 kg/m^3 in water of 1000 kg/m^3 floats with 0.4 of its height under: 0.24 m
    const double side = 0.6, density = 400.0, mass = density * side * side * side;
    auto sim =
        test::makeSimulation(pool(1.0 / 60.0,
                                  "cells = [81, 81]\nsize = [4.0, 4.0]\nwave_speed = 1.5\n"
                                  "damping = 0.5\ndrag = 2.0\n",
                                  "[[entity]]\nname = \"crate\"\n[entity.transform]\nposition = [0, 0.5, 0]\n"
                                  "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.3, 0.3, 0.3]\n"
                                  "sleep = false\nmass = " +
                                      std::to_string(mass) + "\n"));
    for (int f = 0; f < 900; ++f) {
        sim->runFrame();
    }
    const RigidBody& box = test::component<RigidBody>(*sim, "crate");
    const double draft = 0.5 * side - box.position.y; // the bottom's depth under the rest level
    EXPECT_NEAR(draft, 0.4 * side, 0.05 * 0.4 * side) << "centre at " << box.position.y;
    EXPECT_LT(std::abs(box.linearVelocity.y), 0.01) << "settled";
}

/// The volume a field of heights over the grid's nodes holds, m^3: each node's height times its share of its
/// cell inside the grid (a half on an edge, a quarter in a corner).
double volumeOf(const Water& w, const std::vector<double>& heights) {
    double v = 0.0;
    for (int k = 0; k < w.nz; ++k) {
        for (int i = 0; i < w.nx; ++i) {
            const double share =
                (i == 0 || i == w.nx - 1 ? 0.5 : 1.0) * (k == 0 || k == w.nz - 1 ? 0.5 : 1.0);
            v += share * heights[std::size_t(k) * w.nx + i];
        }
    }
    return v * w.dx() * w.dz();
}

/// The water's volume above the rest level, the measure a reflecting pool keeps, independent of how the
/// coupling moves it.
double volumeAboveRest(const Water& w) {
    return volumeOf(w, w.h);
}

/// The angle (degrees) between a body's own up axis and the world's.
double tiltDegrees(const RigidBody& b) {
    const Vec3 up = rotate(b.orientation, Vec3{0.0, 1.0, 0.0});
    return std::acos(std::clamp(up.y, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

std::string box(const std::string& name, double half, double density, const std::string& at,
                const std::string& more = "") {
    const double mass = density * 8.0 * half * half * half;
    return "[[entity]]\nname = \"" + name + "\"\n[entity.transform]\nposition = " + at +
           "\n[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [" + std::to_string(half) + ", " +
           std::to_string(half) + ", " + std::to_string(half) +
           "]\nsleep = false\nmass = " + std::to_string(mass) + "\n" + more;
}

TEST(Water, AHalfDenseBoxRidesAWaveTrainUpAndDown) {
    // a wave train of amplitude A = 0.1 m and period 3 s (wavelength 6 m, 20 times the box) from a maker at
    // the pool's -x edge, absorbed at the others; a 0.3 m cube of density 500 floats in it. A body this
    // small against the wave rides it: it rises and falls by at least 0.8 A (acceptance), and by about the
    // wave's own height there (measured in the same run on the surface it floats on)
    const double amplitude = 0.1;
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0,
             "cells = [121, 41]\nsize = [24.0, 8.0]\ndepth = 2.0\nwave_speed = 2.0\nborder = \"absorb\"\n"
             "drag = 0.5\nwave_maker = { edge = \"-x\", amplitude = 0.1, period = 3.0 }\n",
             box("float", 0.15, 500.0, "[0.0, 0.0, 0.0]")));
    double lo = 1e9, hi = -1e9, waveLo = 1e9, waveHi = -1e9;
    for (int f = 0; f < 60 * 24; ++f) {
        sim->runFrame();
        if (f >= 60 * 12) { // the train has passed the box (6 s at 2 m/s) and the box has settled into it
            const RigidBody& b = test::component<RigidBody>(*sim, "float");
            const Water& w = test::component<Water>(*sim, "pond");
            lo = std::min(lo, b.position.y);
            hi = std::max(hi, b.position.y);
            const double at = w.ambient.at(std::size_t(w.nz / 2) * w.nx + std::size_t(w.nx / 2));
            waveLo = std::min(waveLo, at);
            waveHi = std::max(waveHi, at);
            ASSERT_TRUE(std::isfinite(b.position.y));
        }
    }
    EXPECT_GT(waveHi - waveLo, 2.0 * 0.85 * amplitude) << "the maker's train arrives at about its amplitude";
    EXPECT_GE(hi - lo, 2.0 * 0.8 * amplitude) << "rises and falls by at least 0.8 A each way";
    std::printf("wave %.4f m peak to peak, the box %.4f m\n", waveHi - waveLo, hi - lo);
    EXPECT_NEAR(hi - lo, waveHi - waveLo, 0.25 * (waveHi - waveLo)) << "rides the wave it floats on";
    const RigidBody& b = test::component<RigidBody>(*sim, "float");
    // carried back and forth by the slope, and drifting with the train (no orbital velocity of the water
    // to drag against: about 0.1 m/s)
    EXPECT_LT(std::abs(b.position.x), 2.0) << "carried back and forth, not away";
}

TEST(Water, ABoxReleasedTiltedThirtyDegreesRightsItself) {
    // a flat box (0.8 x 0.3 x 0.8 m) of density 500 is stable upright (its metacentre, I/V = 0.8^2/(12 x
    // 0.15) = 0.36 m above the centre of buoyancy, is well above its centre of mass); released at 30
    // degrees about z, the columns on its low side, deeper in the water, lift it back
    const double mass = 500.0 * 0.8 * 0.3 * 0.8;
    auto sim = test::makeSimulation(pool(
        1.0 / 60.0, "cells = [61, 61]\nsize = [6.0, 6.0]\ndepth = 1.0\nwave_speed = 1.5\ndamping = 0.2\n",
        "[[entity]]\nname = \"raft\"\n[entity.transform]\nposition = [0, 0, 0]\n[entity.rigid_body]\n"
        "shape = \"box\"\nhalf_extents = [0.4, 0.15, 0.4]\norientation = [0, 0, 0.25881904510252074, "
        "0.96592582628906831]\nsleep = false\nmass = " +
            std::to_string(mass) + "\n"));
    ASSERT_NEAR(tiltDegrees(test::component<RigidBody>(*sim, "raft")), 30.0, 1e-9);
    // (it rolls about its upright pose, period about 0.9 s, the roll dying away by the water's drag: 10
    // degrees at most after 2.5 s, 3.4 after 5, 0.6 after 10)
    double most = 0.0;
    for (int f = 0; f < 900; ++f) {
        sim->runFrame();
        if (f >= 600) {
            most = std::max(most, tiltDegrees(test::component<RigidBody>(*sim, "raft")));
        }
    }
    EXPECT_LT(most, 1.0) << "upright within a degree from 10 s to 15 s";
}

TEST(Water, TheWatersVolumeIsKeptWhileBodiesSinkFloatAndRock) {
    // a reflecting pool; a light box, a dense box that sinks to the floor and a tilted one dropped in:
    // the water above the rest level (its displaced share included) stays zero to 1e-6 of the pool's
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [64, 48]\nsize = [6.4, 4.8]\ndepth = 1.0\nwave_speed = 1.5\n",
             box("light", 0.2, 300.0, "[-1.5, 0.5, 0.0]") + box("dense", 0.2, 3000.0, "[0.0, 0.3, 0.5]") +
                 box("tilted", 0.25, 600.0, "[1.5, 0.6, -0.5]", "orientation = [0.2, 0.1, 0.3, 0.9]\n") +
                 "[[entity]]\nname = \"floor\"\n[entity.transform]\nposition = [0, -1, 0]\n"
                 "[entity.rigid_body]\nshape = \"plane\"\n"));
    const Water& w = test::component<Water>(*sim, "pond");
    const double pool = 6.4 * 4.8 * 1.0;
    double worst = 0.0;
    for (int f = 0; f < 300; ++f) {
        sim->runFrame();
        worst = std::max(worst, std::abs(volumeAboveRest(w)));
    }
    EXPECT_LT(worst, 1e-6 * pool);
    EXPECT_GT(*std::max_element(w.occupied.begin(), w.occupied.end()), 0.1) << "the bodies are in the water";
}

class FloatingDensity : public ::testing::TestWithParam<double> {};

TEST_P(FloatingDensity, AnyDensityAtALongStepSettlesAtItsDraftWithoutBlowingUp) {
    // from a thousandth of the water's density to three times it, at dt = 1/20 s: every box ends finite,
    // at rest, floating at the draft Archimedes gives (a fraction density/1000 of its height under) or, if
    // denser, on the pool's floor
    const double density = GetParam(), half = 0.25;
    auto sim = test::makeSimulation(pool(
        1.0 / 20.0, "cells = [41, 41]\nsize = [4.0, 4.0]\ndepth = 1.0\nwave_speed = 1.0\ndamping = 0.5\n",
        // a box for the floor: a box falling onto a Bullet plane at this step sinks into it, water or not
        // (noted in the issue)
        box("b", half, density, "[0.0, 0.5, 0.0]") +
            "[[entity]]\nname = \"floor\"\n[entity.transform]\nposition = [0, -1.5, 0]\n"
            "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [5, 0.5, 5]\n"));
    for (int f = 0; f < 400; ++f) {
        sim->runFrame();
        const RigidBody& b = test::component<RigidBody>(*sim, "b");
        ASSERT_TRUE(std::isfinite(b.position.y) && std::abs(b.position.y) < 3.0) << "frame " << f;
    }
    const RigidBody& b = test::component<RigidBody>(*sim, "b");
    if (density < 1000.0) {
        const double draft = half - b.position.y;
        EXPECT_NEAR(draft, 2.0 * half * density / 1000.0, 0.02 * 2.0 * half + 0.005);
    } else {
        EXPECT_NEAR(b.position.y, -1.0 + half, 0.02) << "on the floor";
    }
    EXPECT_LT(length(b.linearVelocity), 0.02);
}

INSTANTIATE_TEST_SUITE_P(Water, FloatingDensity, ::testing::Values(1.0, 10.0, 100.0, 500.0, 900.0, 3000.0),
                         [](const auto& p) { return "density_" + std::to_string(int(p.param)); });

/// A 2D square of side 0.6 m (as its slab, twice kSlabHalfDepth deep) of this density (kg/m^3), released
/// tilted by `angle` (rad) with its centre at y0, after 15 s in a pool.
RigidBody2D floatedSquare(double density, double angle, double y0) {
    const double volume = 0.6 * 0.6 * 2.0 * kSlabHalfDepth;
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [81, 81]\nsize = [4.0, 4.0]\nwave_speed = 1.5\ndamping = 0.5\ndrag = 2.0\n",
             "[[entity]]\nname = \"log\"\n[entity.transform]\nposition = [0, " + std::to_string(y0) +
                 ", 0]\n[entity.rigid_body_2d]\nshape = \"box\"\nhalf_extents = [0.3, 0.3]\nsleep = false\n"
                 "angle = " +
                 std::to_string(angle) + "\nmass = " + std::to_string(density * volume) + "\n"));
    for (int f = 0; f < 900; ++f) {
        sim->runFrame();
    }
    return test::component<RigidBody2D>(*sim, "log");
}

TEST(Water, A2DSquareFloatsAsItsSlabAtItsDraftAndTurnsAsItsMetacentreSays) {
    // a square log of relative density s floats with s of its side under; flat side up it is stable when
    // its metacentric height GM = side (s/2 + 1/(12 s) - 1/2) is positive (s < 0.21 or s > 0.79), and
    // otherwise turns a corner down (its diagonal upright, 45 degrees) (Archimedes; any naval text)
    const RigidBody2D light = floatedSquare(150.0, 0.3, 0.3);
    EXPECT_NEAR(0.3 - light.position[1], 0.15 * 0.6, 0.05 * 0.15 * 0.6) << "the draft, s of the side";
    EXPECT_LT(std::abs(light.angle), 0.02) << "s = 0.15: GM > 0, released at 0.3 rad it rights itself";
    EXPECT_LT(std::abs(light.velocity[1]), 0.01) << "settled";
    const RigidBody2D middling = floatedSquare(400.0, 0.1, 0.1);
    const double quarter = std::numbers::pi / 2.0;
    const double turned = std::fmod(std::abs(middling.angle), quarter);
    EXPECT_NEAR(turned, quarter / 2.0, 0.05) << "s = 0.4: GM < 0, released at 0.1 rad it turns a corner down";
}

TEST(Water, NothingBelowThePoolsFloorIsBuoyed) {
    // a box of 500 kg/m^3 held 2.5 m under the rest level in water 0.5 m deep is below the pool: no water
    // lifts it, it falls freely (its velocity after 0.3 s is g t, to the step's rounding)
    auto sim = test::makeSimulation(pool(0.01, "cells = [21, 21]\nsize = [4.0, 4.0]\ndepth = 0.5\n",
                                         box("deep", 0.2, 500.0, "[0.0, -2.5, 0.0]")));
    for (int f = 0; f < 30; ++f) {
        sim->runFrame();
    }
    EXPECT_NEAR(test::component<RigidBody>(*sim, "deep").linearVelocity.y, -9.81 * 0.3, 1e-3);
}

TEST(Water, WhereABodySitsOnTheGridChangesNeitherItsDraftNorItsTilt) {
    // on a 0.125 m grid: a 0.5 m cube of 900 kg/m^3 (stable flat: its metacentric height is positive at
    // s > 0.79) between the nodes, an upright cylinder of 900, a 10 cm cube and a 3 cm ball of 500: each
    // floats at Archimedes' draft, upright (sampled at the nodes, the first tilted 10 degrees, the cylinder's
    // draft came out 5% short, the small cube and the ball sank)
    const double pi = std::numbers::pi;
    const std::string bodies =
        box("cube", 0.25, 900.0, "[0.3, -0.2, 0.2]") +
        "[[entity]]\nname = \"drum\"\n[entity.transform]\nposition = [-2.0, -0.2, 1.53]\n"
        "[entity.rigid_body]\nshape = \"cylinder\"\nradius = 0.3\nheight = 0.5\nsleep = false\nmass = " +
        std::to_string(900.0 * pi * 0.09 * 0.5) + "\n" + box("chip", 0.05, 500.0, "[2.031, 0.0, 2.031]") +
        "[[entity]]\nname = \"bead\"\n[entity.transform]\nposition = [-2.03, 0.0, -2.07]\n"
        "[entity.rigid_body]\nshape = \"sphere\"\nradius = 0.03\nsleep = false\nmass = " +
        std::to_string(500.0 * 4.0 / 3.0 * pi * 0.03 * 0.03 * 0.03) + "\n";
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [81, 81]\nsize = [10.0, 10.0]\ndepth = 2.0\ndamping = 0.5\ndrag = 5.0\n",
             bodies));
    for (int f = 0; f < 900; ++f) {
        sim->runFrame();
    }
    const RigidBody& cube = test::component<RigidBody>(*sim, "cube");
    EXPECT_NEAR(cube.position.y, 0.25 - 0.9 * 0.5, 0.01);
    EXPECT_LT(tiltDegrees(cube), 1.0);
    const RigidBody& drum = test::component<RigidBody>(*sim, "drum");
    EXPECT_NEAR(drum.position.y, 0.25 - 0.9 * 0.5, 0.01);
    EXPECT_LT(tiltDegrees(drum), 1.0);
    EXPECT_NEAR(test::component<RigidBody>(*sim, "chip").position.y, 0.05 - 0.5 * 0.1, 0.005);
    EXPECT_NEAR(test::component<RigidBody>(*sim, "bead").position.y, 0.0, 0.003) << "half under";
}

TEST(Water, ABodyTiedUnderWaterPullsItsTetherWithAllItsLift) {
    // a 0.2 m cube of 100 kg/m^3 held 1 m under by a spring (200 N/m) to the floor: at rest the spring
    // holds the lift less the weight, (1000 - 100) 0.008 g = 70.6 N, a stretch of 0.353 m (the water's
    // answer to the body's own motion must not weaken a force the body does not move under: with half the
    // displaced water as added mass it held 11.8 N)
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [41, 41]\nsize = [4.0, 4.0]\ndepth = 2.0\ndamping = 0.5\ndrag = 2.0\n",
             box("buoy", 0.1, 100.0, "[0.0, -1.0, 0.0]") +
                 "[[joint]]\ntype = \"spring\"\na = \"buoy\"\npivot_b = [0.0, -1.5, 0.0]\nstiffness = 200.0\n"
                 "damping = 20.0\nrest = 0.5\n"));
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
    }
    const double stretch = test::component<RigidBody>(*sim, "buoy").position.y - (-1.5) - 0.5;
    EXPECT_NEAR(stretch, 900.0 * 0.008 * 9.81 / 200.0, 0.01);
}

TEST(Water, ALongPlankRollsUprightLikeACubeOfItsSection) {
    // a 2 x 0.2 x 0.2 m plank and a 0.2 m cube of 150 kg/m^3, both released at 17 degrees of roll about
    // x: their sections are alike, so they right alike (the plank's roll once met the stiffness of its
    // length as well as its breadth, and crept back: 8.7 degrees after 5 s)
    const std::string tilt = "orientation = [0.14780941112961063, 0, 0, 0.98901586336191682]\n";
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [81, 81]\nsize = [8.0, 8.0]\ndepth = 1.0\ndamping = 0.5\ndrag = 2.0\n",
             box("cube", 0.1, 150.0, "[-2.0, 0.0, 2.0]", tilt) +
                 "[[entity]]\nname = \"plank\"\n[entity.transform]\nposition = [1.0, 0.0, -1.0]\n"
                 "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [1.0, 0.1, 0.1]\nsleep = false\n" +
                 tilt + "mass = " + std::to_string(150.0 * 2.0 * 0.2 * 0.2) + "\n"));
    for (int f = 0; f < 300; ++f) {
        sim->runFrame();
    }
    EXPECT_LT(tiltDegrees(test::component<RigidBody>(*sim, "cube")), 2.0);
    EXPECT_LT(tiltDegrees(test::component<RigidBody>(*sim, "plank")), 2.0);
}

TEST(Water, A2DPolygonGivenAwayFromItsOriginFloatsAsTheSameSquare) {
    // the 0.6 m square log of density 0.15 as a polygon whose vertices start at its origin, not its centre:
    // it floats level at the same draft as when they are centred (turned about the origin instead of its
    // centre of mass, it rolled to 45 degrees)
    const double mass = 150.0 * 0.6 * 0.6 * 2.0 * kSlabHalfDepth;
    auto sim = test::makeSimulation(pool(
        1.0 / 60.0, "cells = [81, 81]\nsize = [8.0, 4.0]\nwave_speed = 1.5\ndamping = 0.5\ndrag = 2.0\n",
        "[[entity]]\nname = \"log\"\n[entity.transform]\nposition = [1.7, 0.0, 0.0]\n[entity.rigid_body_2d]\n"
        "shape = \"polygon\"\nvertices = [[0.0, 0.0], [0.6, 0.0], [0.6, 0.6], [0.0, 0.6]]\nsleep = false\n"
        "mass = " +
            std::to_string(mass) + "\n"));
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
    }
    const RigidBody2D& log = test::component<RigidBody2D>(*sim, "log");
    EXPECT_LT(std::abs(log.angle), 0.02);
    EXPECT_NEAR(-log.position[1], 0.15 * 0.6, 0.05 * 0.15 * 0.6) << "its bottom (the origin) at the draft";
}

// Spring networks in water (systems/water_system.cpp coupleMasses): each mass the cube of its share of the
// network's volume, lifted by the water it displaces, slowed by 1/2 rho Cd side^2 v^2 (Cd = 1.05, a cube face
// on) and by the water's `drag`, and displacing the surface.

/// The water the bodies in it displace, m^3.
double displacedVolume(const Water& w) {
    return volumeOf(w, w.occupied);
}

class FloatingNetwork : public ::testing::TestWithParam<const char*> {};

TEST_P(FloatingNetwork, ALightOneFloatsOnItsOwnWeightOfWaterAndMakesWaves) {
    // a flat raft 0.6 x 0.3 x 0.6 m of density 400 (43.2 kg), as a soft body or an fem body, dropped in: at
    // rest it displaces its own weight of water, 0.0432 m^3 (Archimedes), the water it pushes aside makes
    // waves and the pool's volume is kept. (Caught: the water's push held over without the gravity the
    // springs' step adds taken out of it, which floated the raft on twice its weight, 0.0864 m^3.)
    const std::string kind = GetParam();
    const double mass = 400.0 * 0.6 * 0.3 * 0.6;
    const std::string body =
        kind == "softbody" ? "[entity.softbody]\nsize = [0.6, 0.3, 0.6]\nresolution = [5, 3, 5]\nmass = " +
                                 std::to_string(mass) + "\nstiffness = 2.0e5\ndamping = 20.0\n"
                           : "[entity.fem]\nmesh = \"box\"\nsize = [0.6, 0.3, 0.6]\nresolution = [4, 2, 4]\n"
                             "young = 1.0e6\ndensity = 400.0\n";
    auto sim = test::makeSimulation(pool(
        1.0 / 60.0, "cells = [61, 61]\nsize = [4.0, 4.0]\ndepth = 1.0\nwave_speed = 1.5\ndamping = 0.5\n",
        "[[entity]]\nname = \"raft\"\n[entity.transform]\nposition = [0.1, 0.3, -0.2]\n" + body));
    const Water& w = test::component<Water>(*sim, "pond");
    double worst = 0.0, waves = 0.0;
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
        worst = std::max(worst, std::abs(volumeAboveRest(w)));
        const auto [low, high] = std::minmax_element(w.h.begin(), w.h.end());
        waves = std::max(waves, *high - *low);
    }
    EXPECT_NEAR(displacedVolume(w), mass / 1000.0, 0.02 * mass / 1000.0);
    const SpringNetwork& raft = test::component<SpringNetwork>(*sim, "raft");
    double fastest = 0.0;
    for (const Vec3& v : raft.v) {
        fastest = std::max(fastest, length(v));
    }
    EXPECT_LT(fastest, 0.01) << "at rest";
    EXPECT_GT(waves, 0.05) << "the water it pushed aside as it fell in made waves";
    EXPECT_LT(worst, 1e-6 * 4.0 * 4.0 * 1.0) << "the water's volume is kept";
}

INSTANTIATE_TEST_SUITE_P(Water, FloatingNetwork, ::testing::Values("softbody", "fem"));

TEST(Water, ADenseRopeSinksAtTheSpeedItsWeightAndTheWatersResistanceBalanceAt) {
    // two masses of 0.5 kg, each a cube of half a strand 0.2 m long and 0.02 m thick (pi 0.02^2 0.2 / 2 m^3):
    // sinking, (m - rho V) g = 1/2 rho Cd s^2 v^2 with s the cube's side and the water's `drag` 0, so
    // v = sqrt(2 (m - rho V) g / (rho Cd s^2)), 1.67 m/s. (Caught: without the face's resistance it fell
    // ever faster, 16 m/s after 2 s.)
    auto sim = test::makeSimulation(
        pool(1.0 / 60.0, "cells = [21, 21]\nsize = [4.0, 4.0]\ndepth = 20.0\nwave_speed = 1.0\ndrag = 0.0\n",
             "[[entity]]\nname = \"rope\"\n[entity.transform]\nposition = [-0.1, 0.2, 0.0]\n[entity.rope]\n"
             "segments = 1\nlength = 0.2\ndirection = [1.0, 0.0, 0.0]\nmass = 1.0\nthickness = 0.02\n"
             "pin = \"none\"\n"));
    for (int f = 0; f < 120; ++f) {
        sim->runFrame();
    }
    const double m = 0.5, volume = std::numbers::pi * 0.02 * 0.02 * 0.2 / 2.0, side = std::cbrt(volume);
    const double expected = std::sqrt(2.0 * (m - 1000.0 * volume) * 9.81 / (1000.0 * 1.05 * side * side));
    const SpringNetwork& rope = test::component<SpringNetwork>(*sim, "rope");
    for (const Vec3& v : rope.v) {
        EXPECT_NEAR(-v.y, expected, 0.01 * expected);
    }
    EXPECT_LT(rope.x[0].y, -2.0) << "well under water";
}

TEST(Water, ALightClothDroppedOnTheWaterLiesOnItAndIsNotThrownOff) {
    // 1 m^2 of 0.2 kg cloth 0.01 m thick (20 kg/m^3) dropped flat from 2 m: it stops on the water and comes
    // to rest on it, no higher than the top of its masses' cubes. (Caught: the heave taken explicitly, k =
    // 0, left it jittering at up to 0.08 m/s; without the face's resistance too, the lift of the masses a
    // step took wholly under water threw it 1.2 m back up.)
    auto sim = test::makeSimulation(pool(
        1.0 / 60.0, "cells = [41, 41]\nsize = [3.0, 3.0]\ndepth = 1.0\nwave_speed = 1.5\ndamping = 0.5\n",
        "[[entity]]\nname = \"sheet\"\n[entity.transform]\nposition = [0.0, 2.0, 0.0]\n[entity.cloth]\n"
        "rows = 11\ncols = 11\nsize = [1.0, 1.0]\nplane = \"xz\"\nmass = 0.2\npin = \"none\"\n"));
    const SpringNetwork& sheet = test::component<SpringNetwork>(*sim, "sheet");
    const double side = std::cbrt(1.0 * 1.0 * 0.01 / 121.0);
    bool wet = false;
    double highest = -1e9;
    for (int f = 0; f < 300; ++f) {
        sim->runFrame();
        for (const Vec3& x : sheet.x) {
            wet = wet || x.y < 0.5 * side;
            if (wet) {
                highest = std::max(highest, x.y);
            }
        }
    }
    ASSERT_TRUE(wet);
    EXPECT_LT(highest, 0.05) << "bounced off the water";
    for (std::size_t i = 0; i < sheet.x.size(); ++i) {
        EXPECT_GT(sheet.x[i].y, 0.0) << "mass " << i << " floats";
        EXPECT_LT(sheet.x[i].y, 0.5 * side) << "mass " << i;
        EXPECT_LT(length(sheet.v[i]), 0.01) << "mass " << i << " at rest";
    }
}

/// `burst` drops born at once on a disc round (x, height, z), falling at 1-2 m/s, 0.04 m across at birth and
/// 0.02 at the end of their 10 s lives.
std::string dropper(bool collide, double height, double x = 0.31, double z = -0.23, double radius = 0.5,
                    int burst = 50) {
    return "[[entity]]\nname = \"rain\"\n[entity.transform]\nposition = [" + std::to_string(x) + ", " +
           std::to_string(height) + ", " + std::to_string(z) +
           "]\n[entity.emitter]\nrate = 0.0\nburst = " + std::to_string(burst) +
           "\nshape = \"disc\"\nradius = " + std::to_string(radius) +
           "\ndirection = [0.0, -1.0, 0.0]\nspread_deg = 0.0\nspeed = [1.0, 2.0]\nlifetime = [10.0, 10.0]\n"
           "size = [0.04, 0.02]\ncollide = " +
           (collide ? "true" : "false") + "\n";
}

/// The volume the dropper's drops bring to water at rest at y = 0 (dt 1/240 s), from their state a step
/// after their birth: each falls to y = 0 in t with y0 = v t + g t^2 / 2, and is a ball of its size then.
double dropsVolume(const ParticlePool& drops) {
    double volume = 0.0;
    for (std::uint32_t i = 0; i < drops.count; ++i) {
        const double v = -drops.vy[i], fall = double(drops.py[i]), g = 9.81;
        const double t = (-v + std::sqrt(v * v + 2.0 * g * fall)) / g + 1.0 / 240.0; // (born a step ago)
        const double size = 0.04 - 0.02 * std::min(1.0, t / 10.0);
        volume += std::numbers::pi / 6.0 * size * size * size;
    }
    return volume;
}

TEST(Water, ParticlesThatCollideFallInAndAddTheirVolumeToThePond) {
    // fifty drops fall into a pool from 1 m, beside a floating box; each is taken in where it meets the
    // surface, adding a ball of its size then (0.04 m at birth, 0.02 at the end of its 10 s life: 0.04 -
    // 0.02 t / 10) to the water, and ringing it, the surface the box floats on too. The reference: each
    // drop's fall to the rest level, y = y0 - v t - g t^2 / 2 from its state a step after its birth, gives
    // its size there. Particles that do not collide, or that are born under water, pass through and add
    // nothing. (Caught: drops taken in at the size they were born with, 5% more water; drops left alive
    // under the surface; the rings left standing on the surface the box floats on, never stepped; particles
    // born under water taken in at once.)
    struct Case {
        bool collide;
        double height;
        bool takenIn;
    };
    for (const Case& k : {Case{true, 1.0, true}, Case{false, 1.0, false}, Case{true, -0.5, false}}) {
        auto sim = test::makeSimulation(
            pool(1.0 / 240.0, "cells = [41, 41]\nsize = [3.0, 3.0]\ndepth = 1.0\nwave_speed = 1.5\n",
                 dropper(k.collide, k.height) + box("crate", 0.15, 500.0, "[-1.0, 0.0, 1.0]")));
        const ParticleEmitter& rain = test::component<ParticleEmitter>(*sim, "rain");
        sim->runFrame(); // the burst is born in the first step
        ASSERT_EQ(rain.pool.count, 50u);
        const double expected = dropsVolume(rain.pool);
        const Water& w = test::component<Water>(*sim, "pond");
        double waves = 0.0;
        for (int f = 0; f < 240; ++f) {
            sim->runFrame();
            const auto [low, high] = std::minmax_element(w.h.begin(), w.h.end());
            waves = std::max(waves, *high - *low);
        }
        if (k.takenIn) {
            EXPECT_EQ(rain.pool.count, 0u) << "every drop was taken in";
            EXPECT_NEAR(volumeAboveRest(w), expected, 0.01 * expected);
            EXPECT_GT(waves, 1e-4) << "the drops ring the surface";
            ASSERT_FALSE(w.ambientV.empty()) << "the box floats on an ambient surface";
            const auto [slow, fast] = std::minmax_element(w.ambientV.begin(), w.ambientV.end());
            EXPECT_GT(*fast - *slow, 1e-4) << "the rings travel on the surface the box floats on";
        } else {
            EXPECT_EQ(rain.pool.count, 50u) << "they pass through";
            EXPECT_NEAR(volumeAboveRest(w), 0.0, 1e-9);
        }
    }
}

TEST(Water, DropsIntoTheOutermostCellsAddTheirWholeVolume) {
    // five such drops into the corner cell of the pool (its nodes on the edges hold half a cell, the corner
    // a quarter), and five into a cell along one edge: each adds its whole volume. (Caught: spread onto the
    // four nodes by the bilinear weights alone, the corner's drops added 49% of their volume, the edge's
    // 69%.) Fifty into one cell raise it so fast that some are under the surface before they meet it.
    for (const double z : {1.47, 0.0}) {
        auto sim =
            test::makeSimulation(pool(1.0 / 240.0, "cells = [41, 41]\nsize = [3.0, 3.0]\ndepth = 1.0\n",
                                      dropper(true, 1.0, 1.47, z, 0.02, 5)));
        const ParticleEmitter& rain = test::component<ParticleEmitter>(*sim, "rain");
        sim->runFrame();
        ASSERT_EQ(rain.pool.count, 5u);
        const double expected = dropsVolume(rain.pool);
        const Water& w = test::component<Water>(*sim, "pond");
        for (int f = 0; f < 120; ++f) {
            sim->runFrame();
        }
        EXPECT_EQ(rain.pool.count, 0u) << "every drop was taken in";
        EXPECT_NEAR(volumeAboveRest(w), expected, 0.01 * expected) << "z = " << z;
    }
}

TEST(Water, ADenseFemBodyOnThePoolsFloorRestsThere) {
    // a 0.3 m fem cube of density 2000 set on a floor 1 m under water: its nodes rest on the floor, held
    // against their weight less their lift, and stay still. (Caught: the water's push added to the velocities
    // at the start of a step, outside the solve that holds resting nodes, lifted the bottom nodes off the
    // floor every few steps, hopping at up to 0.05 m/s.)
    auto sim = test::makeSimulation(pool(
        1.0 / 60.0, "cells = [31, 31]\nsize = [3.0, 3.0]\ndepth = 1.0\nwave_speed = 1.5\ndamping = 0.5\n",
        "[[entity]]\nname = \"floor\"\n[entity.transform]\nposition = [0, -1, 0]\n[entity.rigid_body]\n"
        "shape = \"plane\"\n[[entity]]\nname = \"cube\"\n[entity.transform]\nposition = [0.1, -0.835, 0.05]\n"
        "[entity.fem]\nmesh = \"box\"\nsize = [0.3, 0.3, 0.3]\nresolution = [2, 2, 2]\nyoung = 1.0e6\n"
        "density = 2000.0\n"));
    const SpringNetwork& cube = test::component<SpringNetwork>(*sim, "cube");
    double fastest = 0.0, lowest = 1e9, highestBottom = -1e9;
    for (int f = 0; f < 600; ++f) {
        sim->runFrame();
        if (f < 300) {
            continue; // settled
        }
        for (std::size_t i = 0; i < cube.x.size(); ++i) {
            fastest = std::max(fastest, length(cube.v[i]));
            lowest = std::min(lowest, cube.x[i].y);
        }
        double bottom = 1e9;
        for (const Vec3& x : cube.x) {
            bottom = std::min(bottom, x.y);
        }
        highestBottom = std::max(highestBottom, bottom);
    }
    EXPECT_LT(fastest, 0.005) << "at rest";
    EXPECT_GT(lowest, -1.0) << "above the floor";
    EXPECT_LT(highestBottom, -1.0 + 0.01 + 0.001) << "its bottom stays on the floor, a thickness above it";
}

} // namespace
} // namespace tumble
