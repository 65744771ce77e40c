// A million live particles: one step of births, ageing, deaths, gravity and drag on the `million` demo
// (demos/million.toml) at its steady state, with the vectorised update and, for the ratio, a plain scalar
// loop over the same arrays (the same births, deaths by swap-remove as they are met).
// Then the state hash of that world as a recording takes it every frame (engine/replay.h frameHashes),
// against the hash it replaced (replay format 5's multiply-rotate mix, kept here as the baseline) over the
// same bytes.
//   build/tests/bench/tumble_bench --benchmark_filter=Million --benchmark_repetitions=5

#include "components/particles.h"
#include "engine/parallel.h"
#include "engine/replay.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/particle_system.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstring>
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

/// The plain way: one scalar loop that kills by swap-remove when it meets a death, and moves.
void advancePlain(ParticlePool& p, const Vec3& g, float drag, float dt) {
    const float keep = std::exp(-drag * dt);
    for (std::uint32_t i = 0; i < p.count;) {
        if (std::int32_t(p.deathStep[i] - p.clock) <= 0) {
            const std::uint32_t last = --p.count;
            p.px[i] = p.px[last];
            p.py[i] = p.py[last];
            p.pz[i] = p.pz[last];
            p.vx[i] = p.vx[last];
            p.vy[i] = p.vy[last];
            p.vz[i] = p.vz[last];
            p.birthStep[i] = p.birthStep[last];
            p.deathStep[i] = p.deathStep[last];
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
    ++p.clock;
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

void BM_MillionParticlesStateHash(benchmark::State& state) {
    MillionScene s = steadyMillion();
    s.sim->setThreads(int(state.range(0)));
    std::vector<EntityHash> entities;
    for (auto _ : state) {
        benchmark::DoNotOptimize(frameHashes(s.sim->world(), s.sim->catalog(), entities, s.sim->pool()));
    }
    state.counters["live"] = static_cast<double>(s.emitter->pool.count);
}
// the argument is the thread count
BENCHMARK(BM_MillionParticlesStateHash)->Unit(benchmark::kMillisecond)->Iterations(200)->Arg(1)->Arg(2);

/// The state hash of replay format 5 (before XXH3): 8 bytes at a time, a multiply-rotate mix per word.
std::uint64_t formatFiveHash(const ParticlePool& p) {
    std::uint64_t h = 0x6a09e667f3bcc908ull;
    const auto word = [&h](std::uint64_t w) {
        h ^= w * 0x9e3779b97f4a7c15ull;
        h = ((h << 31) | (h >> 33)) * 0xff51afd7ed558ccdull;
    };
    // the same bytes as the state hash of today's pool (its ages are step numbers, no longer floats)
    for (const void* data :
         {static_cast<const void*>(p.px.data()), static_cast<const void*>(p.py.data()),
          static_cast<const void*>(p.pz.data()), static_cast<const void*>(p.vx.data()),
          static_cast<const void*>(p.vy.data()), static_cast<const void*>(p.vz.data()),
          static_cast<const void*>(p.birthStep.data()), static_cast<const void*>(p.deathStep.data())}) {
        const auto* bytes = static_cast<const unsigned char*>(data);
        for (std::size_t at = 0; at + 8 <= std::size_t(p.count) * sizeof(float); at += 8) {
            std::uint64_t w;
            std::memcpy(&w, bytes + at, 8);
            word(w);
        }
    }
    return h;
}

void BM_MillionParticlesStateHashFormat5(benchmark::State& state) {
    MillionScene s = steadyMillion();
    for (auto _ : state) {
        benchmark::DoNotOptimize(formatFiveHash(s.emitter->pool));
    }
}
BENCHMARK(BM_MillionParticlesStateHashFormat5)->Unit(benchmark::kMillisecond)->Iterations(200);

} // namespace
} // namespace tumble
