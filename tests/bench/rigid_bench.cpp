// The rigid-body bridges against the raw engines on the same scenes, in one binary:
//   a stack of 1000 1 m boxes (10 x 10 x 10) on a plane, Bullet, 1/60 s steps (BASELINES.md: ~4.4 ms raw);
//   a Box2D pyramid of base 40 (820 boxes, rows touching and offset by half a box), 8/3 iterations
//   (BASELINES.md: ~2.5 ms raw).
// Each benchmark times the first 120 steps of a fresh scene, one step per iteration; the bridge's run is a
// whole Tumble fixed step (every system, the bridges' copies in and out, the profiler). The scenes are
// tests/raw_engines.h's; that the bridges give the raw engines' bits is a test (rigid_body_test.cpp), and
// checked here again after the timed steps.
//   build/tests/bench/tumble_bench --benchmark_filter=Stack\|Pyramid --benchmark_repetitions=5

#include "tests/bench/bench_support.h"
#include "tests/raw_engines.h"

#include <benchmark/benchmark.h>

#include <memory>
#include <string>
#include <vector>

namespace tumble {
namespace {

constexpr int kSteps = 120;

std::unique_ptr<Simulation> load(const std::string& text) {
    return std::make_unique<Simulation>(bench::builtinCatalog(), "bench.toml", text,
                                        std::vector<std::string>{});
}

// ---- the Bullet stack: 10 x 10 columns of 10

void BM_BulletStackRaw(benchmark::State& state) {
    raw::BulletStack stack(10, 10);
    for (auto _ : state) {
        stack.step();
    }
}
BENCHMARK(BM_BulletStackRaw)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

void BM_BulletStackBridge(benchmark::State& state) {
    auto sim = load(raw::stackScene(10, 10, false));
    for (auto _ : state) {
        sim->runFrame();
    }
    raw::BulletStack stack(10, 10);
    for (int i = 0; i < kSteps; ++i) {
        stack.step();
    }
    if (raw::bulletState(*sim) != stack.state()) {
        state.SkipWithError("the bridge did not give raw Bullet's bits");
    }
}
BENCHMARK(BM_BulletStackBridge)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

// ---- the Box2D pyramid of base 40

constexpr int kBase = 40;

void BM_Box2DPyramidRaw(benchmark::State& state) {
    raw::Box2DPyramid pyramid(kBase);
    for (auto _ : state) {
        pyramid.step();
    }
}
BENCHMARK(BM_Box2DPyramidRaw)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

void BM_Box2DPyramidBridge(benchmark::State& state) {
    auto sim = load(raw::pyramidScene(kBase));
    for (auto _ : state) {
        sim->runFrame();
    }
    raw::Box2DPyramid pyramid(kBase);
    for (int i = 0; i < kSteps; ++i) {
        pyramid.step();
    }
    if (raw::box2dState(*sim) != pyramid.state()) {
        state.SkipWithError("the bridge did not give raw Box2D's bits");
    }
}
BENCHMARK(BM_Box2DPyramidBridge)->Unit(benchmark::kMillisecond)->Iterations(kSteps);

} // namespace
} // namespace tumble
