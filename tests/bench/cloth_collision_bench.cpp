// Cloth self-collision: one step of the curtain demo (35 x 35, implicit Euler, gusty wind) with
// self-collision on, timed as a whole fixed step of the springs and the cloth collision system, after 120
// frames of billowing; the same step with it off, for the ratio; and refitting the hierarchy of a 100 x 100
// cloth (19,602 triangles) after a step.
//   build/tests/bench/tumble_bench --benchmark_filter=SelfCollision\|Refit --benchmark_repetitions=5

#include "components/spring_network.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/cloth_collision.h"
#include "systems/spring_system.h"
#include "tests/bench/bench_support.h"

#include <benchmark/benchmark.h>

#include <memory>

namespace tumble {
namespace {

const Catalog& catalog() {
    return bench::builtinCatalog();
}

std::unique_ptr<Simulation> curtain(std::vector<std::string> overrides) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    auto sim = std::make_unique<Simulation>(catalog(), path, readScenarioFile(path), overrides);
    for (int i = 0; i < 120; ++i) {
        sim->runFrame();
    }
    return sim;
}

void stepSpringsAndCloth(benchmark::State& state, bool selfCollision) {
    auto sim = curtain(selfCollision ? std::vector<std::string>{"curtain.cloth.self_collision=true"}
                                     : std::vector<std::string>{});
    StepContext ctx;
    ctx.dt = sim->scene().dt;
    ctx.seed = sim->scene().seed;
    ctx.step = sim->step();
    for (auto _ : state) {
        integrateSprings(sim->world(), ctx);
        collideCloth(sim->world(), ctx);
        ++ctx.step;
    }
}

void BM_CurtainImplicit35SelfCollision(benchmark::State& state) {
    stepSpringsAndCloth(state, true);
}
BENCHMARK(BM_CurtainImplicit35SelfCollision)->Unit(benchmark::kMillisecond)->Iterations(300);

void BM_CurtainImplicit35NoSelfCollision(benchmark::State& state) {
    stepSpringsAndCloth(state, false);
}
BENCHMARK(BM_CurtainImplicit35NoSelfCollision)->Unit(benchmark::kMillisecond)->Iterations(300);

void BM_RefitCloth100(benchmark::State& state) {
    auto sim =
        curtain({"curtain.cloth.rows=100", "curtain.cloth.cols=100", "curtain.cloth.self_collision=true"});
    const SpringNetwork* net = nullptr;
    sim->world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& n) { net = &n; });
    std::vector<Aabb> boxes(net->triangles.size());
    Bvh tree;
    for (std::size_t t = 0; t < boxes.size(); ++t) {
        boxes[t] = triangleBox(net->triangles[t], net->x, {}, net->thickness);
    }
    tree.build(boxes);
    for (auto _ : state) {
        // the boxes as the system makes them each step, then the refit
        for (std::size_t t = 0; t < boxes.size(); ++t) {
            boxes[t] = triangleBox(net->triangles[t], net->x, {}, net->thickness);
        }
        benchmark::DoNotOptimize(tree.refit(boxes));
    }
    state.counters["triangles"] = double(boxes.size());
}
BENCHMARK(BM_RefitCloth100)->Unit(benchmark::kMillisecond);

} // namespace
} // namespace tumble
