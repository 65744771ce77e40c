// Engine benchmarks: what the profiler costs per timed scope and per frame, views, the state hash, the pool's
// fork-joins and reading a scenario file.
//   build/tests/bench/tumble_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

#include "engine/hash.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/scenario.h"
#include "engine/schedule.h"
#include "engine/world.h"

#include <benchmark/benchmark.h>

#include <array>
#include <chrono>
#include <optional>
#include <string>
#include <vector>

namespace tumble {
namespace {

constexpr int kSystems = 12; // about what a full scene registers

// one timed scope: two clock reads and the bookkeeping
void BM_ProfilerScope(benchmark::State& state) {
    Profiler p;
    const int slot = p.addSlot("x", Phase::Fixed, false);
    for (auto _ : state) {
        TUMBLE_PROFILE_SCOPE(p, slot);
        benchmark::ClobberMemory();
    }
}
BENCHMARK(BM_ProfilerScope);

// a frame of empty systems through the profiled schedule (input, fixed, frame phases)...
void BM_ProfiledFrame(benchmark::State& state) {
    Profiler p;
    Schedule s(p);
    int counter = 0;
    for (int i = 0; i < kSystems; ++i) {
        s.add(
            i < 2    ? Phase::Input
            : i < 10 ? Phase::Fixed
                     : Phase::Frame,
            "s" + std::to_string(i),
            [&counter](World&, const StepContext&) { benchmark::DoNotOptimize(++counter); },
            Access::everything());
    }
    World w;
    StepContext ctx;
    std::uint64_t frame = 0;
    for (auto _ : state) {
        p.beginFrame(frame++);
        s.run(Phase::Input, w, ctx);
        s.run(Phase::Fixed, w, ctx);
        s.run(Phase::Frame, w, ctx);
        p.endFrame();
    }
}
BENCHMARK(BM_ProfiledFrame);

// ...and the same systems called without any profiling, for the ratio
void BM_UnprofiledFrame(benchmark::State& state) {
    std::vector<SystemFn> fns;
    int counter = 0;
    for (int i = 0; i < kSystems; ++i) {
        fns.emplace_back([&counter](World&, const StepContext&) { benchmark::DoNotOptimize(++counter); });
    }
    World w;
    StepContext ctx;
    for (auto _ : state) {
        for (auto& f : fns) {
            f(w, ctx);
        }
        w.commands().flush();
    }
}
BENCHMARK(BM_UnprofiledFrame);

struct Pos {
    double x, y, z;
};
struct Vel {
    double x, y, z;
};

// a view joining two component types over 100k entities, half of which have both
void BM_ViewTwoComponents(benchmark::State& state) {
    World w;
    for (int i = 0; i < 100000; ++i) {
        const Entity e = w.create();
        w.emplace<Pos>(e, Pos{0, 0, 0});
        if (i % 2 == 0) {
            w.emplace<Vel>(e, Vel{1, 2, 3});
        }
    }
    for (auto _ : state) {
        w.view<Pos, const Vel>().each([](Entity, Pos& p, const Vel& v) {
            p.x += v.x * 0.01;
            p.y += v.y * 0.01;
            p.z += v.z * 0.01;
        });
        benchmark::ClobberMemory();
    }
    state.SetItemsProcessed(state.iterations() * 50000);
}
BENCHMARK(BM_ViewTwoComponents);

// the state hash over 24 MB (a million particles' positions)
void BM_StateHash(benchmark::State& state) {
    std::vector<double> data(3'000'000, 1.25);
    for (auto _ : state) {
        Hasher h;
        h.add(data);
        benchmark::DoNotOptimize(h.digest());
    }
    state.SetBytesProcessed(state.iterations() * std::int64_t(data.size() * sizeof(double)));
}
BENCHMARK(BM_StateHash);

// reading a demo's scenario file (a sweep of short runs reads one per run)
void BM_ReadScenarioFile(benchmark::State& state) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    for (auto _ : state) {
        benchmark::DoNotOptimize(readScenarioFile(path));
    }
}
BENCHMARK(BM_ReadScenarioFile)->Unit(benchmark::kMicrosecond);

// one fork-join of the worker pool over four chunks of a little work (about what a CG product of a
// 100 x 100 cloth hands out), against the same chunks on one thread: what sharing a loop costs
void BM_PoolForkJoin(benchmark::State& state) {
    WorkerPool pool(int(state.range(0)));
    std::vector<double> x(1 << 14, 1.0);
    for (auto _ : state) {
        pool.forChunks(x.size(), x.size() / 4, [&](std::size_t, std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                x[i] = x[i] * 1.0000001 + 1e-9;
            }
        });
        benchmark::ClobberMemory();
    }
}
BENCHMARK(BM_PoolForkJoin)->Arg(1)->Arg(2);

// what a fork-join itself costs: four chunks of almost nothing (the CG step of a small cloth makes
// about a hundred of these)
void BM_PoolForkJoinEmpty(benchmark::State& state) {
    WorkerPool pool(int(state.range(0)));
    std::array<double, 64> x{};
    for (auto _ : state) {
        pool.forChunks(4, 1, [&](std::size_t c, std::size_t, std::size_t) { x[8 * c] += 1.0; });
        benchmark::ClobberMemory();
    }
}
BENCHMARK(BM_PoolForkJoinEmpty)->Arg(1)->Arg(2);

// one fork-join (four chunks of almost nothing) after the calling thread has worked alone for 1 ms (not
// timed; a fixed count of iterations, as the timed part is microseconds), by
// which time idle workers have gone to sleep: with them asleep (0), and kept awake meanwhile (1,
// WorkerPool::Awake, as a thread-count trial's runs on one thread do): what waking them costs the loop
void BM_PoolForkJoinAfterWorkAlone(benchmark::State& state) {
    WorkerPool pool(2);
    std::array<double, 64> x{};
    for (auto _ : state) {
        state.PauseTiming();
        {
            std::optional<WorkerPool::Awake> awake;
            if (state.range(0) != 0) {
                awake.emplace(pool);
            }
            const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(1);
            while (std::chrono::steady_clock::now() < until) {
            }
        }
        state.ResumeTiming();
        pool.forChunks(4, 1, [&](std::size_t c, std::size_t, std::size_t) { x[8 * c] += 1.0; });
        benchmark::ClobberMemory();
    }
}
BENCHMARK(BM_PoolForkJoinAfterWorkAlone)->Arg(0)->Arg(1)->Iterations(1000)->Unit(benchmark::kMicrosecond);

// a loop cut as the implicit solver cuts a 100 x 100 cloth's vector updates (10,201 rows of 16 bytes, in
// chunks of 128 rows: 80 chunks), a little work a row: what claiming many small chunks costs
void BM_PoolForkJoinManyChunks(benchmark::State& state) {
    WorkerPool pool(int(state.range(0)));
    std::vector<float> x(4 * 10201, 1.0f);
    for (auto _ : state) {
        pool.forChunks(10201, 128, [&](std::size_t, std::size_t b, std::size_t e) {
            for (std::size_t i = 4 * b; i < 4 * e; ++i) {
                x[i] = x[i] * 1.0000001f + 1e-9f;
            }
        });
        benchmark::ClobberMemory();
    }
}
BENCHMARK(BM_PoolForkJoinManyChunks)->Arg(1)->Arg(2);

} // namespace
} // namespace tumble
