// Cloth benchmarks on the curtain demo itself (demos/curtain.toml: 35 x 35, 2312 triangles, top row
// pinned, gusty wind, implicit Euler at dt = 1/60): one step of the spring system, timed after 120
// frames of billowing so the solver sees the state a user sees. The 100 x 100 and symplectic variants
// are the same scene with overrides.
//   build/tests/bench/tumble_bench --benchmark_filter=Curtain --benchmark_repetitions=5

#include "engine/parallel.h"
#include "engine/simulation.h"
#include "systems/builtin.h"
#include "systems/spring_forces.h"
#include "systems/spring_integrators.h"
#include "systems/spring_system.h"
#include "tests/bench/bench_support.h"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/Sparse>
#include <benchmark/benchmark.h>

#include <memory>
#include <string>
#include <vector>

namespace tumble {
namespace {

const Catalog& catalog() {
    return bench::builtinCatalog();
}

void curtainStep(benchmark::State& state, std::vector<std::string> overrides, int warmFrames,
                 bool withWind = true, int threads = 1) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    std::string text = readScenarioFile(path);
    if (!withWind) {
        // the wind is the last entity of the file
        text = text.substr(0, text.rfind("[[entity]]", text.find("name = \"wind\"")));
    }
    Simulation sim(catalog(), path, text, overrides);
    for (int i = 0; i < warmFrames; ++i) {
        sim.runFrame();
    }
    // time the spring system alone, one fixed step at a time, at the scene's dt
    WorkerPool pool(threads);
    StepContext ctx;
    ctx.dt = sim.scene().dt;
    ctx.seed = sim.scene().seed;
    ctx.pool = &pool;
    double iterations = 0.0;
    for (auto _ : state) {
        integrateSprings(sim.world(), ctx);
        ctx.time += ctx.dt;
        ++ctx.step;
        state.PauseTiming();
        sim.world().view<SpringWorkspace>().each(
            [&](Entity, SpringWorkspace& w) { iterations += w.lastSolve.iterations; });
        state.ResumeTiming();
    }
    state.counters["cg_iterations"] = iterations / static_cast<double>(state.iterations());
}

// the argument is the thread count (the ratio of /2 to /1 is what a second core buys)
void BM_CurtainImplicit35(benchmark::State& state) {
    curtainStep(state, {}, 120, true, int(state.range(0)));
}
BENCHMARK(BM_CurtainImplicit35)->Unit(benchmark::kMillisecond)->Iterations(300)->Arg(1)->Arg(2);

void BM_CurtainImplicit100(benchmark::State& state) {
    curtainStep(state, {"curtain.cloth.rows=100", "curtain.cloth.cols=100"}, 120, true, int(state.range(0)));
}
BENCHMARK(BM_CurtainImplicit100)->Unit(benchmark::kMillisecond)->Iterations(30)->Arg(1)->Arg(2);

// the 100 x 100 step's linear solve alone (the multigrid's update and the conjugate gradients), from zero,
// on four systems the step met (after 120, 135, 150 and 165 frames), one after the other: the solver's
// cost without the differences of the path a scene takes. A solver that gives other bits leads the step
// benchmarks to other states after their 120 frames, and so to other iteration counts, which hide a few
// percent either way (README, "Threads"); here every build solves the same systems.
void BM_SolveCurtain100(benchmark::State& state) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    Simulation sim(catalog(), path, readScenarioFile(path),
                   {"curtain.cloth.rows=100", "curtain.cloth.cols=100"});
    WorkerPool pool(int(state.range(0)));
    StepContext ctx;
    ctx.dt = sim.scene().dt;
    ctx.seed = sim.scene().seed;
    ctx.pool = &pool;
    std::vector<BlockMatrix<float>> systems;
    std::vector<std::vector<Vec3T<float>>> sides;
    std::vector<std::uint8_t> pinned;
    double tolerance = 0.0;
    for (int frames : {120, 15, 15, 15}) {
        for (int i = 0; i < frames; ++i) {
            sim.runFrame();
        }
        integrateSprings(sim.world(), ctx); // assembles the system of a step
        sim.world().view<SpringWorkspace, const SpringNetwork>().each(
            [&](Entity, SpringWorkspace& w, const SpringNetwork& net) {
                systems.push_back(w.single.system);
                sides.push_back(w.single.rhs);
                pinned = net.pinned;
                tolerance = net.cgTolerance;
            });
    }
    AggregationMultigrid<float> multigrid;
    PcgVectors<float> work;
    std::vector<Vec3T<float>> x;
    double iterations = 0.0;
    for (auto _ : state) {
        for (std::size_t k = 0; k < systems.size(); ++k) {
            multigrid.update(systems[k], pool);
            work.remembered = 0;
            x.assign(systems[k].n, Vec3T<float>{});
            iterations +=
                solvePcg(systems[k], sides[k], x, multigrid, pinned, tolerance, 500, work, pool).iterations;
        }
    }
    state.counters["cg_iterations"] = iterations / static_cast<double>(state.iterations() * systems.size());
}
BENCHMARK(BM_SolveCurtain100)->Unit(benchmark::kMillisecond)->Iterations(12)->Arg(1)->Arg(2);

// symplectic Euler needs about 47 substeps per 60 fps frame on this cloth (BASELINES.md): one such step
void BM_CurtainSymplectic35(benchmark::State& state) {
    curtainStep(state,
                {"curtain.cloth.integrator=symplectic_euler", "scene.dt=0.000354609929", "scene.substeps=47"},
                20);
}
BENCHMARK(BM_CurtainSymplectic35)->Unit(benchmark::kMillisecond)->Iterations(20000);

// the same without the wind (which acts on every triangle): the springs, gravity and drag alone
void BM_CurtainSymplectic35NoWind(benchmark::State& state) {
    curtainStep(state,
                {"curtain.cloth.integrator=symplectic_euler", "scene.dt=0.000354609929", "scene.substeps=47"},
                20, false);
}
BENCHMARK(BM_CurtainSymplectic35NoWind)->Unit(benchmark::kMillisecond)->Iterations(20000);

// the plain way, for the ratio (BASELINES.md measured it at about 29 ms): Eigen triplet assembly of the
// same implicit Euler system and Eigen's Jacobi-preconditioned CG from zero to 1e-6, on the same state
void BM_CurtainPlainEigen35(benchmark::State& state) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/curtain.toml";
    Simulation sim(catalog(), path, readScenarioFile(path), {});
    for (int i = 0; i < 120; ++i) {
        sim.runFrame();
    }
    const SpringNetwork* found = nullptr;
    sim.world().view<const SpringNetwork>().each([&](Entity, const SpringNetwork& n) { found = &n; });
    const SpringNetwork& net = *found;
    const double h = sim.scene().dt;
    const Environment env{{0.0, -9.81, 0.0}, nullptr};
    const auto n = static_cast<Eigen::Index>(3 * net.x.size());
    std::vector<Vec3> f;
    double iterations = 0.0;
    for (auto _ : state) {
        springForces(net, env, net.x, net.v, f);
        std::vector<Eigen::Triplet<double>> triplets;
        Eigen::VectorXd b(n);
        // pinned masses: identity rows and columns, zero right-hand side
        auto add = [&](std::size_t row, std::size_t col, double e) {
            if (!net.pinned[row / 3] && !net.pinned[col / 3]) {
                triplets.emplace_back(static_cast<int>(row), static_cast<int>(col), e);
            }
        };
        for (std::size_t i = 0; i < net.x.size(); ++i) {
            const double diag = net.pinned[i] ? 1.0 : 1.0 / net.invMass[i] + h * net.drag;
            for (std::size_t c = 0; c < 3; ++c) {
                triplets.emplace_back(static_cast<int>(3 * i + c), static_cast<int>(3 * i + c), diag);
            }
            const double fi[3] = {h * f[i].x, h * f[i].y, h * f[i].z};
            for (std::size_t c = 0; c < 3; ++c) {
                b[static_cast<Eigen::Index>(3 * i + c)] = net.pinned[i] ? 0.0 : fi[c];
            }
        }
        for (const SpringLink& s : net.links) {
            Mat3 k;
            Vec3 u;
            double len = 0.0;
            if (!springStiffness(s, net.x[s.a], net.x[s.b], k, u, len)) {
                continue;
            }
            const Vec3 kdv = k * (net.v[s.b] - net.v[s.a]);
            const double change[3] = {kdv.x, kdv.y, kdv.z}, uu[3] = {u.x, u.y, u.z};
            for (std::size_t r = 0; r < 3; ++r) {
                b[static_cast<Eigen::Index>(3 * s.a + r)] += net.pinned[s.a] ? 0.0 : h * h * change[r];
                b[static_cast<Eigen::Index>(3 * s.b + r)] -= net.pinned[s.b] ? 0.0 : h * h * change[r];
                for (std::size_t c = 0; c < 3; ++c) {
                    const double e = h * s.kd * uu[r] * uu[c] + h * h * k.m[3 * r + c];
                    add(3 * s.a + r, 3 * s.a + c, e);
                    add(3 * s.b + r, 3 * s.b + c, e);
                    add(3 * s.a + r, 3 * s.b + c, -e);
                    add(3 * s.b + r, 3 * s.a + c, -e);
                }
            }
        }
        Eigen::SparseMatrix<double> a(n, n);
        a.setFromTriplets(triplets.begin(), triplets.end());
        Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
        cg.setTolerance(1e-6);
        cg.compute(a);
        Eigen::VectorXd dv = cg.solve(b);
        benchmark::DoNotOptimize(dv.data());
        iterations += static_cast<double>(cg.iterations());
    }
    state.counters["cg_iterations"] = iterations / static_cast<double>(state.iterations());
}
BENCHMARK(BM_CurtainPlainEigen35)->Unit(benchmark::kMillisecond)->Iterations(10);

} // namespace
} // namespace tumble
