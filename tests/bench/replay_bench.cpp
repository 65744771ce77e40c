// What recording a replay costs a run of the curtain demo (no rendering): one frame plain, and one frame
// with what `run --record` adds (the per-entity state hashes, the applied events, the frame appended to the
// replay and a chunk flushed every kFramesPerChunk frames). Each benchmark runs the first 240 frames of a
// fresh simulation.
//   build/tests/bench/tumble_bench --benchmark_filter=CurtainRun --benchmark_repetitions=9

#include "engine/replay.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>

namespace tumble {
namespace {

constexpr int kFrames = 240;

std::unique_ptr<Simulation> curtain() {
    const Catalog& catalog = bench::builtinCatalog();
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    return std::make_unique<Simulation>(catalog, path, readScenarioFile(path), std::vector<std::string>{});
}

void BM_CurtainRun(benchmark::State& state) {
    auto sim = curtain();
    for (auto _ : state) {
        sim->runFrame();
        benchmark::DoNotOptimize(sim->takeAppliedEvents());
    }
}
BENCHMARK(BM_CurtainRun)->Unit(benchmark::kMillisecond)->Iterations(kFrames);

void BM_CurtainRunRecorded(benchmark::State& state) {
    auto sim = curtain();
    const std::string path = (std::filesystem::temp_directory_path() / "tumble_bench_record.tumble").string();
    ReplayWriter writer(path, ReplayHeader{kReplayVersion, buildId(), "curtain.toml", "", {}});
    std::vector<EntityHash> entities;
    for (auto _ : state) {
        sim->runFrame();
        FrameRecord rec{sim->takeAppliedEvents(), frameHashes(sim->world(), sim->catalog(), entities), entities};
        writer.frame(rec);
    }
    writer.finish();
    std::filesystem::remove(path);
}
BENCHMARK(BM_CurtainRunRecorded)->Unit(benchmark::kMillisecond)->Iterations(kFrames);

void BM_CurtainFrameHashes(benchmark::State& state) {
    auto sim = curtain();
    for (int i = 0; i < 60; ++i) {
        sim->runFrame();
    }
    std::vector<EntityHash> entities;
    for (auto _ : state) {
        benchmark::DoNotOptimize(frameHashes(sim->world(), sim->catalog(), entities));
    }
}
BENCHMARK(BM_CurtainFrameHashes)->Unit(benchmark::kMicrosecond);

} // namespace
} // namespace tumble
