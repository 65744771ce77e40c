#pragma once
// The `tumble` command line (CONTRACT.md): list, check, run, replay. The engine owns the verbs; the systems arrive
// through the catalog the caller passes in, so the engine never names a system.

#include "engine/catalog.h"

#include <string>

namespace tumble {

/// Exit codes of CONTRACT.md.
enum ExitCode : int {
    kExitOk = 0,
    kExitFailure = 1,      ///< runtime failure
    kExitBadInput = 2,     ///< usage, scenario or replay file
    kExitOverBudget = 3,   ///< `budget`
    kExitDiverged = 4,     ///< `replay --verify`
    kExitInterrupted = 130 ///< Ctrl-C: outputs so far were written
};

/// Runs the command line; returns the process exit code.
int runCli(int argc, char** argv, const Catalog& catalog);

/// The folder that holds the demos: $TUMBLE_DEMOS, else demos/ beside or above the executable, else the
/// source tree's demos/.
std::string demoDirectory();

/// A path to a .toml file, or a demo name, to the scenario file's path. Throws ScenarioError if neither.
std::string resolveScenario(const std::string& nameOrPath);

} // namespace tumble
