// One fixed step of a 256 x 256 height field (the wave equation, reflecting borders, no bodies in it),
// as the water system takes it, after a disturbance has set the whole surface moving.
//   build/tests/bench/tumble_bench --benchmark_filter=Water --benchmark_repetitions=5

#include "engine/parallel.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/water_system.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

namespace tumble {
namespace {

void BM_Water256Step(benchmark::State& state) {
    const Catalog& catalog = bench::builtinCatalog();
    const std::string text = R"([scene]
name = "w"
[[entity]]
name = "pond"
[entity.water]
cells = [256, 256]
size = [25.6, 25.6]
wave_speed = 2.0
damping = 0.01
[[event]]
frame = 0
entity = "pond"
action = "disturb"
position = [0, 0, 0]
radius = 2.0
amount = 0.1
)";
    Simulation sim(catalog, "bench.toml", text, {});
    for (int i = 0; i < 60; ++i) {
        sim.runFrame();
    }
    WorkerPool pool(int(state.range(0)));
    StepContext ctx;
    ctx.dt = sim.scene().dt;
    ctx.pool = &pool;
    for (auto _ : state) {
        stepWater(sim.world(), ctx);
    }
    state.counters["nodes"] = 256.0 * 256.0;
}
// the argument is the thread count
BENCHMARK(BM_Water256Step)->Unit(benchmark::kMillisecond)->Arg(1)->Arg(2);

} // namespace
} // namespace tumble
