#pragma once
// The `tumble` command line (README, "Using it"): list, check, run, replay. The engine owns the verbs; the
// systems arrive through the catalog the caller passes in, so the engine never names a system.

#include "engine/catalog.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace tumble {

/// Exit codes (README, "Using it").
enum ExitCode : int {
    kExitOk = 0,
    kExitFailure = 1,      ///< runtime failure
    kExitBadInput = 2,     ///< usage, scenario or replay file
    kExitOverBudget = 3,   ///< `budget`
    kExitDiverged = 4,     ///< `replay --verify`
    kExitInterrupted = 130 ///< Ctrl-C: outputs so far were written
};

/// What `tumble view` is asked for (the scenario already read); see app/viewer.h.
struct ViewRequest {
    std::string scenarioPath;
    std::string scenarioText;
    std::vector<std::string> sets; ///< --set overrides
    std::uint64_t memoryCap = 0;   ///< bytes
    std::string record;            ///< --record FILE: a replay of what happens in the window
    std::string profile;           ///< --profile FILE: the budget summary, written when the window closes
    bool paused = false;           ///< --paused: start with the simulation stopped
    int threads = 1;               ///< --threads: threads the steps run on
};

/// The viewer of a program that has one (the engine's CLI itself opens no window).
using ViewerFn = std::function<int(const Catalog&, const ViewRequest&)>;

/// Runs the command line; returns the process exit code. `view` runs `viewer` (without one, it says so).
int runCli(int argc, char** argv, const Catalog& catalog, const ViewerFn& viewer = {});

/// The folder that holds the demos: $TUMBLE_DEMOS, else demos/ beside or above the executable, else the
/// source tree's demos/.
std::string demoDirectory();

/// A path to a .toml file, or a demo name, to the scenario file's path. Throws ScenarioError if neither.
std::string resolveScenario(const std::string& nameOrPath);

} // namespace tumble
