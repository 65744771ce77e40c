// The five integrators against the theory of the harmonic oscillator: order of convergence as dt halves,
// energy growth, conservation and loss, and stability on a stiff spring.
//
// The test oscillator is one free mass on a spring of rest length 1 from a pin at the origin, moving along
// x with no gravity: the force -k (x - 1) - c v is exactly linear, so the closed forms below are exact.

#include "components/spring_network.h"
#include "engine/run_report.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>

namespace tumble {
namespace {

using test::makeSimulation;

std::string num(double v) {
    std::ostringstream os;
    os.precision(17);
    os << v;
    return os.str();
}

struct Oscillator {
    double k = 40.0, m = 1.0, c = 0.0, a = 0.2; ///< N/m, kg, N s/m, m (initial stretch)
};

std::unique_ptr<Simulation> oscillator(const std::string& integrator, double dt, const Oscillator& o) {
    return makeSimulation("[scene]\nname = \"osc\"\ngravity = [0, 0, 0]\ndt = " + num(dt) +
                          "\n[[entity]]\nname = \"bob\"\n[entity.springs]\nintegrator = \"" + integrator +
                          "\"\nsolver_precision = \"double\"\ncg_tolerance = 1e-13\n"
                          "masses = [ { x = [0, 0, 0], pinned = true }, { x = [" +
                          num(1.0 + o.a) + ", 0, 0], m = " + num(o.m) +
                          " } ]\nlinks = [ { a = 0, b = 1, rest = 1.0, k = " + num(o.k) +
                          ", kd = " + num(o.c) + " } ]\n");
}

const SpringNetwork& bob(Simulation& sim) {
    const SpringNetwork* out = nullptr;
    sim.world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& n) { out = &n; });
    return *out;
}

/// Displacement from rest of m x'' + c x' + k x = 0, x(0) = a, x'(0) = 0 (underdamped).
double exactDisplacement(double t, const Oscillator& o) {
    const double zeta = o.c / (2.0 * std::sqrt(o.k * o.m));
    const double w0 = std::sqrt(o.k / o.m);
    const double wd = w0 * std::sqrt(1.0 - zeta * zeta);
    return o.a * std::exp(-zeta * w0 * t) * (std::cos(wd * t) + zeta * w0 / wd * std::sin(wd * t));
}

double errorAt(const std::string& integrator, double dt, double seconds, const Oscillator& o) {
    auto sim = oscillator(integrator, dt, o);
    const auto steps = std::lround(seconds / dt);
    for (long i = 0; i < steps; ++i) {
        sim->runFrame();
    }
    return std::abs(bob(*sim).x[1].x - 1.0 - exactDisplacement(sim->time(), o));
}

double energy(Simulation& sim, const Oscillator& o) {
    const SpringNetwork& net = bob(sim);
    const double x = net.x[1].x - 1.0, v = net.v[1].x;
    return 0.5 * o.k * x * x + 0.5 * o.m * v * v;
}

struct OrderCase {
    const char* integrator;
    int order;
};

void PrintTo(const OrderCase& c, std::ostream* os) {
    *os << c.integrator << " (order " << c.order << ")";
}

class IntegratorOrder : public ::testing::TestWithParam<OrderCase> {};

TEST_P(IntegratorOrder, DampedOscillatorErrorShrinksAtTheIntegratorsOrder) {
    const OrderCase c = GetParam();
    const Oscillator o{40.0, 1.0, 1.5, 0.2};
    const double e1 = errorAt(c.integrator, 0.004, 1.0, o);
    const double e2 = errorAt(c.integrator, 0.002, 1.0, o);
    const double e3 = errorAt(c.integrator, 0.001, 1.0, o);
    const double expected = std::pow(2.0, c.order);
    // each halving of dt divides the error by 2^order (within 15%)
    EXPECT_NEAR(e1 / e2, expected, 0.15 * expected) << e1 << " " << e2;
    EXPECT_NEAR(e2 / e3, expected, 0.15 * expected) << e2 << " " << e3;
    // and the solution is close to the closed form to begin with
    EXPECT_LT(e3, 0.01 * o.a) << c.integrator;
}

INSTANTIATE_TEST_SUITE_P(Springs, IntegratorOrder,
                         ::testing::Values(OrderCase{"explicit_euler", 1}, OrderCase{"midpoint", 2},
                                           OrderCase{"rk4", 4}, OrderCase{"symplectic_euler", 1},
                                           OrderCase{"implicit_euler", 1}),
                         [](const ::testing::TestParamInfo<OrderCase>& p) {
                             return std::string(p.param.integrator);
                         });

/// One step of each method on the linear oscillator, written from its definition (spring_integrators.h):
/// the exact discrete recurrence the integrator must follow, step for step.
void recurrenceStep(const std::string& method, double h, const Oscillator& o, double& x, double& v) {
    auto a = [&](double xx, double vv) { return (-o.k * xx - o.c * vv) / o.m; };
    if (method == "explicit_euler") {
        const double x1 = x + h * v, v1 = v + h * a(x, v);
        x = x1;
        v = v1;
    } else if (method == "symplectic_euler") {
        v = v + h * a(x, v);
        x = x + h * v;
    } else if (method == "midpoint") {
        const double xm = x + 0.5 * h * v, vm = v + 0.5 * h * a(x, v);
        const double x1 = x + h * vm, v1 = v + h * a(xm, vm);
        x = x1;
        v = v1;
    } else if (method == "rk4") {
        const double v1 = v, a1 = a(x, v);
        const double v2 = v + 0.5 * h * a1, a2 = a(x + 0.5 * h * v1, v2);
        const double v3 = v + 0.5 * h * a2, a3 = a(x + 0.5 * h * v2, v3);
        const double v4 = v + h * a3, a4 = a(x + h * v3, v4);
        x += h / 6.0 * (v1 + 2.0 * v2 + 2.0 * v3 + v4);
        v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
    } else { // implicit_euler: (m + h c + h^2 k) dv = h (-k x - c v - h k v), v' = v + dv, x' = x + h v'
        const double dv = h * (-o.k * x - o.c * v - h * o.k * v) / (o.m + h * o.c + h * h * o.k);
        v += dv;
        x += h * v;
    }
}

class IntegratorRecurrence : public ::testing::TestWithParam<OrderCase> {};

TEST_P(IntegratorRecurrence, EachStepIsTheMethodsExactDiscreteRecurrence) {
    // a damped oscillator at a coarse step (omega h = 0.25), 400 steps: the simulated state against the
    // method's own recurrence, within 1e-9 of the amplitude after every step (a method that is merely of
    // the right order, or another method of that order, drifts far beyond that)
    const OrderCase c = GetParam();
    const Oscillator o{40.0, 1.0, 1.5, 0.2};
    const double h = 0.04;
    auto sim = oscillator(c.integrator, h, o);
    double x = o.a, v = 0.0;
    for (int step = 1; step <= 400; ++step) {
        sim->runFrame();
        recurrenceStep(c.integrator, h, o, x, v);
        const SpringNetwork& net = bob(*sim);
        ASSERT_NEAR(net.x[1].x - 1.0, x, 1e-9 * o.a) << c.integrator << ", step " << step;
        ASSERT_NEAR(net.v[1].x, v, 1e-9 * o.a * std::sqrt(o.k / o.m)) << c.integrator << ", step " << step;
    }
}

INSTANTIATE_TEST_SUITE_P(Springs, IntegratorRecurrence,
                         ::testing::Values(OrderCase{"explicit_euler", 1}, OrderCase{"midpoint", 2},
                                           OrderCase{"rk4", 4}, OrderCase{"symplectic_euler", 1},
                                           OrderCase{"implicit_euler", 1}),
                         [](const ::testing::TestParamInfo<OrderCase>& p) {
                             return std::string(p.param.integrator);
                         });

TEST(Integrators, ExplicitEulerGainsEnergyAsTheTheorySays) {
    // on an undamped oscillator each explicit Euler step multiplies the energy by exactly 1 + (omega h)^2
    const Oscillator o{100.0, 1.0, 0.0, 0.1};
    const double h = 0.01, omegaH = std::sqrt(o.k / o.m) * h;
    auto sim = oscillator("explicit_euler", h, o);
    const double e0 = energy(*sim, o);
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
    }
    const double predicted = e0 * std::pow(1.0 + omegaH * omegaH, 300);
    EXPECT_NEAR(energy(*sim, o), predicted, 1e-9 * predicted);
    EXPECT_GT(energy(*sim, o), 19.0 * e0) << "about twentyfold in three seconds";
}

TEST(Integrators, ImplicitEulerLosesEnergyAsTheTheorySays) {
    // backward Euler on the same oscillator divides the energy by 1 + (omega h)^2 every step
    const Oscillator o{100.0, 1.0, 0.0, 0.1};
    const double h = 0.01, omegaH = std::sqrt(o.k / o.m) * h;
    auto sim = oscillator("implicit_euler", h, o);
    const double e0 = energy(*sim, o);
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
    }
    const double predicted = e0 / std::pow(1.0 + omegaH * omegaH, 300);
    EXPECT_NEAR(energy(*sim, o), predicted, 1e-6 * predicted);
    EXPECT_LT(energy(*sim, o), 0.06 * e0);
}

TEST(Integrators, SymplecticEulerEnergyStaysBoundedForThousandsOfPeriods) {
    const Oscillator o{100.0, 1.0, 0.0, 0.1};
    const double h = 0.01, omegaH = std::sqrt(o.k / o.m) * h;
    auto sim = oscillator("symplectic_euler", h, o);
    const double e0 = energy(*sim, o);
    double worst = 0.0;
    // 1000 periods of 0.63 s
    for (int i = 0; i < 62832; ++i) {
        sim->runFrame();
        worst = std::max(worst, std::abs(energy(*sim, o) - e0) / e0);
    }
    EXPECT_LT(worst, omegaH) << "bounded by O(omega h), not growing";
    EXPECT_LT(std::abs(energy(*sim, o) - e0) / e0, omegaH);
}

TEST(Integrators, MidpointAndRk4DriftSlowly) {
    // midpoint gains energy slowly (|amplification|^2 = 1 + (omega h)^4 / 4), RK4 loses it slowly
    const Oscillator o{100.0, 1.0, 0.0, 0.1};
    auto mid = oscillator("midpoint", 0.01, o);
    auto rk = oscillator("rk4", 0.01, o);
    const double e0 = energy(*mid, o);
    for (int i = 0; i < 1000; ++i) {
        mid->runFrame();
        rk->runFrame();
    }
    EXPECT_GT(energy(*mid, o), e0);
    EXPECT_NEAR(energy(*mid, o), e0 * std::pow(1.0 + std::pow(0.1, 4) / 4.0, 1000), 1e-9 * e0);
    EXPECT_LT(energy(*rk, o), e0);
    EXPECT_GT(energy(*rk, o), 0.999 * e0);
}

TEST(Integrators, StiffSpringAtSixtyHertzStaysBoundedUnderImplicitEuler) {
    // k = 1e6 at dt = 1/60: omega h = 16.7, far beyond every explicit method's stability limit
    for (const char* precision : {"double", "float"}) {
        auto sim =
            makeSimulation("[scene]\nname = \"stiff\"\ngravity = [0, -9.81, 0]\ndt = 0.016666666666666666\n"
                           "[[entity]]\nname = \"bob\"\n[entity.springs]\nintegrator = \"implicit_euler\"\n"
                           "solver_precision = \"" +
                           std::string(precision) +
                           "\"\nmasses = [ { x = [0, 0, 0], pinned = true }, { x = [1.5, 0, 0] } ]\n"
                           "links = [ { a = 0, b = 1, rest = 1.0, k = 1e6 } ]\n");
        for (int i = 0; i < 600; ++i) {
            sim->runFrame();
            const SpringNetwork& net = bob(*sim);
            ASSERT_TRUE(isFinite(net.x[1]) && isFinite(net.v[1])) << precision << " frame " << i;
            ASSERT_LT(length(net.x[1]), 1.5 + 1e-9) << "never further out than it started";
        }
        EXPECT_TRUE(sim->world().resource<RunReport>().failures.empty());
        EXPECT_NEAR(length(bob(*sim).x[1]), 1.0, 1e-3) << "it settles at its rest length";
    }
}

TEST(Integrators, StiffSpringUnderExplicitEulerIsCaughtNotCrashed) {
    for (const char* integrator : {"explicit_euler", "midpoint", "rk4", "symplectic_euler"}) {
        auto sim = makeSimulation("[scene]\nname = \"stiff\"\ndt = 0.016666666666666666\n"
                                  "[[entity]]\nname = \"bob\"\n[entity.springs]\nintegrator = \"" +
                                  std::string(integrator) +
                                  "\"\nmasses = [ { x = [0, 0, 0], pinned = true }, { x = [1.5, 0, 0] } ]\n"
                                  "links = [ { a = 0, b = 1, rest = 1.0, k = 1e6 } ]\n");
        for (int i = 0; i < 120; ++i) {
            ASSERT_NO_THROW(sim->runFrame());
        }
        const auto& failures = sim->world().resource<RunReport>().failures;
        ASSERT_EQ(failures.size(), 1u) << integrator;
        EXPECT_NE(failures[0].find(integrator), std::string::npos) << failures[0];
        EXPECT_TRUE(bob(*sim).frozen);
    }
}

} // namespace
} // namespace tumble
