// What recording a replay costs a run of the curtain demo (no rendering): one frame plain, and one frame
// with what `run --record` adds (the per-entity state hashes, the applied events, the frame appended to the
// replay and a chunk flushed every kFramesPerChunk frames). Each benchmark runs the first 240 frames of a
// fresh simulation. BM_CurtainRunHeld: the same frames with a vertex held and dragged by the mouse spring.
//   build/tests/bench/tumble_bench --benchmark_filter=CurtainRun --benchmark_repetitions=9

#include "engine/replay.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

#include <cmath>
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
        FrameRecord rec{sim->takeAppliedEvents(), frameHashes(sim->world(), sim->catalog(), entities),
                        entities};
        writer.frame(rec);
    }
    writer.finish();
    std::filesystem::remove(path);
}
BENCHMARK(BM_CurtainRunRecorded)->Unit(benchmark::kMillisecond)->Iterations(kFrames);

/// The curtain held by a vertex of its lower edge that the mouse drags round a circle (what `tumble view`
/// does): the counter is the mouse spring's own time per step, from the profiler.
void BM_CurtainRunHeld(benchmark::State& state) {
    auto sim = curtain();
    const std::uint32_t vertex = 34 * 35 + 17;
    auto input = [&](const char* action, double angle) {
        EventDef ev;
        ev.step = sim->step();
        ev.entity = "curtain";
        ev.action = action;
        if (std::string(action) == "grab") {
            ev.value = {double(vertex)};
        }
        ev.position = {0.3 * std::cos(angle), 0.3 + 0.3 * std::sin(angle), 0.5};
        if (auto problem = resolveEvent(sim->catalog(), sim->world(), ev, {})) {
            state.SkipWithError(problem->c_str());
        }
        sim->addEvents({ev});
    };
    input("grab", 0.0);
    double angle = 0.0;
    for (auto _ : state) {
        angle += 0.05;
        input("drag", angle);
        sim->runFrame();
        benchmark::DoNotOptimize(sim->takeAppliedEvents());
    }
    for (const SlotStats& s : sim->profiler().slotStats()) {
        if (s.name == "mouse_spring") {
            state.counters["mouse_spring_us"] = s.meanMs * 1000.0;
        }
    }
}
BENCHMARK(BM_CurtainRunHeld)->Unit(benchmark::kMillisecond)->Iterations(kFrames);

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
