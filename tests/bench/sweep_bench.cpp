// What `tumble sweep` costs beyond its runs (issue: under 30 ms a case): a 200-case sweep of `rope` (60
// frames, no render) at one case at a time, against the same 200 `tumble run` commands started one after
// another by this program, in the same iteration. Counters: overhead_ms_per_case (the sweep's wall time less
// the direct runs', a case) and own_ms_per_case (the sweep's wall time less the wall time of its own runs,
// as the sweep measures them: the same quantity without the noise of a second set of runs).

#include "app/subprocess.h"
#include "app/sweep.h"

#include <benchmark/benchmark.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>

namespace tumble {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double seconds(Clock::time_point since) {
    return std::chrono::duration<double>(Clock::now() - since).count();
}

/// Runs a command to its end (its output to a log), as the sweep starts each run.
void runToEnd(const std::vector<std::string>& argv, const std::string& log) {
    const pid_t pid = spawnLogged(argv, log);
    int status = 0;
    ::waitpid(pid, &status, 0);
}

void BM_SweepOverhead200Rope(benchmark::State& state) {
    const std::string dir = fs::temp_directory_path() / "tumble_sweep_bench";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string file = dir + "/rope200.toml";
    std::ofstream(file)
        << "[sweep]\nscenario = \"rope\"\nframes = 60\n[[axis]]\nkey = \"chain.rope.stiffness\"\n"
           "log_range = [500.0, 5000.0, 20]\n[[axis]]\nkey = \"chain.rope.damping\"\n"
           "range = [0.1, 0.5, 10]\n";
    const Sweep sweep = readSweep(file);
    const std::string tumble = std::string(TUMBLE_BINARY);
    for (auto _ : state) {
        // the runs alone: the command the sweep gives each case, less reading their outputs back
        const auto direct = Clock::now();
        for (std::size_t c = 0; c < sweep.caseCount(); ++c) {
            fs::create_directories(dir + "/direct");
            runToEnd(caseRunCommand(sweep, tumble, dir + "/direct", c, 0), dir + "/direct.log");
        }
        const double directSeconds = seconds(direct);
        fs::remove_all(dir + "/out");
        const auto swept = Clock::now();
        runToEnd({tumble, "sweep", file, "--local", "-j", "1", "--quiet", "--out", dir + "/out"},
                 dir + "/sweep.log");
        const double sweepSeconds = seconds(swept);
        double runSeconds = 0.0;
        for (std::size_t c = 0; c < sweep.caseCount(); ++c) {
            runSeconds += readCaseResult(dir + "/out", c, sweep).value_or(CaseResult{}).wallSeconds;
        }
        state.counters["overhead_ms_per_case"] =
            1e3 * (sweepSeconds - directSeconds) / double(sweep.caseCount());
        state.counters["own_ms_per_case"] = 1e3 * (sweepSeconds - runSeconds) / double(sweep.caseCount());
        state.counters["run_ms_per_case"] = 1e3 * directSeconds / double(sweep.caseCount());
    }
    fs::remove_all(dir);
}
BENCHMARK(BM_SweepOverhead200Rope)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

} // namespace
} // namespace tumble
