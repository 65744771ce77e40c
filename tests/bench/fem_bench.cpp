// Finite-element bodies (systems/fem.h): one implicit step of a 10,368-tetrahedron box (12 x 12 x 12
// cells), lying on nothing and falling freely after a few steps of settling its solver, and the heap it
// holds per tetrahedron once it has stepped (the body, its solver's matrix, multigrid and work vectors).
//   build/tests/bench/tumble_bench --benchmark_filter=Fem --benchmark_repetitions=5

#include "engine/parallel.h"
#include "systems/fem.h"
#include "systems/spring_integrators.h"

#include <benchmark/benchmark.h>

#include <malloc.h>

namespace tumble {
namespace {

SpringNetwork femBox() {
    FemMaterial m;
    m.young = 1e5;
    m.poisson = 0.3;
    m.density = 1000.0;
    m.stiffnessDamping = 0.01;
    return buildFem(boxTets({0.0, 0.0, 0.0}, {1.0, 1.0, 1.0}, {12, 12, 12}), m, {});
}

// the argument is the thread count
void BM_Fem10kImplicit(benchmark::State& state) {
    const std::size_t before = mallinfo2().uordblks;
    SpringNetwork net = femBox();
    SpringWorkspace work;
    WorkerPool pool(int(state.range(0)));
    Environment env{{0.0, -9.81, 0.0}};
    env.pool = &pool;
    // a spin, so that every element turns and is strained (not the identity rotation of a body at rest)
    for (std::size_t i = 0; i < net.v.size(); ++i) {
        net.v[i] = cross(Vec3{0.0, 2.0, 1.0}, net.x[i]) + Vec3{0.1 * net.x[i].y, 0.0, 0.0};
    }
    for (int i = 0; i < 5; ++i) {
        stepNetwork(net, work, env, 1.0 / 60.0);
    }
    const std::size_t after = mallinfo2().uordblks;
    double iterations = 0.0;
    for (auto _ : state) {
        stepNetwork(net, work, env, 1.0 / 60.0);
        iterations += work.lastSolve.iterations;
    }
    state.counters["tetrahedra"] = double(net.fem.tets.size());
    state.counters["bytes_per_tet"] = double(after - before) / double(net.fem.tets.size());
    state.counters["cg_iterations"] = iterations / double(state.iterations());
}
BENCHMARK(BM_Fem10kImplicit)->Unit(benchmark::kMillisecond)->Arg(1)->Arg(2);

} // namespace
} // namespace tumble
