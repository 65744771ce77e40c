// Cloth benchmarks: one step of a hanging cloth, implicit (35 x 35 = the curtain, and 100 x 100) and
// symplectic (35 x 35). The cloth is built by the same builder as the scenarios, pinned along its top row,
// and brought into motion first (100 steps in gusty wind) so the solver sees a real, moving state.
//   build/tests/bench/tumble_bench --benchmark_filter=Cloth --benchmark_repetitions=5

#include "components/force_field.h"
#include "systems/spring_builders.h"
#include "systems/spring_integrators.h"

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <vector>

namespace tumble {
namespace {

struct ClothScene {
    SpringNetwork net;
    SpringWorkspace work;
    std::vector<ForceField> fields;
    Environment env;
};

ClothScene makeCloth(int n, Integrator integrator) {
    ClothDef def;
    def.rows = def.cols = n;
    def.size = {2.0, 2.0};
    def.mass = 1.0;
    def.stretch = 5000.0;
    def.shear = 500.0;
    def.bend = 50.0;
    def.damping = 0.02;
    clothPinPreset("top-row", n, n, def.pins);
    ClothScene s{buildCloth(def), {}, {}, {}};
    s.net.integrator = integrator;
    s.net.drag = 0.01;
    s.net.cgTolerance = 1e-3;
    ForceField wind;
    wind.kind = FieldKind::Wind;
    wind.strength = wind.current = {0.0, 0.0, 3.0};
    wind.coefficient = 0.5;
    if (std::getenv("NO_WIND") == nullptr) s.fields.push_back(wind);
    s.env = {{0.0, -9.81, 0.0}, &s.fields};
    return s;
}

void runCloth(benchmark::State& state, int n, Integrator integrator) {
    ClothScene s = makeCloth(n, integrator);
    // symplectic Euler needs about 47 substeps per frame to stay stable on this cloth (BASELINES.md)
    const double h = integrator == Integrator::SymplecticEuler ? 1.0 / 60.0 / 47.0 : 1.0 / 60.0;
    for (int i = 0; i < 100; ++i) {
        stepNetwork(s.net, s.work, s.env, h);
    }
    double iterations = 0.0;
    for (auto _ : state) {
        stepNetwork(s.net, s.work, s.env, h);
        iterations += s.work.lastSolve.iterations;
    }
    state.counters["cg_iterations"] = iterations / static_cast<double>(state.iterations());
    state.counters["triangles"] = static_cast<double>(s.net.triangles.size());
}

void BM_ClothImplicit35(benchmark::State& state) {
    runCloth(state, 35, Integrator::ImplicitEuler);
}
BENCHMARK(BM_ClothImplicit35)->Unit(benchmark::kMillisecond);

void BM_ClothImplicit100(benchmark::State& state) {
    runCloth(state, 100, Integrator::ImplicitEuler);
}
BENCHMARK(BM_ClothImplicit100)->Unit(benchmark::kMillisecond);

void BM_ClothSymplectic35(benchmark::State& state) {
    runCloth(state, 35, Integrator::SymplecticEuler);
}
BENCHMARK(BM_ClothSymplectic35)->Unit(benchmark::kMillisecond);

} // namespace
} // namespace tumble
