// A million live particles: one step of births, ageing, deaths, gravity and drag on the `million` demo
// (demos/million.toml) at its steady state, with the vectorised update and, for the ratio, a plain scalar
// loop over the same arrays (the same births, deaths by swap-remove as they are met).
//   build/tests/bench/tumble_bench --benchmark_filter=Million --benchmark_repetitions=5

#include "components/particles.h"
#include "engine/parallel.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/particle_system.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <string>

namespace tumble {
namespace {

struct MillionScene {
    std::unique_ptr<Simulation> sim;
    ParticleEmitter* emitter = nullptr;
};

MillionScene steadyMillion() {
    const Catalog& catalog = bench::builtinCatalog();
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/million.toml";
    MillionScene s{
        std::make_unique<Simulation>(catalog, path, readScenarioFile(path), std::vector<std::string>{}),
        nullptr};
    for (int i = 0; i < 200; ++i) { // past 3 s: the first particles have died, the count holds at a million
        s.sim->runFrame();
    }
    s.sim->world().view<ParticleEmitter>().each([&](Entity, ParticleEmitter& e) { s.emitter = &e; });
    return s;
}

/// The plain way: one scalar loop that ages, kills by swap-remove when it meets a death, and moves.
void advancePlain(ParticlePool& p, const Vec3& g, float drag, float dt) {
    const float keep = std::exp(-drag * dt);
    for (std::uint32_t i = 0; i < p.count;) {
        p.age[i] += dt;
        if (p.age[i] >= p.lifetime[i]) {
            const std::uint32_t last = --p.count;
            p.px[i] = p.px[last];
            p.py[i] = p.py[last];
            p.pz[i] = p.pz[last];
            p.vx[i] = p.vx[last];
            p.vy[i] = p.vy[last];
            p.vz[i] = p.vz[last];
            p.age[i] = p.age[last];
            p.lifetime[i] = p.lifetime[last];
            continue;
        }
        p.vx[i] = p.vx[i] * keep + float(g.x) * dt;
        p.vy[i] = p.vy[i] * keep + float(g.y) * dt;
        p.vz[i] = p.vz[i] * keep + float(g.z) * dt;
        p.px[i] += p.vx[i] * dt;
        p.py[i] += p.vy[i] * dt;
        p.pz[i] += p.vz[i] * dt;
        ++i;
    }
}

void runMillion(benchmark::State& state, bool plain, int threads = 1) {
    MillionScene s = steadyMillion();
    WorkerPool pool(threads);
    StepContext ctx;
    ctx.dt = s.sim->scene().dt;
    ctx.pool = &pool; // births share out too
    const Vec3 g{0.0, -9.81, 0.0};
    const auto drag = static_cast<float>(s.emitter->def.drag);
    for (auto _ : state) {
        // births (the emitter system), then ageing, deaths and motion
        emitParticles(s.sim->world(), ctx);
        if (plain) {
            advancePlain(s.emitter->pool, g, drag, static_cast<float>(ctx.dt));
        } else {
            advanceParticles(s.emitter->pool, g, drag, static_cast<float>(ctx.dt), pool);
        }
        benchmark::ClobberMemory();
    }
    state.counters["live"] = static_cast<double>(s.emitter->pool.count);
}

// the argument is the thread count
void BM_MillionParticles(benchmark::State& state) {
    runMillion(state, false, int(state.range(0)));
}
BENCHMARK(BM_MillionParticles)->Unit(benchmark::kMillisecond)->Iterations(300)->Arg(1)->Arg(2);

void BM_MillionParticlesPlainLoop(benchmark::State& state) {
    runMillion(state, true);
}
BENCHMARK(BM_MillionParticlesPlainLoop)->Unit(benchmark::kMillisecond)->Iterations(300);

} // namespace
} // namespace tumble
