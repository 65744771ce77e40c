// Height-field water against physics: a crest travels at the wave speed; without damping the
// wave energy stays bounded; a step beyond the CFL limit is taken in stable substeps; a floating box
// settles at the draft its density predicts.

#include "components/rigid_body.h"
#include "components/water.h"
#include "engine/run_report.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

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

} // namespace
} // namespace tumble
