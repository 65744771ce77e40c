// Air on a grid (systems/air_solver.h): one step of a 64^3 grid (4 m across) with a chimney's hot,
// smoky plume rising through it, every force on, after 30 steps of it; and the heap it holds per cell.
//   build/tests/bench/tumble_bench --benchmark_filter=Air --benchmark_repetitions=5

#include "engine/parallel.h"
#include "systems/air_solver.h"
#include "systems/air_system.h"

#include <benchmark/benchmark.h>

#include <malloc.h>

namespace tumble {
namespace {

// the argument is the thread count
void BM_Air64Step(benchmark::State& state) {
    const std::size_t before = mallinfo2().uordblks;
    Air air;
    air.cells = {64, 64, 64};
    air.cell = 4.0 / 64.0;
    air.border[3] = AirBorder::Open;
    air.vorticity = 0.3;
    air.smokeWeight = 0.1;
    air.heatLift = 1.0;
    initAir(air);
    WorkerPool pool(int(state.range(0)));
    AirSource chimney;
    chimney.radius = 0.2;
    chimney.smoke = 1.0;
    chimney.heat = 5.0;
    chimney.drives = true;
    chimney.velocity = {0.2, 1.0, 0.0};
    const Vec3 at{0.0, -1.6, 0.0};
    const double dt = 1.0 / 60.0;
    for (int s = 0; s < 30; ++s) {
        feedAir(air, chimney, at, dt);
        stepAir(air, {0.0, -9.81, 0.0}, dt, pool);
    }
    const std::size_t after = mallinfo2().uordblks;
    double iterations = 0.0;
    for (auto _ : state) {
        feedAir(air, chimney, at, dt);
        stepAir(air, {0.0, -9.81, 0.0}, dt, pool);
        iterations += air.lastIterations;
    }
    state.counters["cells"] = double(air.cellCount());
    state.counters["bytes_per_cell"] = double(after - before) / double(air.cellCount());
    state.counters["cg_iterations"] = iterations / double(state.iterations());
}
BENCHMARK(BM_Air64Step)->Unit(benchmark::kMillisecond)->Arg(1)->Arg(2);

} // namespace
} // namespace tumble
