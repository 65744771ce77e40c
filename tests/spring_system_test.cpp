// The spring system against physics: free fall, the harmonic and damped oscillators, energy, pins.

#include "components/spring_network.h"
#include "engine/name.h"
#include "engine/run_report.h"
#include "systems/linear_solver.h"
#include "systems/spring_integrators.h"
#include "systems/spring_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <utility>
#include <vector>

namespace tumble {
namespace {

using test::makeSimulation;

SpringNetwork& network(Simulation& sim, const std::string& name) {
    return test::component<SpringNetwork>(sim, name);
}

/// One free mass on a spring of rest length 1 from a pin at the origin, no gravity: a 1D oscillator along x
/// with x(0) = 1 + a, v(0) = 0.
std::string oscillator(double dt, double k, double m, double kd, double amplitude) {
    return "[scene]\nname = \"osc\"\ngravity = [0, 0, 0]\ndt = " + std::to_string(dt) +
           "\n[[entity]]\nname = \"bob\"\n[entity.springs]\nmasses = [ { x = [0, 0, 0], pinned = true }, { x "
           "= [" +
           std::to_string(1.0 + amplitude) + ", 0, 0], m = " + std::to_string(m) +
           " } ]\nlinks = [ { a = 0, b = 1, rest = 1.0, k = " + std::to_string(k) +
           ", kd = " + std::to_string(kd) + " } ]\n";
}

/// Closed form of m x'' + c x' + k x = 0 with x(0) = a, x'(0) = 0 (underdamped).
double dampedDisplacement(double t, double k, double m, double c, double a) {
    const double zeta = c / (2.0 * std::sqrt(k * m));
    const double w0 = std::sqrt(k / m);
    const double wd = w0 * std::sqrt(1.0 - zeta * zeta);
    return a * std::exp(-zeta * w0 * t) * (std::cos(wd * t) + zeta * w0 / wd * std::sin(wd * t));
}

double displacementAfter(double dt, double seconds, double k, double m, double c, double a) {
    auto sim = makeSimulation(oscillator(dt, k, m, c, a));
    const auto steps = static_cast<int>(std::lround(seconds / dt));
    for (int i = 0; i < steps; ++i) {
        sim->runFrame();
    }
    return network(*sim, "bob").x[1].x - 1.0;
}

TEST(SpringSystem, FreeFallMatchesTheSymplecticEulerSolutionAndConvergesAtFirstOrder) {
    const double g = 9.81;
    double previousError = 0.0;
    for (double dt : {0.01, 0.005, 0.0025}) {
        auto sim = makeSimulation(
            "[scene]\nname = \"fall\"\ndt = " + std::to_string(dt) +
            "\n[[entity]]\nname = \"ball\"\n[entity.springs]\nmasses = [ { x = [0, 10, 0] } ]\n");
        const int steps = static_cast<int>(std::lround(1.0 / dt));
        for (int i = 0; i < steps; ++i) {
            sim->runFrame();
        }
        const double t = sim->time();
        const double y = network(*sim, "ball").x[0].y;
        const double exact = 10.0 - 0.5 * g * t * t;
        const double error = std::abs(y - exact);
        // symplectic Euler on constant acceleration is off by exactly g dt t / 2
        EXPECT_NEAR(error, 0.5 * g * dt * t, 1e-9) << "dt " << dt;
        if (previousError > 0.0) {
            EXPECT_NEAR(previousError / error, 2.0, 0.01) << "first order: halving dt halves the error";
        }
        previousError = error;
    }
}

TEST(SpringSystem, UndampedPeriodMatchesTwoPiRootMOverK) {
    const double k = 100.0, m = 0.5, dt = 1e-4;
    const double expected = 2.0 * std::numbers::pi * std::sqrt(m / k);
    auto sim = makeSimulation(oscillator(dt, k, m, 0.0, 0.1));
    // time between successive upward zero crossings of the displacement
    std::vector<double> crossings;
    double prev = network(*sim, "bob").x[1].x - 1.0;
    while (crossings.size() < 6) {
        sim->runFrame();
        const double d = network(*sim, "bob").x[1].x - 1.0;
        if (prev < 0.0 && d >= 0.0) {
            crossings.push_back(sim->time() - dt * d / (d - prev)); // linear interpolation in the step
        }
        prev = d;
        ASSERT_LT(sim->time(), 100.0 * expected) << "the oscillator never crossed zero";
    }
    const double period = (crossings.back() - crossings.front()) / double(crossings.size() - 1);
    EXPECT_NEAR(period, expected, 1e-3 * expected);
}

TEST(SpringSystem, DampedOscillatorMatchesClosedFormAndConvergesAtFirstOrder) {
    const double k = 40.0, m = 1.0, c = 1.5, a = 0.2, T = 2.0;
    const double exact = dampedDisplacement(T, k, m, c, a);
    const double e1 = std::abs(displacementAfter(0.002, T, k, m, c, a) - exact);
    const double e2 = std::abs(displacementAfter(0.001, T, k, m, c, a) - exact);
    const double e3 = std::abs(displacementAfter(0.0005, T, k, m, c, a) - exact);
    EXPECT_LT(e3, 2e-3 * a);
    EXPECT_NEAR(e1 / e2, 2.0, 0.3) << e1 << " " << e2;
    EXPECT_NEAR(e2 / e3, 2.0, 0.3) << e2 << " " << e3;
}

TEST(SpringSystem, SymplecticEulerKeepsUndampedEnergyBounded) {
    const double k = 100.0, m = 1.0, dt = 0.01, a = 0.1;
    auto sim = makeSimulation(oscillator(dt, k, m, 0.0, a));
    const double e0 = 0.5 * k * a * a;
    auto energy = [&] {
        const SpringNetwork& net = network(*sim, "bob");
        const double x = net.x[1].x - 1.0, v = net.v[1].x;
        return 0.5 * k * x * x + 0.5 * m * v * v;
    };
    // 200 periods (period 0.63 s): the relative error oscillates with amplitude ~ omega dt / 2 and never
    // grows
    double worstEarly = 0.0, worstLate = 0.0;
    const int steps = 12600;
    for (int i = 0; i < steps; ++i) {
        sim->runFrame();
        const double rel = std::abs(energy() - e0) / e0;
        double& worst = i < steps / 10 ? worstEarly : worstLate;
        worst = std::max(worst, rel);
    }
    const double omegaDt = std::sqrt(k / m) * dt;
    EXPECT_LT(worstLate, omegaDt) << "the energy error stays within the symplectic bound";
    EXPECT_LT(worstLate, 1.05 * worstEarly) << "and does not grow over 200 periods";
}

// A set of a `springs` network's masses takes the velocities it gives them (the masses and links stay), as a
// body set to a velocity takes it. Seen to fail before: accepted, and nothing changed. The oscillator at
// rest, no gravity: the set gives the bob v = (0, 0, 5) along no spring, which one symplectic step keeps
// (the spring, at its rest length, pulls nothing).
TEST(SpringSystem, ASetOfTheMassesVelocitiesTakesThem) {
    const std::string scene =
        oscillator(0.01, 100.0, 1.0, 0.0, 0.0) +
        "[[event]]\nframe = 2\naction = \"set\"\nkey = \"bob.springs.masses\"\n"
        "value = [ { x = [0, 0, 0], pinned = true }, { x = [1, 0, 0], v = [0, 0, 5] } ]\n";
    auto sim = makeSimulation(scene);
    for (int i = 0; i < 2; ++i) {
        sim->runFrame();
    }
    EXPECT_EQ(network(*sim, "bob").v[1].z, 0.0);
    sim->runFrame();
    const SpringNetwork& net = network(*sim, "bob");
    EXPECT_NEAR(net.v[1].z, 5.0, 1e-9);
    EXPECT_NEAR(net.x[1].z, 0.05, 1e-9) << "a step of 0.01 s at 5 m/s";
    EXPECT_EQ(net.v[0].z, 0.0) << "the pinned mass stays";
}

TEST(SpringSystem, PinnedMassesDoNotMove) {
    auto sim = makeSimulation(oscillator(0.01, 100.0, 1.0, 0.5, 0.3));
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
    }
    const SpringNetwork& net = network(*sim, "bob");
    EXPECT_EQ(net.x[0], (Vec3{0.0, 0.0, 0.0}));
    EXPECT_EQ(net.v[0], (Vec3{0.0, 0.0, 0.0}));
}

TEST(SpringSystem, ImpulseChangesMomentumByItsValue) {
    auto sim = makeSimulation(R"(
[scene]
name = "kick"
gravity = [0, 0, 0]
[[entity]]
name = "pair"
[entity.springs]
masses = [ { x = [0, 0, 0], m = 1.0 }, { x = [1, 0, 0], m = 3.0 } ]
links = [ { a = 0, b = 1 } ]
[[event]]
frame = 2
entity = "pair"
action = "impulse"
value = [0, 0, 8]
)");
    auto momentum = [&] {
        const SpringNetwork& net = network(*sim, "pair");
        Vec3 p;
        for (std::size_t i = 0; i < net.v.size(); ++i) {
            p += net.v[i] * (1.0 / net.invMass[i]);
        }
        return p;
    };
    sim->runFrame();
    sim->runFrame();
    EXPECT_EQ(momentum().z, 0.0) << "the event is due at the start of step 2, not before";
    sim->runFrame();
    EXPECT_NEAR(momentum().z, 8.0, 1e-12);
}

// The state hash covers what shapes the next step: besides dv (the warm start), the solutions the next
// solve's first guess combines (linear_solver.h), and nothing it recomputes.
TEST(SpringSystem, TheStateHashTakesTheSolutionsTheNextFirstGuessCombines) {
    auto sim = test::makeSimulation(test::readFile(std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml"));
    for (int i = 0; i < 3; ++i) {
        sim->runFrame();
    }
    const std::uint64_t before = sim->hash();
    SpringWorkspace* work = nullptr;
    sim->world().view<SpringWorkspace>().each([&](Entity, SpringWorkspace& w) { work = &w; });
    ASSERT_NE(work, nullptr);
    PcgVectors<float>& pcg = work->single.pcg;
    ASSERT_EQ(pcg.remembered, kGuessHistory) << "one solve a frame";
    for (std::size_t k = 0; k + 1 < kGuessHistory; ++k) {
        const Vec3T<float> kept = pcg.solutions[k][5];
        pcg.solutions[k][5].x += 1.0f;
        EXPECT_NE(sim->hash(), before) << "solution " << k << " is combined by the next solve";
        pcg.solutions[k][5] = kept;
    }
    // the oldest is forgotten before the next solve, and the products are taken again
    pcg.solutions[kGuessHistory - 1][5].x += 1.0f;
    pcg.products[0][5].x += 1.0f;
    EXPECT_EQ(sim->hash(), before);
}

// A cloth's matrix (1225 masses: the curtain) is read from its blocks' upper triangles: each entry of its
// assembly is formed as its mirror is, to the bit (else the step would run on the stored blocks, as
// fast as before the packing, and no other test would see it).
TEST(SpringSystem, AClothsMatrixIsPackedAsItsBlocksAreSymmetric) {
    auto sim = test::makeSimulation(test::readFile(std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml"));
    for (int i = 0; i < 3; ++i) {
        sim->runFrame();
    }
    const SpringWorkspace& work = test::component<SpringWorkspace>(*sim, "curtain");
    EXPECT_GE(work.single.system.n, kPackedRows);
    EXPECT_TRUE(work.single.system.isPacked());
}

// Which networks step alone (each on every thread) and which side by side (each on one thread): a network
// with more than an equal share of the work left (shared by the threads, or by the networks left if fewer)
// steps alone, the largest first.
TEST(SpringSystem, ANetworkWithMoreThanItsShareOfTheWorkStepsAloneOnEveryThread) {
    using Indices = std::vector<std::size_t>;
    // stress_cloth at two threads: the 150 x 150 cloth has more than half, then the 100 x 100 more than
    // half of the rest, then the 64 x 64; the last, by itself, steps on one thread either way
    const std::vector<double> stress = {12250.0, 40960.0, 100000.0, 225000.0};
    NetworkShares s = shareOutNetworks(stress, 2);
    EXPECT_EQ(s.alone, (Indices{3, 2, 1}));
    EXPECT_EQ(s.together, (Indices{0}));
    // at 16 threads the shares are of the networks left: the same
    EXPECT_EQ(shareOutNetworks(stress, 16).alone, (Indices{3, 2, 1}));
    // equal networks share out evenly side by side: none has more than its share, at as many threads as
    // networks, fewer or more
    s = shareOutNetworks(std::vector<double>(4, 100.0), 2);
    EXPECT_TRUE(s.alone.empty());
    EXPECT_EQ(s.together, (Indices{0, 1, 2, 3}));
    EXPECT_TRUE(shareOutNetworks(std::vector<double>(16, 100.0), 16).alone.empty());
    EXPECT_TRUE(shareOutNetworks({100.0, 100.0}, 3).alone.empty());
    // one large among small ones: it alone, then the small ones side by side, in entity order
    s = shareOutNetworks({10.0, 1000.0, 10.0, 10.0, 10.0}, 4);
    EXPECT_EQ(s.alone, (Indices{1}));
    EXPECT_EQ(s.together, (Indices{0, 2, 3, 4}));
    // two of the same size, both more than their share: the first in entity order first
    s = shareOutNetworks({500.0, 10.0, 500.0}, 4);
    EXPECT_EQ(s.alone, (Indices{0, 2}));
    EXPECT_EQ(s.together, (Indices{1}));
    // one thread: nothing to share
    s = shareOutNetworks(stress, 1);
    EXPECT_TRUE(s.alone.empty());
    EXPECT_EQ(s.together, (Indices{0, 1, 2, 3}));
    EXPECT_TRUE(shareOutNetworks({}, 4).together.empty());
}

// A cloth large enough to step alone on every thread beside a network that blows up and one at rest: the
// same bits every frame and the same report at one thread (all in one loop) and at four (the cloth alone on
// every thread, then the two small ones, as their shares say).
TEST(SpringSystem, ABlowUpBesideANetworkSteppingAloneIsTheSameAtAnyThreadCount) {
    const std::string scene =
        std::string("[scene]\nname = \"mixed\"\ndt = 0.0166666667\n") + test::kBlowingUpBob + R"(
[[entity]]
name = "sheet"
[entity.cloth]
rows = 24
cols = 24
size = [1.0, 1.0]
plane = "xy"
mass = 1.0
stretch = 2000.0
pin = "top-row"
integrator = "implicit_euler"
[[entity]]
name = "calm"
[entity.springs]
masses = [ { x = [0, 5, 0] } ]
)";
    auto run = [&](int threads) {
        auto sim = makeSimulation(scene);
        sim->setThreads(threads);
        std::vector<std::uint64_t> hashes;
        for (int f = 0; f < 60; ++f) {
            sim->runFrame();
            hashes.push_back(sim->hash());
        }
        EXPECT_TRUE(network(*sim, "bob").frozen);
        EXPECT_FALSE(network(*sim, "sheet").frozen);
        return std::make_pair(hashes, sim->world().resource<RunReport>().failures);
    };
    const auto one = run(1);
    const auto four = run(4);
    EXPECT_EQ(one.first, four.first);
    ASSERT_EQ(one.second.size(), 1u);
    EXPECT_EQ(one.second, four.second);
}

// A mass costs about 10 times as much under implicit Euler as under symplectic Euler, and an explicit
// method as many times as it evaluates the forces.
TEST(SpringSystem, ANetworksWorkIsItsMassesTimesWhatItsIntegratorCostsAMass) {
    SpringNetwork net;
    net.x.resize(100);
    const std::pair<Integrator, double> costs[] = {{Integrator::SymplecticEuler, 100.0},
                                                   {Integrator::ExplicitEuler, 100.0},
                                                   {Integrator::Midpoint, 200.0},
                                                   {Integrator::Rk4, 400.0},
                                                   {Integrator::ImplicitEuler, 1000.0}};
    for (const auto& [integrator, work] : costs) {
        net.integrator = integrator;
        EXPECT_EQ(networkWork(net), work) << integratorName(integrator);
    }
}
} // namespace
} // namespace tumble
