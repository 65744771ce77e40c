// The air grid (systems/air_solver.h) against what the physics says: the projection leaves no divergence
// above its tolerance, still warm air stays still, smoke rides a uniform flow at its speed, heat rises.

#include "engine/parallel.h"
#include "engine/simd.h"
#include "systems/air_solver.h"
#include "systems/air_system.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

namespace tumble {
namespace {

Air makeAir(const std::array<int, 3>& cells, double cell, AirBorder border) {
    Air air;
    air.cells = cells;
    air.cell = cell;
    air.border.fill(border);
    initAir(air);
    return air;
}

/// The largest |divergence| (1/s) of a cell outside bodies and sources, by a plain loop over the faces (the
/// check the solver's own four-at-a-time maximum is held to).
double plainDivergenceMax(const Air& air) {
    const int nx = air.cells[0], ny = air.cells[1], nz = air.cells[2];
    double most = 0.0;
    for (int k = 0; k < nz; ++k) {
        for (int j = 0; j < ny; ++j) {
            for (int i = 0; i < nx; ++i) {
                if (!air.solid.empty() && air.solid[air.at(i, j, k)] != 0) {
                    continue;
                }
                const auto u = [&](int a) { return double(air.u[std::size_t(a + (nx + 1) * (j + ny * k))]); };
                const auto v = [&](int b) { return double(air.v[std::size_t(i + nx * (b + (ny + 1) * k))]); };
                const auto w = [&](int c) { return double(air.w[std::size_t(i + nx * (j + ny * c))]); };
                const double flow = (u(i + 1) - u(i)) + (v(j + 1) - v(j)) + (w(k + 1) - w(k));
                most = std::max(most, std::abs(flow) / air.cell);
            }
        }
    }
    return most;
}

double largestSpeed(const Air& air) {
    double m = 0.0;
    for (const std::vector<float>* f : {&air.u, &air.v, &air.w}) {
        for (float x : *f) {
            m = std::max(m, double(std::abs(x)));
        }
    }
    return m;
}

// A random velocity field (up to 1 m/s on every face) projected in a closed box, an open one and one open
// on one side only: every cell's divergence after it under the tolerance, from 1e2-1e3 1/s before.
TEST(Air, ProjectionLeavesNoDivergenceAboveTheTolerance) {
    WorkerPool pool(2);
    for (int kind = 0; kind < 3; ++kind) {
        Air air = makeAir({24, 20, 17}, 0.05, kind == 1 ? AirBorder::Open : AirBorder::Closed);
        if (kind == 2) {
            air.border[3] = AirBorder::Open;
            initAir(air);
        }
        air.tolerance = 1e-3;
        std::mt19937 random(3);
        std::uniform_real_distribution<float> speed(-1.0f, 1.0f);
        for (std::vector<float>* f : {&air.u, &air.v, &air.w}) {
            for (float& x : *f) {
                x = speed(random);
            }
        }
        EXPECT_GT(airDivergenceMax(air, pool), 10.0);
        projectAir(air, pool);
        EXPECT_LE(air.divergenceMax, 1e-3) << "borders " << kind;
        EXPECT_LE(airDivergenceMax(air, pool), 1e-3) << "borders " << kind;
        EXPECT_GT(air.lastIterations, 0u);
        EXPECT_LT(air.lastIterations, 60u) << "borders " << kind;
    }
}

// The multigrid's smoother and coarse levels (Jacobi weighted by a Chebyshev polynomial's roots, coarse
// stencils growing 2.2 a level) and the first guess carried on in time from the last two pressures
// (systems/air_solver.cpp) keep CG short on a plume: a chimney blowing up through a 32^3 grid with every
// force on, CG took 1.5 iterations a step over steps 10-60. Seen failing with the last pressure as the
// guess (2.0), and with it and two Chebyshev sweeps on every level, stencils growing 2 (2.54), or plain
// Jacobi's weights (3.58).
TEST(Air, TheSmootherKeepsCGShortOnAPlume) {
    WorkerPool pool(2);
    Air air;
    air.cells = {32, 32, 32};
    air.cell = 2.0 / 32.0;
    air.border[3] = AirBorder::Open;
    air.vorticity = 0.3;
    air.smokeWeight = 0.1;
    air.heatLift = 1.0;
    initAir(air);
    AirSource chimney;
    chimney.radius = 0.1;
    chimney.smoke = 1.0;
    chimney.heat = 5.0;
    chimney.drives = true;
    chimney.velocity = {0.2, 1.0, 0.0};
    const Vec3 at{0.0, -0.8, 0.0};
    double iterations = 0.0;
    for (int s = 0; s < 60; ++s) {
        feedAir(air, chimney, at, 1.0 / 60.0);
        stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        ASSERT_LE(air.divergenceMax, air.tolerance) << "step " << s;
        iterations += s >= 10 ? double(air.lastIterations) : 0.0;
    }
    EXPECT_LT(iterations / 50.0, 1.8);
}

// A flow turned round at once (every face's velocity reversed and the source blowing the other way, as a
// `set` event might): the guess carried on from the last two pressures is then far off, and CG still
// brings every cell's divergence under the tolerance, in every step after.
TEST(Air, AFlowTurnedRoundAtOnceIsStillProjectedToTheTolerance) {
    WorkerPool pool(2);
    Air air;
    air.cells = {24, 24, 24};
    air.cell = 2.0 / 24.0;
    air.border[3] = AirBorder::Open;
    air.heatLift = 1.0;
    initAir(air);
    AirSource jet;
    jet.radius = 0.15;
    jet.heat = 5.0;
    jet.drives = true;
    jet.velocity = {1.0, 2.0, 0.0};
    const Vec3 at{0.0, -0.5, 0.0};
    for (int s = 0; s < 40; ++s) {
        if (s == 20) {
            for (std::vector<float>* f : {&air.u, &air.v, &air.w}) {
                for (float& x : *f) {
                    x = -x;
                }
            }
            jet.velocity = {-2.0, -1.0, 1.0};
        }
        voxeliseSolids(air, {}, {{&jet, at}});
        ASSERT_TRUE(advectAir(air, 1.0 / 60.0, pool)) << "step " << s;
        feedAir(air, jet, at, 1.0 / 60.0);
        finishAirStep(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        EXPECT_LE(air.divergenceMax, air.tolerance) << "step " << s;
        EXPECT_LE(airDivergenceMax(air, pool), air.tolerance) << "step " << s;
        EXPECT_LT(air.lastIterations, 60u) << "step " << s;
    }
}

// The projection on boxes of odd and thin shapes (a coarse level then merges fewer than eight cells at its
// ends, and the levels stop at a few cells), closed, open, open on one side and open on three, with and
// without a driving source's solid cells: six projections of a velocity stirred anew each time, every
// one ending under the tolerance in at most 11 CG iterations (the multigrid stays a positive definite
// preconditioner whatever its levels' shapes: 200, the cap, and a divergence left over, if it did not).
// Seen failing with the smoother's Chebyshev interval topped at 1.2 instead of D^-1 A's bound of 2 (18-19
// iterations).
TEST(Air, TheProjectionConvergesOnOddShapesWithAnyBordersAndSolids) {
    WorkerPool pool(2);
    const std::array<std::array<int, 3>, 8> shapes = {
        {{4, 4, 4}, {5, 7, 4}, {64, 4, 4}, {4, 33, 5}, {9, 9, 9}, {17, 5, 31}, {33, 33, 33}, {6, 40, 6}}};
    for (const std::array<int, 3>& n : shapes) {
        for (int borders = 0; borders < 4; ++borders) {
            for (bool solids : {false, true}) {
                Air air;
                air.cells = n;
                air.cell = 0.05;
                for (std::size_t side = 0; side < 6; ++side) {
                    const bool open =
                        borders == 1 || (borders == 2 && side == 3) || (borders == 3 && side % 2 == 0);
                    air.border[side] = open ? AirBorder::Open : AirBorder::Closed;
                }
                initAir(air);
                AirSource block;
                block.radius = 0.06;
                block.drives = true;
                block.velocity = {0.5, -0.3, 0.2};
                std::mt19937 random(7);
                std::uniform_real_distribution<float> speed(-1.0f, 1.0f);
                const std::string where = std::to_string(n[0]) + " x " + std::to_string(n[1]) + " x " +
                                          std::to_string(n[2]) + ", borders " + std::to_string(borders) +
                                          (solids ? ", solids" : "");
                for (int s = 0; s < 6; ++s) {
                    for (std::vector<float>* f : {&air.u, &air.v, &air.w}) {
                        for (float& x : *f) {
                            x += 0.3f * speed(random);
                        }
                    }
                    if (solids) {
                        voxeliseSolids(air, {}, {{&block, Vec3{0.0, 0.0, 0.0}}});
                    }
                    projectAir(air, pool);
                    ASSERT_LE(air.divergenceMax, 1e-3) << where << ", projection " << s;
                    ASSERT_LE(plainDivergenceMax(air), 1e-3) << where << ", projection " << s;
                    EXPECT_LE(air.lastIterations, 11u) << where << ", projection " << s;
                }
            }
        }
    }
}

// The largest divergence, taken four cells at a time, misses no cell: one face moving in an otherwise still
// grid 13 cells wide (a row of three fours and one more), at each place along a row in turn, is found at
// its two cells' 1/dx. Seen failing for the cells at 1, 5 and 9 (0 found) while the one-at-a-time end
// of each row wiped the maximum of the cells i = 1 mod 4.
TEST(Air, TheLargestDivergenceMissesNoCell) {
    WorkerPool pool(2);
    Air air = makeAir({13, 6, 5}, 0.1, AirBorder::Closed);
    for (int i = 0; i < 13; ++i) {
        std::fill(air.v.begin(), air.v.end(), 0.0f);
        air.v[std::size_t(i + 13 * (3 + 7 * 2))] = 1.0f; // between cells (i, 2, 2) and (i, 3, 2)
        EXPECT_EQ(airDivergenceMax(air, pool), 1.0 / 0.1) << "cell " << i;
        EXPECT_EQ(plainDivergenceMax(air), 1.0 / 0.1) << "cell " << i;
    }
}

// The advection refuses a grid with one NaN or infinite face anywhere (it would send the trilinear samples
// past the arrays): a face of u, v or w at each place along a row 13 cells wide (one or two blocks of lanes
// and the rest one at a time), in the SSE2 and the AVX2 builds, and the same grid with every face finite
// advects. Seen to fail with the lanes' NaN flags not read: a NaN in the first eight cells of a row (the
// AVX2 build's lanes) was passed over, and the samples it sent past the arrays crashed the test.
TEST(Air, AFaceNotFiniteAnywhereStopsTheAdvection) {
    const Simd before = activeSimd();
    for (const Simd simd : {Simd::Sse2, Simd::Avx2}) {
        if (simd == Simd::Avx2 && !avx2Available()) {
            continue;
        }
        forceSimd(simd);
        WorkerPool pool(2);
        Air air = makeAir({13, 6, 5}, 0.1, AirBorder::Open);
        for (const float bad : {std::nanf(""), INFINITY, -INFINITY}) {
            for (std::vector<float>* faces : {&air.u, &air.v, &air.w}) {
                const bool u = faces == &air.u;
                const std::size_t row = u                 ? 14 * (3 + 6 * 2)
                                        : faces == &air.v ? 13 * (3 + 7 * 2)
                                                          : 13 * (3 + 6 * 2);
                for (std::size_t i = 0; i < (u ? 14u : 13u); ++i) {
                    std::fill(air.u.begin(), air.u.end(), 0.5f);
                    std::fill(air.v.begin(), air.v.end(), 0.0f);
                    std::fill(air.w.begin(), air.w.end(), 0.0f);
                    ASSERT_TRUE(advectAir(air, 0.01, pool));
                    std::fill(air.u.begin(), air.u.end(), 0.5f);
                    (*faces)[row + i] = bad;
                    EXPECT_FALSE(advectAir(air, 0.01, pool))
                        << bad << " at " << i << (simd == Simd::Avx2 ? ", AVX2" : ", SSE2");
                }
            }
        }
    }
    forceSimd(before);
}

// Still air uniformly 5 degrees warmer than nothing, with heat lifting it: in none of 300 steps does
// anything move faster than 1e-6 m/s. Seen to fail with buoyancy taken from the heat itself rather than
// from its difference to the mean (the projection then has to cancel a uniform lift, to its tolerance).
TEST(Air, StillWarmAirStaysStill) {
    WorkerPool pool(2);
    Air air = makeAir({16, 16, 16}, 0.1, AirBorder::Closed);
    air.heatLift = 2.0;
    air.smokeWeight = 0.5;
    std::fill(air.heat.begin(), air.heat.end(), 5.0f);
    double fastest = 0.0;
    for (int s = 0; s < 300; ++s) {
        stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        fastest = std::max(fastest, largestSpeed(air));
    }
    EXPECT_LT(fastest, 1e-6);
}

// A smoke blob in a uniform flow of 1.5 m/s along x (open at both ends): its centroid moves at the flow's
// speed, within 2%.
TEST(Air, SmokeRidesAUniformFlowAtItsSpeed) {
    WorkerPool pool(2);
    Air air = makeAir({48, 16, 16}, 0.05, AirBorder::Closed);
    air.border[0] = air.border[1] = AirBorder::Open;
    initAir(air);
    std::fill(air.u.begin(), air.u.end(), 1.5f);
    const Vec3 start{-0.6, 0.0, 0.0};
    for (int k = 0; k < 16; ++k) {
        for (int j = 0; j < 16; ++j) {
            for (int i = 0; i < 48; ++i) {
                const Vec3 p = air.origin() + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell;
                air.smoke[air.at(i, j, k)] = float(std::exp(-dot(p - start, p - start) / (0.1 * 0.1)));
            }
        }
    }
    const Vec3 before = airSmokeCentroid(air);
    const double dt = 1.0 / 60.0;
    for (int s = 0; s < 40; ++s) {
        stepAir(air, {0.0, -9.81, 0.0}, dt, pool);
    }
    const Vec3 after = airSmokeCentroid(air);
    const double expected = 1.5 * 40 * dt;
    EXPECT_NEAR(after.x - before.x, expected, 0.02 * expected);
    EXPECT_NEAR(after.y, before.y, 1e-3);
    EXPECT_NEAR(after.z, before.z, 1e-3);
}

// A hot blob in still air rises: after half a second its heat's centroid is higher and the air at its
// centre moves up, while the box as a whole holds still (closed).
TEST(Air, AHotBlobRises) {
    WorkerPool pool(2);
    Air air = makeAir({16, 24, 16}, 0.05, AirBorder::Closed);
    air.heatLift = 1.0;
    auto heatCentroidY = [&] {
        double total = 0.0, moment = 0.0;
        for (int k = 0; k < 16; ++k) {
            for (int j = 0; j < 24; ++j) {
                for (int i = 0; i < 16; ++i) {
                    total += air.heat[air.at(i, j, k)];
                    moment += air.heat[air.at(i, j, k)] * (j + 0.5);
                }
            }
        }
        return moment / total * air.cell;
    };
    for (int k = 0; k < 16; ++k) {
        for (int j = 0; j < 24; ++j) {
            for (int i = 0; i < 16; ++i) {
                const Vec3 p = air.origin() + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell;
                air.heat[air.at(i, j, k)] = float(
                    10.0 * std::exp(-dot(p - Vec3{0.0, -0.3, 0.0}, p - Vec3{0.0, -0.3, 0.0}) / (0.1 * 0.1)));
            }
        }
    }
    const double before = heatCentroidY();
    for (int s = 0; s < 30; ++s) {
        stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
    }
    EXPECT_GT(heatCentroidY(), before + 0.05);
    EXPECT_GT(airVelocityAt(air, Vec3{0.0, -0.2, 0.0}).y, 0.1);
}

// A shear flow u = U cos(pi y / H) between two walls (open along x) decays by viscosity as the heat
// equation's slowest mode does, exp(-nu (pi / H)^2 t), within 2%.
TEST(Air, ViscosityDampsAShearAsTheClosedFormSays) {
    WorkerPool pool(2);
    Air air = makeAir({8, 32, 4}, 1.0 / 32.0, AirBorder::Closed);
    air.border[0] = air.border[1] = AirBorder::Open;
    air.viscosity = 0.01;
    initAir(air);
    const double height = 1.0, pi = std::acos(-1.0);
    for (int k = 0; k < 4; ++k) {
        for (int j = 0; j < 32; ++j) {
            for (int i = 0; i <= 8; ++i) {
                air.u[std::size_t(i) + 9 * (std::size_t(j) + 32 * std::size_t(k))] =
                    float(std::cos(pi * (j + 0.5) / 32.0));
            }
        }
    }
    const double dt = 1.0 / 60.0;
    const int steps = 120;
    for (int s = 0; s < steps; ++s) {
        stepAir(air, {0.0, -9.81, 0.0}, dt, pool);
    }
    // the amplitude: the profile's projection on the mode
    double along = 0.0, norm = 0.0;
    for (int j = 0; j < 32; ++j) {
        const double mode = std::cos(pi * (j + 0.5) / 32.0);
        along += mode * air.u[4 + 9 * std::size_t(j)];
        norm += mode * mode;
    }
    const double expected = std::exp(-air.viscosity * (pi / height) * (pi / height) * steps * dt);
    EXPECT_NEAR(along / norm, expected, 0.02 * (1.0 - expected));
}

// Vorticity confinement puts back the energy of eddies that the grid's interpolation smooths away: a
// vortex (u = sin(pi x) cos(pi y), v = -cos(pi x) sin(pi y) in a closed unit square, the same along z)
// keeps more of its kinetic energy with it than without (a force of the wrong sign takes energy out).
TEST(Air, VorticityConfinementKeepsAVortexSpinning) {
    WorkerPool pool(2);
    const double pi = std::acos(-1.0);
    auto energyAfter = [&](double vorticity, bool maccormack = false) {
        Air air;
        air.cells = {16, 16, 4};
        air.cell = 1.0 / 16.0;
        air.maccormack = maccormack;
        initAir(air);
        air.vorticity = vorticity;
        for (int k = 0; k < 4; ++k) {
            for (int j = 0; j < 16; ++j) {
                for (int i = 0; i <= 16; ++i) {
                    air.u[std::size_t(i) + 17 * (std::size_t(j) + 16 * std::size_t(k))] =
                        float(std::sin(pi * i / 16.0) * std::cos(pi * (j + 0.5) / 16.0));
                }
            }
            for (int j = 0; j <= 16; ++j) {
                for (int i = 0; i < 16; ++i) {
                    air.v[std::size_t(i) + 16 * (std::size_t(j) + 17 * std::size_t(k))] =
                        float(-std::cos(pi * (i + 0.5) / 16.0) * std::sin(pi * j / 16.0));
                }
            }
        }
        projectAir(air, pool);
        const double start = airKineticEnergy(air);
        for (int s = 0; s < 60; ++s) {
            stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        }
        return airKineticEnergy(air) / start;
    };
    const double without = energyAfter(0.0), with = energyAfter(1.0); // 0.62 and 0.84 when written
    EXPECT_LT(without, 0.8);                                          // the smoothing is there to undo
    EXPECT_GT(with, without + 0.15);
    // MacCormack's advection smooths less than the semi-Lagrangian step: without confinement, it keeps
    // more of the vortex's energy (0.83 against 0.62 when written)
    EXPECT_GT(energyAfter(0.0, true), without + 0.1);
}

// MacCormack's advection against the exact answer: a smoke blob (a Gaussian of 4 cells' radius) carried
// by a uniform flow of 1.5 m/s for 40 steps, its field compared with the blob moved by exactly 1 m. Its
// error is under 0.45 of the plain step's, and it makes no new extremum (smoke stays within 0 and the
// start's peak, to rounding); heat, started at twice the smoke, stays twice it. Seen to fail, for the
// semi-Lagrangian MacCormack step the cells had before the conserving one: with the correction's sign
// flipped (error 3x larger), the whole difference taken off rather than half, the clamp left out (smoke
// below zero behind the blob), heat's step back read from smoke's. For the conserving one: with the
// antidiffusive flux's sign flipped (error 3.2x the plain one's), without the limiter (smoke -0.036 behind
// the blob), with a face scaled by the ratios of the wrong sides (-0.039).
TEST(Air, MacCormackCarriesSmokeWithLessErrorAndNoNewExtremum) {
    WorkerPool pool(2);
    const Vec3 start{-0.6, 0.0, 0.0}, shift{1.5 * 40 / 60.0, 0.0, 0.0};
    auto blob = [](const Vec3& p, const Vec3& at) { return std::exp(-dot(p - at, p - at) / (0.2 * 0.2)); };
    struct Result {
        double error, lowest, highest;
        bool heatLikeSmoke; // heat started at twice the smoke and, with no buoyancy, stays so (a factor of
                            // two commutes with every rounding but the flush of a denormal: to 1e-6)
    };
    auto carry = [&](bool maccormack) {
        Air air;
        air.cells = {48, 16, 16};
        air.cell = 0.05;
        air.border[0] = air.border[1] = AirBorder::Open;
        air.maccormack = maccormack;
        initAir(air);
        std::fill(air.u.begin(), air.u.end(), 1.5f);
        auto centreOf = [&](int i, int j, int k) {
            return air.origin() + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell;
        };
        for (int k = 0; k < 16; ++k) {
            for (int j = 0; j < 16; ++j) {
                for (int i = 0; i < 48; ++i) {
                    const double b = blob(centreOf(i, j, k), start);
                    air.smoke[air.at(i, j, k)] = b < 1e-20 ? 0.0f : float(b); // no subnormals
                    air.heat[air.at(i, j, k)] = 2.0f * air.smoke[air.at(i, j, k)];
                }
            }
        }
        const float peak = *std::max_element(air.smoke.begin(), air.smoke.end());
        for (int s = 0; s < 40; ++s) {
            stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        }
        bool heatTwiceSmoke = true;
        for (std::size_t c = 0; c < air.smoke.size(); ++c) {
            heatTwiceSmoke = heatTwiceSmoke && std::abs(air.heat[c] - 2.0f * air.smoke[c]) <=
                                                   1e-6f * std::abs(air.heat[c]) + 1e-30f;
        }
        Result r{0.0, 0.0, 0.0, heatTwiceSmoke};
        for (int k = 0; k < 16; ++k) {
            for (int j = 0; j < 16; ++j) {
                for (int i = 0; i < 48; ++i) {
                    const double d = air.smoke[air.at(i, j, k)] - blob(centreOf(i, j, k), start + shift);
                    r.error += d * d;
                }
            }
        }
        r.error = std::sqrt(r.error);
        r.lowest = *std::min_element(air.smoke.begin(), air.smoke.end());
        r.highest = *std::max_element(air.smoke.begin(), air.smoke.end()) / peak;
        return r;
    };
    const Result plain = carry(false), corrected = carry(true);
    EXPECT_LT(corrected.error, 0.45 * plain.error) << "semi-Lagrangian " << plain.error; // 0.42 written
    EXPECT_GE(corrected.lowest, -1e-6);                                                  // rounding
    EXPECT_LE(corrected.highest, 1.0);
    EXPECT_GT(corrected.highest, plain.highest); // the peak smoothed away less
    EXPECT_TRUE(corrected.heatLikeSmoke) << "heat corrected as smoke is (the pair shares one pass)";
}

// Smoke and heat are carried without being made or lost: in a closed box where a hot blob rises and curls,
// with vorticity confinement on, the totals of smoke and of heat after 120 steps are those at the start, to
// float rounding, with either advection. Seen to fail with the semi-Lagrangian step the cells had before
// (smoke 15.7 -> 8.1 and heat 445 -> 279 plain; smoke 15.7 -> 28.1 and heat 445 -> 374 with MacCormack).
TEST(Air, AClosedBoxKeepsItsSmokeAndHeat) {
    WorkerPool pool(2);
    for (bool maccormack : {false, true}) {
        Air air;
        air.cells = {16, 24, 16};
        air.cell = 0.05;
        air.heatLift = 2.0;
        air.vorticity = 0.5;
        air.maccormack = maccormack;
        initAir(air);
        const Vec3 hot{0.0, -0.3, 0.0}, smoky{0.1, -0.2, 0.05};
        for (int k = 0; k < 16; ++k) {
            for (int j = 0; j < 24; ++j) {
                for (int i = 0; i < 16; ++i) {
                    const Vec3 p = air.origin() + Vec3{i + 0.5, j + 0.5, k + 0.5} * air.cell;
                    air.heat[air.at(i, j, k)] = float(10.0 * std::exp(-dot(p - hot, p - hot) / 0.01));
                    air.smoke[air.at(i, j, k)] = float(std::exp(-dot(p - smoky, p - smoky) / 0.005));
                }
            }
        }
        const auto total = [](const std::vector<float>& f) {
            double sum = 0.0;
            for (float x : f) {
                sum += x;
            }
            return sum;
        };
        const double smoke = total(air.smoke), heat = total(air.heat);
        for (int s = 0; s < 120; ++s) {
            stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
        }
        EXPECT_GT(largestSpeed(air), 0.3) << "the blob rises";
        EXPECT_NEAR(total(air.smoke), smoke, 1e-5 * smoke) << (maccormack ? "maccormack" : "plain");
        EXPECT_NEAR(total(air.heat), heat, 1e-5 * heat) << (maccormack ? "maccormack" : "plain");
    }
}

// The same bits at any thread count: a warm, smoky blob with every force on, 10 steps at 1, 2 and 3
// threads, with either advection (the grid has 288 rows: over kSharedRows, so its loops are shared out;
// at 180, as it had, every loop ran on the calling thread).
/// Every stage of a step on (buoyancy, confinement, viscosity, dissipation), and smoke and heat strewn over
/// the cells in a fixed pattern.
void everyForceOn(Air& air) {
    air.heatLift = 1.0;
    air.smokeWeight = 0.3;
    air.vorticity = 0.5;
    air.viscosity = 1e-3;
    air.dissipation = 0.1;
    for (std::size_t c = 0; c < air.heat.size(); ++c) {
        air.heat[c] = float((c * 7919) % 13) * 0.1f;
        air.smoke[c] = float((c * 104729) % 7) * 0.2f;
    }
}

TEST(Air, AnyThreadCountGivesTheSameBits) {
    for (bool maccormack : {false, true}) {
        auto run = [maccormack](int threads) {
            WorkerPool pool(threads);
            Air air;
            air.cells = {12, 32, 9};
            air.cell = 0.05;
            air.border[3] = AirBorder::Open;
            air.maccormack = maccormack;
            initAir(air);
            everyForceOn(air);
            for (int s = 0; s < 10; ++s) {
                stepAir(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
            }
            return air;
        };
        const Air one = run(1);
        for (int threads : {2, 3}) {
            const Air many = run(threads);
            EXPECT_EQ(many.u, one.u) << threads << " threads";
            EXPECT_EQ(many.v, one.v);
            EXPECT_EQ(many.w, one.w);
            EXPECT_EQ(many.smoke, one.smoke);
            EXPECT_EQ(many.heat, one.heat);
            EXPECT_EQ(many.pressure, one.pressure);
        }
    }
}

/// Whether two fields hold the same bits (== takes -0 for 0 and never a NaN for itself).
bool sameBits(const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

// The solver's loops compiled for SSE2 and for AVX2 (systems/air_solver_avx2.cpp) give the same bits: every
// stage on (buoyancy, confinement, viscosity, dissipation), plain and MacCormack advection, a driving
// source's solid cells and held faces, an open side, and a flow of over 64 cells a step, whose cells take
// the semi-Lagrangian step. Seen to fail with the AVX2 build's FMA contraction allowed (-ffp-contract=fast).
TEST(Air, Avx2AndSse2GiveTheSameBits) {
    if (!avx2Available()) {
        GTEST_SKIP() << "no AVX2 on this processor";
    }
    const Simd before = activeSimd();
    for (int variant = 0; variant < 3; ++variant) {
        auto run = [variant](Simd simd) {
            forceSimd(simd);
            WorkerPool pool(2);
            Air air;
            air.cells = {13, 24, 10};
            air.cell = 0.05;
            air.border[3] = AirBorder::Open;
            air.border[1] = AirBorder::Open;
            air.maccormack = variant == 1;
            initAir(air);
            everyForceOn(air);
            if (variant == 2) {
                std::fill(air.u.begin(), air.u.end(), 250.0f); // 83 cells a step
            }
            AirSource fan;
            fan.radius = 0.08;
            fan.smoke = 2.0;
            fan.heat = 3.0;
            fan.velocity = {1.5, 2.0, 0.0};
            fan.drives = true;
            const Vec3 at{-0.1, -0.35, 0.02};
            for (int s = 0; s < 8; ++s) {
                voxeliseSolids(air, {}, {{&fan, at}});
                if (!advectAir(air, 1.0 / 60.0, pool)) {
                    ADD_FAILURE() << "blew up, variant " << variant;
                    break;
                }
                feedAir(air, fan, at, 1.0 / 60.0);
                finishAirStep(air, {0.0, -9.81, 0.0}, 1.0 / 60.0, pool);
            }
            return air;
        };
        const Air sse2 = run(Simd::Sse2);
        const Air avx2 = run(Simd::Avx2);
        EXPECT_GT(sse2.lastIterations, 0u) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.u, sse2.u)) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.v, sse2.v)) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.w, sse2.w)) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.smoke, sse2.smoke)) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.heat, sse2.heat)) << "variant " << variant;
        EXPECT_TRUE(sameBits(avx2.pressure, sse2.pressure)) << "variant " << variant;
        EXPECT_EQ(avx2.divergenceMax, sse2.divergenceMax) << "variant " << variant;
    }
    forceSimd(before);
}

// A source adds smoke * dt to each cell whose centre is inside its sphere (the sphere's volume times it in
// all, within the voxels' 3%), imposes its velocity on the faces inside and leaves the others; one smaller
// than a cell feeds the cell it is in.
TEST(Air, ASourceFeedsItsShape) {
    Air air = makeAir({24, 24, 24}, 0.05, AirBorder::Closed);
    AirSource source;
    source.radius = 0.3;
    source.smoke = 2.0;
    source.heat = 1.0;
    source.drives = true;
    source.velocity = {0.0, 1.5, -0.5};
    feedAir(air, source, {0.01, 0.02, 0.0}, 0.1);
    const double pi = std::acos(-1.0), volume = 4.0 / 3.0 * pi * 0.3 * 0.3 * 0.3;
    EXPECT_NEAR(airSmokeTotal(air), 2.0 * 0.1 * volume, 0.03 * 2.0 * 0.1 * volume);
    const Vec3 inside = airVelocityAt(air, {0.0, 0.0, 0.0});
    EXPECT_NEAR(inside.x, 0.0, 1e-6);
    EXPECT_NEAR(inside.y, 1.5, 1e-6);
    EXPECT_NEAR(inside.z, -0.5, 1e-6);
    EXPECT_EQ(airVelocityAt(air, {0.5, 0.0, 0.0}).y, 0.0f);

    Air small = makeAir({8, 8, 8}, 0.1, AirBorder::Closed);
    AirSource tiny;
    tiny.radius = 0.01;
    tiny.smoke = 1.0;
    feedAir(small, tiny, {0.12, -0.05, 0.03}, 0.5);
    EXPECT_EQ(small.smoke[small.at(5, 3, 4)], 0.5f);
    EXPECT_NEAR(airSmokeTotal(small), 0.5 * 0.001, 1e-12);

    // one smaller than a cell drives that cell's six faces (it drove none: a small fan blew nothing)
    tiny.drives = true;
    tiny.velocity = {0.0, 5.0, 0.0};
    feedAir(small, tiny, {0.12, -0.05, 0.03}, 0.5);
    for (const int j : {3, 4}) { // the v faces below and above cell (5, 3, 4)
        EXPECT_EQ(small.v[std::size_t(5 + 8 * (j + 9 * 4))], 5.0f) << j;
    }

    // a thin sheet on a face plane holds no cell's centre but drives every face inside it (49 here), not
    // only the six of the cell its centre is in (as a review found the line above first did)
    Air sheetAir = makeAir({8, 8, 8}, 0.1, AirBorder::Closed);
    AirSource sheet;
    sheet.sphere = false;
    sheet.halfExtents = {0.02, 0.35, 0.35};
    sheet.drives = true;
    sheet.velocity = {3.0, 0.0, 0.0};
    feedAir(sheetAir, sheet, {0.0, 0.0, 0.0}, 0.5);
    EXPECT_EQ(std::count(sheetAir.u.begin(), sheetAir.u.end(), 3.0f), 49);

    // and one whose centre has left the box feeds nothing (it fed the nearest edge cell for ever)
    Air left = makeAir({8, 8, 8}, 0.1, AirBorder::Closed);
    feedAir(left, tiny, {3.0, 0.0, 0.0}, 0.5);
    EXPECT_EQ(airSmokeTotal(left), 0.0);
    EXPECT_EQ(airKineticEnergy(left), 0.0);
}

} // namespace
} // namespace tumble

#include "components/particles.h"
#include "components/spring_network.h"
#include "engine/run_report.h"
#include "tests/test_support.h"

namespace tumble {
namespace {

/// Mean z of a network's masses.
double meanZ(const SpringNetwork& net) {
    double z = 0.0;
    for (const Vec3& x : net.x) {
        z += x.z;
    }
    return z / double(net.x.size());
}

/// A room of air open along z with two small curtains hanging side by side in it, the upper one in the jet
/// of a fan blowing along z when `fan`, and a wall between the fan and that curtain when `wall`.
std::string jetScene(bool fan, bool wall) {
    std::string text = "[scene]\nname = \"jet\"\ndt = 0.0166666667\n"
                       "[[entity]]\nname = \"room\"\n[entity.air]\ncells = [12, 16, 24]\n"
                       "size = [1.5, 2.0, 3.0]\nborder = { \"-z\" = \"open\", \"+z\" = \"open\" }\n"
                       "coefficient = 2.0\n";
    for (const auto& [name, y] : {std::pair{"upper", 0.6}, std::pair{"lower", -0.3}}) {
        text += std::string("[[entity]]\nname = \"") + name + "\"\n[entity.transform]\nposition = [0.0, " +
                std::to_string(y) +
                ", 0.0]\n[entity.cloth]\nrows = 8\ncols = 8\nsize = [0.4, 0.4]\nplane = \"xy\"\n"
                "mass = 0.05\nstretch = 500.0\nshear = 50.0\nbend = 0.5\npin = \"top-row\"\n"
                "integrator = \"implicit_euler\"\n";
    }
    if (fan) {
        text += "[[entity]]\nname = \"fan\"\n[entity.transform]\nposition = [0.0, 0.5, -1.1]\n"
                "[entity.air_source]\nair = \"room\"\nshape = \"box\"\nhalf_extents = [0.3, 0.3, 0.1]\n"
                "smoke = 0.0\nvelocity = [0.0, 0.0, 3.0]\n";
    }
    if (wall) {
        text += "[[entity]]\nname = \"wall\"\n[entity.transform]\nposition = [0.0, 0.5, -0.4]\n"
                "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.5, 0.5, 0.1]\nmass = 0.0\n";
    }
    return text;
}

/// How far the two curtains' masses moved along z on average in a second: upper, lower.
std::pair<double, double> curtainsPushed(const std::string& scene) {
    auto sim = test::makeSimulation(scene);
    const double upper0 = meanZ(test::component<SpringNetwork>(*sim, "upper"));
    const double lower0 = meanZ(test::component<SpringNetwork>(*sim, "lower"));
    for (int frame = 0; frame < 60; ++frame) {
        sim->runFrame();
    }
    return {meanZ(test::component<SpringNetwork>(*sim, "upper")) - upper0,
            meanZ(test::component<SpringNetwork>(*sim, "lower")) - lower0};
}

// Two small curtains hang side by side in a room of air; a fan blows along z at the height of the upper
// one. After a second the upper one is pushed downstream several times further than the lower one, and
// with the fan off neither moves along z (seen to fail with the air left out of the cloth's forces).
TEST(Air, ACurtainInAFansJetIsPushedFurtherThanOneBesideIt) {
    const auto [upper, lower] = curtainsPushed(jetScene(true, false));
    EXPECT_GT(upper, 0.03); // 0.061 m when written, the lower one 0.0036
    EXPECT_GT(upper, 5.0 * std::abs(lower));
    const auto [still, stillLower] = curtainsPushed(jetScene(false, false));
    EXPECT_NEAR(still, 0.0, 1e-9);
    EXPECT_NEAR(stillLower, 0.0, 1e-9);
}

// A static wall between the fan and the curtain shelters it: the air flows round the wall, and the curtain
// behind it moves along z by under a tenth of what it does in the open jet (seen to fail with the solid
// cells' faces left free).
TEST(Air, AWallSheltersACurtainFromTheJet) {
    const double open = curtainsPushed(jetScene(true, false)).first;
    const double sheltered = curtainsPushed(jetScene(true, true)).first;
    EXPECT_LT(std::abs(sheltered), 0.1 * open);
}

// A box moving at 2 m/s through still air (no gravity) drags the air beside it: half a second later the
// cells along its side move with it, the air ahead is pushed forward and the air behind follows it. Seen
// to fail with the solid cells' faces left free (the same test holds with only the faces across the
// surface held: it does not tell no-slip from free-slip).
TEST(Air, AMovingBoxDragsTheAirBesideIt) {
    auto sim = test::makeSimulation(
        "[scene]\nname = \"paddle\"\ngravity = [0.0, 0.0, 0.0]\n"
        "[[entity]]\nname = \"room\"\n[entity.air]\ncells = [32, 16, 16]\nsize = [4.0, 2.0, 2.0]\n"
        "[[entity]]\nname = \"paddle\"\n[entity.transform]\nposition = [-1.2, 0.0, 0.0]\n"
        "[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.3, 0.3, 0.3]\nmass = 1.0\n"
        "linear_velocity = [2.0, 0.0, 0.0]\nsleep = false\n");
    for (int frame = 0; frame < 30; ++frame) {
        sim->runFrame();
    }
    const Air& air = test::component<Air>(*sim, "room");
    const double x = -1.2 + 2.0 * 0.5; // where the box is now
    // the first layer of cells beside it (0.30 m/s when written; further out the air flows back round it)
    EXPECT_GT(airVelocityAt(air, {x, 0.3625, 0.0}).x, 0.2);
    EXPECT_GT(airVelocityAt(air, {x + 0.45, 0.0, 0.0}).x, 0.5); // ahead of it
    EXPECT_GT(airVelocityAt(air, {x - 0.45, 0.0, 0.0}).x, 1.0); // behind it
}

// Smoke puffs ride the air: particles born still in a fan's stream (no gravity) move downstream at about
// its speed after a second, with drag 5/s towards the air; the same emitter without `air` keeps them still.
TEST(Air, ParticlesRideTheAir) {
    auto meanVx = [](bool ride) {
        std::string text =
            "[scene]\nname = \"puffs\"\ngravity = [0.0, 0.0, 0.0]\n"
            "[[entity]]\nname = \"room\"\n[entity.air]\ncells = [24, 12, 12]\n"
            "size = [3.0, 1.5, 1.5]\nborder = { \"-x\" = \"open\", \"+x\" = \"open\" }\n"
            "[[entity]]\nname = \"fan\"\n[entity.transform]\nposition = [-1.0, 0.0, 0.0]\n"
            "[entity.air_source]\nair = \"room\"\nshape = \"box\"\nhalf_extents = [0.3, 0.7, 0.7]\n"
            "smoke = 0.0\nvelocity = [2.0, 0.0, 0.0]\n"
            "[[entity]]\nname = \"puffs\"\n[entity.transform]\nposition = [-1.0, 0.0, 0.0]\n"
            "[entity.emitter]\nburst = 200\nshape = \"sphere\"\nradius = 0.2\nspeed = [0.0, 0.0]\n"
            "lifetime = [5.0, 5.0]\ndrag = 5.0\ncollide = false\n";
        if (ride) {
            text += "air = \"room\"\n";
        }
        auto sim = test::makeSimulation(text);
        for (int frame = 0; frame < 60; ++frame) {
            sim->runFrame();
        }
        const ParticlePool& p = test::component<ParticleEmitter>(*sim, "puffs").pool;
        double vx = 0.0;
        for (std::uint32_t i = 0; i < p.count; ++i) {
            vx += p.vx[i];
        }
        return vx / double(p.count);
    };
    EXPECT_GT(meanVx(true), 1.0);
    EXPECT_EQ(meanVx(false), 0.0);
}

// The drag towards the air is exact over the step: particles born still in air flowing uniformly at 2 m/s
// along x (open at both ends, so the projection keeps it so), without gravity, with drag 5/s, move at
// 2 (1 - e^(-5 t)) after t, to float rounding. Seen to fail with the air's share added before the update's
// own decay (they settled at e^(-drag dt) of the air's speed).
TEST(Air, ParticlesTakeTheAirsSpeedAtTheirDragsRate) {
    auto sim = test::makeSimulation(
        "[scene]\nname = \"drift\"\ngravity = [0.0, 0.0, 0.0]\ndt = 0.0166666667\n"
        "[[entity]]\nname = \"room\"\n[entity.air]\ncells = [16, 8, 8]\nsize = [2.0, 1.0, 1.0]\n"
        "border = { \"-x\" = \"open\", \"+x\" = \"open\" }\n"
        "[[entity]]\nname = \"puffs\"\n[entity.transform]\nposition = [-0.6, 0.0, 0.0]\n"
        "[entity.emitter]\nburst = 50\nshape = \"sphere\"\nradius = 0.2\nspeed = [0.0, 0.0]\n"
        "lifetime = [10.0, 10.0]\ndrag = 5.0\ncollide = false\nair = \"room\"\n");
    Air& air = test::component<Air>(*sim, "room");
    std::fill(air.u.begin(), air.u.end(), 2.0f);
    const int frames = 30;
    for (int frame = 0; frame < frames; ++frame) {
        sim->runFrame();
    }
    const ParticlePool& p = test::component<ParticleEmitter>(*sim, "puffs").pool;
    ASSERT_EQ(p.count, 50u);
    const double expected = 2.0 * (1.0 - std::exp(-5.0 * frames * 0.0166666667));
    for (std::uint32_t i = 0; i < p.count; ++i) {
        EXPECT_NEAR(p.vx[i], expected, 1e-4) << "particle " << i;
        EXPECT_NEAR(p.vy[i], 0.0, 1e-5);
        EXPECT_NEAR(p.vz[i], 0.0, 1e-5);
    }
}

} // namespace
} // namespace tumble

namespace tumble {
namespace {

/// The chimney demo after 4 s: the smoke's centroid, and the air's mean velocity along x just behind the
/// block, below its roof.
struct Plume {
    Vec3 centroid;
    double leeFlow = 0.0; ///< m/s
};

Plume chimneyPlume(const std::string& text) {
    auto sim = test::makeSimulation(text);
    for (int frame = 0; frame < 240; ++frame) {
        sim->runFrame();
    }
    const Air& air = test::component<Air>(*sim, "sky");
    double flow = 0.0;
    int n = 0;
    for (double x = 0.65; x < 1.0; x += 0.1) {
        for (double y = 0.1; y < 0.9; y += 0.1) {
            for (double z = -0.3; z <= 0.3; z += 0.1) {
                flow += airVelocityAt(air, {x, y, z}).x;
                ++n;
            }
        }
    }
    return {airSmokeCentroid(air), flow / n};
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

// The chimney demo does what it says: the smoke rises from the stack (its centroid above the stack's top:
// the source blows it up and heat lifts it) and the wind bends it downstream (its centroid well downwind of
// the stack, where without wind it stays over it); behind the block the air curls back (its mean flow along x
// below the roof runs against the wind, where without the block it runs with it). Seen to fail with boxes
// left out of the voxeliser.
TEST(Air, TheChimneysPlumeBendsDownwindAndCurlsBehindTheBlock) {
    const std::string demo = test::readFile(std::string(TUMBLE_SOURCE_DIR) + "/demos/chimney.toml");
    const Plume plume = chimneyPlume(demo);
    EXPECT_GT(plume.centroid.y, 1.2);
    EXPECT_GT(plume.centroid.x, -1.3 + 0.8);
    const Plume calm =
        chimneyPlume(replaced(demo, "velocity = [1.6, 0.0, 0.0]", "velocity = [0.0, 0.0, 0.0]"));
    EXPECT_NEAR(calm.centroid.x, -1.3, 0.2);
    EXPECT_GT(calm.centroid.y, 1.2);
    const Plume open =
        chimneyPlume(replaced(demo, "position = [0.3, 0.6, 0.0]", "position = [0.3, 0.6, 9.0]"));
    EXPECT_LT(plume.leeFlow, 0.0);
    EXPECT_GT(open.leeFlow, 0.3);
}

} // namespace
} // namespace tumble

namespace tumble {
namespace {

// A uniform flow of 5 m/s through an 8 x 4 x 6 grid of 0.25 m cells has the kinetic energy of its air,
// 1/2 rho V u^2, to rounding. Seen to fail with every face counted as a whole cell: 12.5% high here (the
// two sides' faces along the flow each stand for half a cell).
TEST(Air, TheKineticEnergyOfAUniformFlowIsItsAirsHalfMVSquared) {
    Air air = makeAir({8, 4, 6}, 0.25, AirBorder::Open);
    std::fill(air.u.begin(), air.u.end(), 5.0f);
    const double volume = 8 * 4 * 6 * 0.25 * 0.25 * 0.25;
    EXPECT_NEAR(airKineticEnergy(air), 0.5 * 1.2 * volume * 25.0, 1e-9);
}

/// A nozzle of 2 cm blowing smoke along x through a tube of 1 cm cells, open at its far end: the smoke in
/// the tube after half a second, and the kinetic energy there.
std::pair<double, double> jet(double speed) {
    auto sim = test::makeSimulation(
        "[scene]\nname = \"jet\"\n[[entity]]\nname = \"room\"\n[entity.air]\ncells = [32, 16, 16]\n"
        "size = [0.32, 0.16, 0.16]\nborder = { \"+x\" = \"open\" }\n"
        "[[entity]]\nname = \"nozzle\"\n[entity.transform]\nposition = [-0.1, 0.0, 0.0]\n"
        "[entity.air_source]\nair = \"room\"\nradius = 0.02\nsmoke = 10.0\nvelocity = [" +
        std::to_string(speed) + ", 0.0, 0.0]\n");
    for (int frame = 0; frame < 30; ++frame) {
        sim->runFrame();
    }
    const Air& air = test::component<Air>(*sim, "room");
    return {airSmokeTotal(air), airKineticEnergy(air)};
}

// A jet whose speed carries the air further than its nozzle's size in a step (2 and 4 m/s: 3.3 and 6.7 cm
// a step through a nozzle of 2 cm) blows as a slow one does: its smoke and its flow fill the tube, more
// of the flow the faster it blows. Seen to fail with the sources fed before the advection, which carried
// every fed cell and face off in the same step: the fast jets left 1% of the slow one's smoke and no flow.
TEST(Air, AJetFasterThanItsNozzleIsWideStillBlows) {
    const auto [slowSmoke, slowEnergy] = jet(0.5);
    EXPECT_GT(slowSmoke, 0.0);
    for (const double speed : {2.0, 4.0}) {
        const auto [smoke, energy] = jet(speed);
        EXPECT_GT(smoke, 0.5 * slowSmoke) << speed << " m/s";
        EXPECT_GT(energy, slowEnergy) << speed << " m/s";
    }
}

// Explicit viscosity takes 6 nu dt / dx^2 substeps a step: a grid asking more than 1000 is refused at load
// (with what would fit), not run for minutes a step. Seen to fail with no bound: viscosity 1000 on 1 cm
// cells hung the run (a million substeps a step), and on 1 mm cells the count overflowed an int and the air
// blew up silently.
TEST(Air, AViscosityTooLargeForTheStepIsRefusedAtLoad) {
    for (const char* cell : {"0.16", "0.016"}) {
        try {
            test::makeSimulation(std::string("[scene]\nname = \"visc\"\n[[entity]]\nname = \"room\"\n"
                                             "[entity.air]\ncells = [16, 16, 16]\nsize = [") +
                                 cell + ", " + cell + ", " + cell + "]\nviscosity = 1000.0\n");
            ADD_FAILURE() << "not refused with " << cell << " m";
        } catch (const ScenarioError& e) {
            EXPECT_NE(std::string(e.what()).find("viscosity 1000 m^2/s"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("at most"), std::string::npos) << e.what();
        }
    }
    EXPECT_NO_THROW(test::makeSimulation("[scene]\nname = \"visc\"\n[[entity]]\nname = \"room\"\n"
                                         "[entity.air]\ncells = [16, 16, 16]\nsize = [1.6, 1.6, 1.6]\n"
                                         "viscosity = 1.0\n"));
}

// A grid driven past anything physical (1 mm cells at a step of a second, vorticity 100, buoyancy 1e4, a
// source of 1e6 degrees a second) blows up: it is frozen, still, and the run says so as a failure, while
// it goes on to its end. Seen to fail without the check: at frame 55 the velocity turned NaN and the next
// advection's gathers read past the arrays (the run died of SIGSEGV).
TEST(Air, AGridThatBlowsUpIsFrozenAndSaysSo) {
    auto sim = test::makeSimulation(
        "[scene]\nname = \"blow\"\ndt = 1.0\n"
        "[[entity]]\nname = \"room\"\n[entity.air]\ncells = [8, 8, 8]\nsize = [0.008, 0.008, 0.008]\n"
        "advection = \"maccormack\"\nvorticity = 100.0\nbuoyancy = [1e4, 1e4]\n"
        "[[entity]]\nname = \"fan\"\n[entity.transform]\nposition = [0.001, 0.0, 0.0]\n"
        "[entity.air_source]\nair = \"room\"\nshape = \"box\"\nhalf_extents = [0.001, 0.001, 0.001]\n"
        "smoke = 1000.0\nheat = 1e6\nvelocity = [10000.0, 10000.0, 1000.0]\n");
    for (int frame = 0; frame < 120; ++frame) {
        sim->runFrame();
    }
    const auto& failures = sim->world().resource<RunReport>().failures;
    ASSERT_EQ(failures.size(), 1u);
    EXPECT_NE(failures[0].find("air 'room' blew up at frame"), std::string::npos) << failures[0];
    const Air& air = test::component<Air>(*sim, "room");
    EXPECT_TRUE(air.frozen);
    for (const std::vector<float>* f : {&air.u, &air.v, &air.w, &air.smoke, &air.heat}) {
        EXPECT_TRUE(std::all_of(f->begin(), f->end(), [](float x) { return std::isfinite(x); }));
    }
    EXPECT_EQ(largestSpeed(air), 0.0);
}

} // namespace
} // namespace tumble

namespace tumble {
namespace {

/// A room of air 3 x 2 x 2 m on 24 x 16 x 16 cells (open along x when `open`) with a fan, a box 0.2 m
/// deep (`half` its half extents across, 0.35 m unless given) blowing 5 m/s along x, centred at x =
/// `fanX`, run for two seconds: the air's velocity along x 0.3 and 0.6 m downstream of its centre (0.2
/// and 0.5 m beyond its front), the grid's largest divergence and its last projection's CG iterations.
struct FanJet {
    double near, far, divergence;
    std::uint32_t iterations;
};
FanJet fanJet(bool open, double fanX, double half = 0.35) {
    auto sim = test::makeSimulation(
        std::string("[scene]\nname = \"fan\"\ndt = 0.0166666667\n[[entity]]\nname = \"room\"\n[entity.air]\n"
                    "cells = [24, 16, 16]\nsize = [3.0, 2.0, 2.0]\n") +
        (open ? "border = { \"-x\" = \"open\", \"+x\" = \"open\" }\n" : "") +
        "[[entity]]\nname = \"fan\"\n[entity.transform]\nposition = [" + std::to_string(fanX) +
        ", 0.0, 0.0]\n[entity.air_source]\nair = \"room\"\nshape = \"box\"\nhalf_extents = [0.1, " +
        std::to_string(half) + ", " + std::to_string(half) + "]\nsmoke = 0.0\nvelocity = [5.0, 0.0, 0.0]\n");
    for (int frame = 0; frame < 120; ++frame) {
        sim->runFrame();
    }
    const Air& air = test::component<Air>(*sim, "room");
    return {airVelocityAt(air, {fanX + 0.3, 0.0, 0.0}).x, airVelocityAt(air, {fanX + 0.6, 0.0, 0.0}).x,
            air.divergenceMax, air.lastIterations};
}

// A fan blows at the velocity it is given: its cells are held through the projection, the air flowing in
// behind it and out in front at 5 m/s (within 1% just beyond its front and further on), in a room open at
// both ends and in a closed one (where the air comes back round it). Seen to fail with the source's faces
// left to the projection: 4.15 and 4.21 m/s in the open room, 4.89 near it in the closed one (the
// divergence it put in was taken out of its own jet). A fan that would feed a closed pocket unevenly
// (against a closed room's wall, whose faces there stay walls; filling the room's whole section, the air
// on either side a pocket) is left to the projection: the divergence stays within the tolerance. Seen to
// fail with such fans held too: their pockets' pressure problems have no solution, and the divergence
// was 0.24 and 2e5 1/s.
TEST(Air, AFanBlowsAtTheVelocityItIsGiven) {
    const FanJet open = fanJet(true, -1.0);
    EXPECT_NEAR(open.near, 5.0, 0.05);
    EXPECT_NEAR(open.far, 5.0, 0.05);
    EXPECT_LT(open.divergence, 1e-3);
    const FanJet closed = fanJet(false, -0.8);
    EXPECT_NEAR(closed.near, 5.0, 0.05);
    EXPECT_GT(closed.far, 4.9);
    EXPECT_LT(closed.divergence, 1e-3);
    for (const auto& [x, half] : {std::pair{-1.4, 0.35}, std::pair{0.0, 1.0}}) {
        const FanJet pocket = fanJet(false, x, half);
        EXPECT_LT(pocket.divergence, 1e-3) << x << ", " << half;
        EXPECT_LT(pocket.iterations, 50u) << x << ", " << half;
        EXPECT_LT(pocket.near, 5.0) << x << ", " << half;
    }
}

} // namespace
} // namespace tumble

namespace tumble {
namespace {

// The chimney demo on coarser cells (24 x 18 x 12) keeps its air's kinetic energy near the steady
// crosswind's (1/2 rho V u^2 = 37 J for 1.6 m/s through the 24 m^3 box) for 12 s: between 25 and 60 J
// every second after the first two. Seen to fail with MacCormack's corrected velocity clamped to the
// values its first sample mixed: the energy burst past 500 J after 10 s (the full demo after 14-18 s).
TEST(Air, MacCormackAirKeepsItsEnergyInASteadyWind) {
    const std::string demo = test::readFile(std::string(TUMBLE_SOURCE_DIR) + "/demos/chimney.toml");
    auto sim = test::makeSimulation(replaced(demo, "cells = [36, 27, 18]", "cells = [24, 18, 12]"));
    for (int second = 1; second <= 12; ++second) {
        for (int frame = 0; frame < 60; ++frame) {
            sim->runFrame();
        }
        if (second > 2) {
            const double energy = airKineticEnergy(test::component<Air>(*sim, "sky"));
            EXPECT_GT(energy, 25.0) << "after " << second << " s";
            EXPECT_LT(energy, 60.0) << "after " << second << " s";
        }
    }
}

} // namespace
} // namespace tumble
