// Particle systems against physics and arithmetic: projectile motion, exact emission counts, the steady
// state, floors that hold, a vortex that keeps its radius, the cone of directions, and the kernel.

#include "components/particles.h"
#include "engine/parallel.h"
#include "engine/random.h"
#include "engine/simd.h"
#include "systems/particle_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

#include <cmath>
#include <numbers>

namespace tumble {
namespace {

using test::makeSimulation;

ParticleEmitter& emitter(Simulation& sim) {
    ParticleEmitter* out = nullptr;
    sim.world().view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) { out = &e; });
    return *out;
}

std::string scene(const std::string& emitterKeys, const std::string& extra = "",
                  const std::string& dt = "0.01") {
    return "[scene]\nname = \"p\"\ndt = " + dt + "\n[[entity]]\nname = \"spout\"\n[entity.emitter]\n" +
           emitterKeys + "\n" + extra;
}

TEST(ParticleSystem, BurstThrownUpFollowsTheProjectileWithinSymplecticEulersError) {
    const double v0 = 12.0, g = 9.81, dt = 0.01;
    auto sim =
        makeSimulation(scene("burst = 20\nspeed = [12.0, 12.0]\nspread_deg = 0.0\nlifetime = [10.0, 10.0]\n"
                             "direction = [0, 1, 0]\ncollide = false"));
    for (int n = 1; n <= 200; ++n) {
        sim->runFrame();
        const double t = n * dt;
        const double exact = v0 * t - 0.5 * g * t * t;
        const ParticlePool& p = emitter(*sim).pool;
        ASSERT_EQ(p.count, 20u);
        for (std::uint32_t i = 0; i < p.count; ++i) {
            // symplectic Euler under constant gravity lands exactly g dt t / 2 below the parabola
            ASSERT_NEAR(p.py[i], exact - 0.5 * g * dt * t, 1e-4 + 1e-5 * std::abs(exact)) << "step " << n;
            ASSERT_EQ(p.px[i], 0.0f);
            ASSERT_EQ(p.pz[i], 0.0f);
        }
    }
}

TEST(ParticleSystem, RateBirthsAreExactIncludingFractions) {
    for (const auto& [rate, dt, seconds, expected] :
         std::vector<std::tuple<std::string, std::string, int, std::uint32_t>>{
             {"100.0", "0.0166666667", 120, 200u}, // 100 per second for 2 s at 60 Hz: 1.67 a step, 200 in all
             {"100.0", "0.01", 200, 200u},
             {"7.5", "0.01", 200, 15u},
             {"1000.0", "0.0166666667", 60, 1000u}}) {
        auto sim =
            makeSimulation(scene("rate = " + rate + "\nlifetime = [100.0, 100.0]\ncollide = false", "", dt));
        for (int i = 0; i < seconds; ++i) {
            sim->runFrame();
        }
        EXPECT_EQ(emitter(*sim).born, expected) << rate << " at dt " << dt;
        EXPECT_EQ(emitter(*sim).pool.count, expected);
    }
}

TEST(ParticleSystem, SteadyStateCountIsExactlyTheBirthsOfALifetime) {
    // 300 a second at dt = 0.01: 3 births a step. Each particle is born at the start of a step and updated
    // in that step and each after; it dies in the update where its age, K dt, reaches its lifetime of 2 s:
    // K = 200. So it outlives K - 1 steps, and after every step 3 (K - 1) are alive: exactly (a lifetime
    // off by one step is 3 particles; ages summed in float took 201 steps to reach 2 s)
    const int K = 200;
    auto sim = makeSimulation(scene("rate = 300.0\nlifetime = [2.0, 2.0]\ncollide = false"));
    for (int i = 0; i < 500; ++i) {
        sim->runFrame();
    }
    for (int i = 0; i < 100; ++i) {
        sim->runFrame();
        ASSERT_EQ(emitter(*sim).pool.count, std::uint32_t(3 * (K - 1))) << "K = " << K;
    }
}

TEST(ParticleSystem, ALongLifeEndsInTheStepItsAgeReachesIt) {
    // 50 s at dt = 1/60 is 3000 steps: the particle of a burst is alive after 2999 and gone after 3000 (ages
    // summed in float reached 50 s one step late; 1000 s, thirteen steps late)
    auto sim = makeSimulation(
        scene("burst = 1\nlifetime = [50.0, 50.0]\ncollide = false", "", "0.0166666666666666667"));
    for (int i = 0; i < 2999; ++i) {
        sim->runFrame();
    }
    EXPECT_EQ(emitter(*sim).pool.count, 1u);
    sim->runFrame();
    EXPECT_EQ(emitter(*sim).pool.count, 0u);
    // 2.1 s at dt = 0.3 is 7 steps, though 2.1 / 0.3 is a little over 7 in double
    sim = makeSimulation(scene("burst = 1\nlifetime = [2.1, 2.1]\ncollide = false", "", "0.3"));
    for (int i = 0; i < 6; ++i) {
        sim->runFrame();
    }
    EXPECT_EQ(emitter(*sim).pool.count, 1u);
    sim->runFrame();
    EXPECT_EQ(emitter(*sim).pool.count, 0u);
}

TEST(ParticleSystem, FullPoolDropsBirthsAndCountsThem) {
    auto sim =
        makeSimulation(scene("burst = 100\nmax_particles = 60\nlifetime = [5.0, 5.0]\ncollide = false"));
    sim->runFrame();
    EXPECT_EQ(emitter(*sim).pool.count, 60u);
    EXPECT_EQ(emitter(*sim).dropped, 40u);
    EXPECT_EQ(emitter(*sim).born, 60u);
}

TEST(ParticleSystem, ParticlesThrownAtAFloorNeverEndUpBelowIt) {
    auto sim = makeSimulation(
        scene("rate = 2000.0\nspeed = [5.0, 15.0]\nspread_deg = 40.0\ndirection = [0.3, -1, 0.1]\n"
              "lifetime = [3.0, 4.0]\nrestitution = 0.6",
              "[entity.transform]\nposition = [0, 2, 0]\n[[entity]]\nname = \"floor\"\n"
              "[entity.rigid_body]\nshape = \"plane\"\n[[entity]]\nname = \"ball\"\n"
              "[entity.transform]\nposition = [1, 0.2, 0]\n[entity.rigid_body]\nshape = \"sphere\"\n"
              "radius = 0.5\n"));
    std::uint64_t checked = 0;
    for (int i = 0; i < 300; ++i) {
        sim->runFrame();
        const ParticlePool& p = emitter(*sim).pool;
        for (std::uint32_t k = 0; k < p.count; ++k) {
            ASSERT_GE(p.py[k], 0.0f) << "frame " << i << " at " << p.px[k] << " " << p.py[k] << " " << p.pz[k]
                                     << " v " << p.vx[k] << " " << p.vy[k] << " " << p.vz[k];
            const double dx = p.px[k] - 1.0, dy = p.py[k] - 0.2, dz = p.pz[k];
            ASSERT_GE(dx * dx + dy * dy + dz * dz, 0.25 * (1.0 - 1e-5)) << "inside the ball at frame " << i;
            ++checked;
        }
    }
    EXPECT_GT(checked, 100000u);
}

TEST(ParticleSystem, VortexWithoutDragKeepsEachParticlesRadius) {
    const double omega = 3.0;
    auto sim =
        makeSimulation(scene("lifetime = [100.0, 100.0]\ncollide = false\nmax_particles = 64",
                             "[[entity]]\nname = \"twister\"\n[entity.force_field]\nkind = \"vortex\"\n"
                             "strength = 3.0\ncoefficient = 0.0\naxis = [0, 1, 0]\n",
                             "0.001"));
    // particles circling the axis at the vortex's own angular speed, at several radii and heights
    ParticlePool& p = emitter(*sim).pool;
    Rng rng(5);
    for (std::uint32_t i = 0; i < 32; ++i) {
        const double r = 0.5 + 0.05 * i, phi = rng.uniform(0.0, 2.0 * std::numbers::pi);
        p.px[i] = float(r * std::cos(phi));
        p.pz[i] = float(r * std::sin(phi));
        p.py[i] = float(rng.uniform(0.0, 1.0));
        // omega (axis x r) with axis y: (r_z, 0, -r_x) omega
        p.vx[i] = float(omega * p.pz[i]);
        p.vz[i] = float(-omega * p.px[i]);
        p.deathStep[i] = 1000000; // a step far beyond the test's
    }
    p.count = 32;
    std::vector<double> radius(32);
    for (std::uint32_t i = 0; i < 32; ++i) {
        radius[i] = std::hypot(p.px[i], p.pz[i]);
    }
    sim->world().resource<SceneDef>().gravity = {0.0, 0.0, 0.0};
    for (int n = 0; n < 5000; ++n) { // 5 s: about two and a half turns
        sim->runFrame();
    }
    ASSERT_EQ(emitter(*sim).pool.count, 32u);
    for (std::uint32_t i = 0; i < 32; ++i) {
        const ParticlePool& q = emitter(*sim).pool;
        EXPECT_NEAR(std::hypot(q.px[i], q.pz[i]), radius[i], 0.005 * radius[i]) << i;
    }
}

TEST(ParticleSystem, DirectionsFillTheSpreadConeUniformly) {
    auto sim = makeSimulation(
        scene("burst = 20000\nmax_particles = 20000\nspread_deg = 60.0\ndirection = [0, 0, 1]\n"
              "speed = [1.0, 1.0]\ncollide = false\nlifetime = [5.0, 5.0]",
              "", "0.000001"));
    sim->world().resource<SceneDef>().gravity = {0.0, 0.0, 0.0};
    sim->runFrame();
    const ParticlePool& p = emitter(*sim).pool;
    ASSERT_EQ(p.count, 20000u);
    double sumCos = 0.0, sumX = 0.0, sumY = 0.0;
    for (std::uint32_t i = 0; i < p.count; ++i) {
        const double c = p.vz[i]; // unit speed: the cosine to the axis
        ASSERT_GE(c, 0.5 - 1e-6) << "inside the 60 degree cone";
        sumCos += c;
        sumX += p.vx[i];
        sumY += p.vy[i];
    }
    // uniform over the cap: cos theta uniform in [0.5, 1] (mean 0.75, sd 0.144); no azimuth preferred
    EXPECT_NEAR(sumCos / p.count, 0.75, 0.004);
    EXPECT_NEAR(sumX / p.count, 0.0, 0.01);
    EXPECT_NEAR(sumY / p.count, 0.0, 0.01);
}

TEST(ParticleSystem, SameSeedSameParticlesOtherSeedOthers) {
    const std::string text = scene("rate = 500.0\nspread_deg = 30.0\nspeed = [2.0, 6.0]\nshape = \"sphere\"\n"
                                   "radius = 0.3\ncollide = false");
    auto a = makeSimulation(text), b = makeSimulation(text), c = makeSimulation(text, {"scene.seed=9"});
    for (int i = 0; i < 50; ++i) {
        a->runFrame();
        b->runFrame();
        c->runFrame();
    }
    EXPECT_EQ(a->hash(), b->hash());
    EXPECT_NE(a->hash(), c->hash());
    EXPECT_EQ(emitter(*a).pool.count, emitter(*c).pool.count) << "the count does not depend on the draws";
}

TEST(ParticleSystem, VectorisedKernelMatchesAPlainLoopExactly) {
    // on SSE2 and, where the processor has it, AVX2 (1000 of the 1003 through the eight-wide loop)
    ParticlePool p, q;
    reserveParticles(p, 1003);
    Rng rng(11);
    for (std::uint32_t i = 0; i < 1003; ++i) {
        for (std::vector<float>* a : {&p.px, &p.py, &p.pz, &p.vx, &p.vy, &p.vz}) {
            (*a)[i] = float(rng.uniform(-5.0, 5.0));
        }
    }
    // steps left to live, from 2 past to 40 ahead, around a clock about to wrap: a particle dies in this
    // update when it has none left (steps left <= 0)
    std::vector<int> left(1003);
    p.clock = 0xfffffff0u;
    for (std::uint32_t i = 0; i < 1003; ++i) {
        left[i] = int(std::floor(rng.uniform(-2.0, 40.0)));
        p.birthStep[i] = p.clock - std::uint32_t(rng.uniform(0.0, 100.0));
        p.deathStep[i] = p.clock + std::uint32_t(left[i]);
    }
    p.count = 1003;
    q = p;
    const Vec3 g{0.0, -9.81, 0.0};
    const float drag = 0.3f, dt = 0.02f;
    // the plain reference: same arithmetic per particle
    std::vector<std::array<double, 8>> moved;
    std::vector<bool> alive;
    for (std::uint32_t i = 0; i < q.count; ++i) {
        const float keep = std::exp(-drag * dt);
        const float vx = q.vx[i] * keep + float(g.x) * dt;
        const float vy = q.vy[i] * keep + float(g.y) * dt;
        const float vz = q.vz[i] * keep + float(g.z) * dt;
        alive.push_back(left[i] > 0);
        moved.push_back({q.px[i] + vx * dt, q.py[i] + vy * dt, q.pz[i] + vz * dt, vx, vy, vz,
                         double(q.birthStep[i]), double(q.deathStep[i])});
    }
    // and its order: the survivors past the new end fill the holes below it, the k-th hole from the start
    // taking the k-th such survivor
    const auto survivors = static_cast<std::uint32_t>(std::count(alive.begin(), alive.end(), true));
    std::vector<std::uint32_t> fillers;
    for (std::uint32_t i = survivors; i < q.count; ++i) {
        if (alive[i]) {
            fillers.push_back(i);
        }
    }
    std::vector<std::array<double, 8>> expected;
    std::size_t next = 0;
    for (std::uint32_t i = 0; i < survivors; ++i) {
        expected.push_back(alive[i] ? moved[i] : moved[fillers[next++]]);
    }
    ASSERT_EQ(next, fillers.size());
    const Simd before = activeSimd();
    std::vector<Simd> kernels = {Simd::Sse2};
    if (avx2Available()) {
        kernels.push_back(Simd::Avx2);
    }
    for (const Simd simd : kernels) {
        forceSimd(simd);
        p = q;
        const std::uint32_t deaths = advanceParticles(p, g, drag, dt);
        const char* name = simd == Simd::Avx2 ? "avx2" : "sse2";
        ASSERT_EQ(p.count, survivors) << name;
        EXPECT_EQ(deaths, 1003u - p.count) << name;
        EXPECT_GT(deaths, 0u) << name;
        std::vector<std::array<double, 8>> got;
        for (std::uint32_t i = 0; i < p.count; ++i) {
            got.push_back({p.px[i], p.py[i], p.pz[i], p.vx[i], p.vy[i], p.vz[i], double(p.birthStep[i]),
                           double(p.deathStep[i])});
        }
        EXPECT_EQ(got, expected) << name;
        EXPECT_EQ(p.clock, 0xfffffff1u) << "one update done (" << name << ")";
    }
    forceSimd(before);
}

TEST(ParticleSystem, Avx2AndSse2KernelsAndAnyThreadCountGiveTheSameBitsInTheSameOrder) {
    // three chunks and a ragged tail, many deaths: the lists of dead groups and the hole fills they drive
    // must come out the same, particle for particle, whichever kernel and however many threads
    constexpr std::uint32_t n = 40003;
    ParticlePool base;
    reserveParticles(base, n);
    Rng rng(5);
    for (std::uint32_t i = 0; i < n; ++i) {
        for (std::vector<float>* a : {&base.px, &base.py, &base.pz, &base.vx, &base.vy, &base.vz}) {
            (*a)[i] = float(rng.uniform(-5.0, 5.0));
        }
    }
    // around a step count about to wrap, some due already: the death test compares 32-bit differences
    base.clock = 0xfffffff0u;
    for (std::uint32_t i = 0; i < n; ++i) {
        base.birthStep[i] = base.clock - std::uint32_t(rng.uniform(0.0, 1e6));
        base.deathStep[i] = base.clock + std::uint32_t(std::int32_t(std::floor(rng.uniform(-3.0, 30.0))));
    }
    base.count = n;
    const Vec3 g{0.3, -9.81, 0.1};
    const Simd before = activeSimd();
    auto run = [&](Simd simd, int threads) {
        forceSimd(simd);
        WorkerPool pool(threads);
        ParticlePool p = base;
        for (int step = 0; step < 5; ++step) {
            advanceParticles(p, g, 0.4f, 0.05f, pool);
        }
        return p;
    };
    const ParticlePool reference = run(Simd::Sse2, 1);
    ASSERT_LT(reference.count, n - 1000) << "the test wants many deaths";
    std::vector<std::pair<Simd, int>> variants = {{Simd::Sse2, 3}};
    if (avx2Available()) {
        variants.push_back({Simd::Avx2, 1});
        variants.push_back({Simd::Avx2, 2});
    }
    for (const auto& [simd, threads] : variants) {
        const ParticlePool p = run(simd, threads);
        ASSERT_EQ(p.count, reference.count);
        for (auto member : {&ParticlePool::px, &ParticlePool::py, &ParticlePool::pz, &ParticlePool::vx,
                            &ParticlePool::vy, &ParticlePool::vz}) {
            EXPECT_EQ(std::memcmp((p.*member).data(), (reference.*member).data(), p.count * sizeof(float)), 0)
                << (simd == Simd::Avx2 ? "avx2" : "sse2") << " at " << threads << " threads";
        }
        for (auto member : {&ParticlePool::birthStep, &ParticlePool::deathStep}) {
            EXPECT_TRUE(
                std::equal((p.*member).begin(), (p.*member).begin() + p.count, (reference.*member).begin()))
                << (simd == Simd::Avx2 ? "avx2" : "sse2") << " at " << threads << " threads";
        }
    }
    forceSimd(before);
    if (!avx2Available()) {
        GTEST_SKIP() << "no AVX2 here: only SSE2 at several thread counts was compared";
    }
}

TEST(ParticleSystem, BirthsHaveTheSameBitsAtAnyThreadCount) {
    // draws keyed by the birth's number: 5000 births of a sphere emitter (rejection sampling, so a varying
    // number of draws each) in chunks on 1 to 7 threads, and in two calls, give the same particles
    ParticleEmitter base;
    base.def.shape = EmitterShape::Sphere;
    base.def.radius = 0.5;
    base.seed = 77;
    reserveParticles(base.pool, 6000);
    auto born = [&](int threads, bool split) {
        WorkerPool pool(threads);
        ParticleEmitter e = base;
        if (split) {
            spawnParticles(e, 1234, 0.01, pool);
            spawnParticles(e, 5000 - 1234, 0.01, pool);
        } else {
            spawnParticles(e, 5000, 0.01, pool);
        }
        return e;
    };
    const ParticleEmitter reference = born(1, false);
    ASSERT_EQ(reference.pool.count, 5000u);
    EXPECT_EQ(reference.born, 5000u);
    for (const auto& [threads, split] :
         std::vector<std::pair<int, bool>>{{2, false}, {7, false}, {3, true}}) {
        const ParticleEmitter e = born(threads, split);
        ASSERT_EQ(e.pool.count, reference.pool.count);
        for (auto member : {&ParticlePool::px, &ParticlePool::py, &ParticlePool::pz, &ParticlePool::vx,
                            &ParticlePool::vy, &ParticlePool::vz}) {
            EXPECT_EQ(
                std::memcmp((e.pool.*member).data(), (reference.pool.*member).data(), 5000 * sizeof(float)),
                0)
                << threads << " threads" << (split ? ", two calls" : "");
        }
        EXPECT_EQ(e.pool.deathStep, reference.pool.deathStep)
            << threads << " threads" << (split ? ", two calls" : "");
    }
    // and they are different particles: no two births share their draws
    std::vector<float> xs(reference.pool.px.begin(), reference.pool.px.begin() + 5000);
    std::sort(xs.begin(), xs.end());
    EXPECT_EQ(std::adjacent_find(xs.begin(), xs.end()), xs.end());
}

TEST(ParticleSystem, ColourAndSizeOverLife) {
    EmitterDef d;
    d.colorStart = {1.0f, 0.8f, 0.2f, 1.0f};
    d.colorEnd = {0.8f, 0.0f, 0.0f, 0.0f};
    d.size = {0.05f, 0.01f};
    EXPECT_EQ(particleColor(d, 0.0f), d.colorStart);
    EXPECT_EQ(particleColor(d, 1.0f), d.colorEnd);
    EXPECT_NEAR(particleColor(d, 0.5f)[3], 0.5f, 1e-7);
    EXPECT_NEAR(particleSize(d, 0.5f), 0.03f, 1e-7);
}

TEST(ParticleSystem, BurstEventGivesBirthAtItsStep) {
    auto sim =
        makeSimulation(scene("lifetime = [10.0, 10.0]\ncollide = false",
                             "[[event]]\nframe = 5\nentity = \"spout\"\naction = \"burst\"\nvalue = [42]\n"));
    for (int i = 0; i < 5; ++i) {
        sim->runFrame();
        ASSERT_EQ(emitter(*sim).pool.count, 0u);
    }
    sim->runFrame();
    EXPECT_EQ(emitter(*sim).pool.count, 42u);
}

TEST(ParticleSystem, RateCountStaysExactOverAHundredThousandSteps) {
    // 100 a second at dt = 0.01 for 1000 s: exactly one birth a step, every step
    auto sim = makeSimulation(scene("rate = 100.0\nlifetime = [0.5, 0.5]\ncollide = false"));
    for (int i = 1; i <= 100000; ++i) {
        sim->runFrame();
        ASSERT_EQ(emitter(*sim).born, std::uint64_t(i)) << "step " << i;
    }
}

TEST(ParticleSystem, SetRateCarriesTheOwedFraction) {
    // 0.5 a second, the rate set again (to the same value) every 1.5 s: 6 s still give 3 births
    std::string events;
    for (double at : {1.5, 3.0, 4.5}) {
        events += "[[event]]\nat = " + std::to_string(at) +
                  "\nentity = \"spout\"\naction = \"set_rate\"\nvalue = [0.5]\n";
    }
    auto sim = makeSimulation(scene("rate = 0.5\nlifetime = [100.0, 100.0]\ncollide = false", events));
    for (int i = 0; i < 600; ++i) {
        sim->runFrame();
    }
    EXPECT_EQ(emitter(*sim).born, 3u);
}

TEST(ParticleSystem, BounceHeightFollowsRestitution) {
    // dropped from 2 m onto a plane with restitution 0.5: the first rebound tops out near 0.25 x 2 m
    auto sim =
        makeSimulation(scene("burst = 1\nspeed = [0.0, 0.0]\nspread_deg = 0.0\nlifetime = [10.0, 10.0]\n"
                             "restitution = 0.5",
                             "[entity.transform]\nposition = [0, 2, 0]\n[[entity]]\nname = \"floor\"\n"
                             "[entity.rigid_body]\nshape = \"plane\"\n",
                             "0.001"));
    bool bounced = false;
    double top = 0.0;
    for (int i = 0; i < 1500; ++i) {
        sim->runFrame();
        const ParticlePool& p = emitter(*sim).pool;
        bounced = bounced || p.vy[0] > 0.0f;
        if (bounced) {
            top = std::max(top, double(p.py[0]));
        }
    }
    ASSERT_TRUE(bounced);
    EXPECT_NEAR(top, 0.5, 0.02);
}

TEST(ParticleSystem, KernelHandlesEveryTailLength) {
    for (std::uint32_t n : {0u, 1u, 3u, 4u, 5u, 8u, 9u}) {
        for (const bool allDie : {false, true}) {
            ParticlePool p;
            reserveParticles(p, 16);
            for (std::uint32_t i = 0; i < n; ++i) {
                p.deathStep[i] = allDie ? 0u : 500u; // this update, or a later one
                p.py[i] = float(i);
            }
            p.count = n;
            const std::uint32_t deaths = advanceParticles(p, {0.0, -9.81, 0.0}, 0.0f, 0.02f);
            EXPECT_EQ(deaths, allDie ? n : 0u) << n;
            EXPECT_EQ(p.count, allDie ? 0u : n) << n;
        }
    }
}

} // namespace
} // namespace tumble
