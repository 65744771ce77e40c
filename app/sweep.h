#pragma once
// Parameter sweeps (README "Sweeps"; the file format in CONTRACT.md). A sweep file names a scenario, axes
// over keys that --set accepts, and metrics read from each case's final dump. Every case is one or more
// `tumble run` processes (one per repeat), started by this program on this machine (--local) or by Slurm's
// array tasks (--slurm, each task running one shard: the cases whose index is the task's modulo the task
// count). A case's outcome is kept in OUT/cases/NNNNN/result.json, written whole (a temporary file
// renamed) only once the case has ended, so a sweep stopped anywhere, by Ctrl-C, a kill or a lost node,
// resumes by running only the cases without one; OUT/results.csv is merged from them in case order.
//
// Why processes rather than threads: a case that crashes, hangs or blows up must end as a row of the table,
// not end the sweep, and a Slurm task is a process anyway; a process costs about 4 ms to start here.

#include "engine/catalog.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// One axis of a sweep: a key and the values it takes, each as --set reads it.
struct SweepAxis {
    std::string key;                  ///< a --set key, "chain.rope.stiffness"
    std::vector<std::string> values;  ///< as --set reads them: TOML text ("400", "\"rk4\"", "true")
    std::vector<std::string> display; ///< as the table shows them (strings unquoted)
    bool logScale = false;            ///< from log_range: plots use a log axis
    bool generated = false;           ///< from range, log_range or random (not listed one by one)
    int line = 0;                     ///< where the axis is in the sweep file (0: unknown)
    int column = 0;
};

/// A value read from a case's final dump.
struct SweepMetric {
    std::string name;        ///< its column in results.csv
    std::string entity;      ///< the entity's name in the scenario
    std::string field;       ///< x | v (a mass, node or body), count (particles), h (a water node)
    std::int64_t index = -1; ///< which mass, node, body or water node (row-major); -1: the last
    int component = 0;       ///< 0, 1 or 2 of x or v
    int line = 0;
    int column = 0;
};

/// A sweep file, read and checked in form (checkSweep checks it against the scenario).
struct Sweep {
    std::string path;         ///< the sweep file as given (messages name it)
    std::string file;         ///< the sweep file, absolute
    std::string name;         ///< the file's stem: the default output folder is out/<name>/
    std::string scenarioPath; ///< resolved: a demo's file or a path relative to the sweep file, absolute
    std::string scenarioText;
    std::int64_t frames = 0; ///< frames per run; 0: the scene's own
    int threads = 1;         ///< threads per run (any count gives the same bits)
    int repeats = 1;         ///< runs per case: times are their medians, the hash must be the same
    bool zip = false;        ///< axes zipped (case i takes every axis's value i) rather than a grid
    std::uint64_t seed = 1;  ///< seeds the random axes
    double timeout = 0.0;    ///< s a run may take before it is killed and its case is an error; 0: none
    std::vector<SweepAxis> axes;
    std::vector<SweepMetric> metrics;

    /// Cases: the product of the axes' lengths (grid, the last axis fastest) or their common length (zip).
    std::size_t caseCount() const;
    /// The index of each axis's value in case `c`.
    std::vector<std::size_t> caseValueIndices(std::size_t c) const;
    /// The --set arguments of case `c`: "KEY=VALUE", one per axis.
    std::vector<std::string> caseSets(std::size_t c) const;
};

/// Reads a sweep file. Throws ScenarioError (file:line:col, a did-you-mean for a misspelt key).
Sweep readSweep(const std::string& path);

/// Loads the scenario with each axis's values (every listed value; a range's ends) as --set would, and
/// checks each metric's entity exists, before any case runs. Throws ScenarioError located at the axis
/// or metric. Returns the scenario's physics budget, ms (plots draw it).
double checkSweep(const Catalog& catalog, const Sweep& sweep);

/// A number that changes when anything that changes the table changes: the scenario and its text, the
/// frames, repeats, cases and metrics (not the threads: any count gives the same bits).
std::uint64_t sweepFingerprint(const Sweep& sweep);

/// What became of one case.
struct CaseResult {
    std::string status = "error";     ///< ok | error | blow_up
    int exitCode = 0;                 ///< the (first failing) run's exit code; 128 + N for signal N
    std::optional<double> p50;        ///< physics ms: the median over repeats of each run's p50
    std::optional<double> p99;        ///< the median over repeats of each run's p99
    std::optional<double> max;        ///< the largest over repeats
    std::string hash;                 ///< the final state hash, 16 hex digits ("" when the run made none)
    std::vector<std::string> metrics; ///< one per metric, as text ("" when the dump lacks it)
    std::string detail;               ///< what went wrong: the blow-up's or error's message
    double wallSeconds = 0.0;         ///< the runs' wall time, s (the sweep's own overhead is measured
                                      ///< against it)
    std::string sweep;                ///< hash16 of the sweepFingerprint it was run for
};

/// `tumble sweep`'s options.
struct SweepOptions {
    std::string file;
    std::string out;    ///< default out/<sweep name>/
    bool local = false; ///< --local
    int jobs = 0;       ///< -j: cases at a time (0: cores / threads per case)
    bool slurm = false; ///< --slurm
    std::string partition;
    int maxParallel = 0;        ///< --max-parallel: Slurm's %K throttle (0: none)
    int tasks = 0;              ///< --tasks: array tasks (0: one per case, at most 1000)
    bool noWait = false;        ///< --no-wait
    std::string shard;          ///< --shard I/N
    bool merge = false;         ///< --merge
    bool status = false;        ///< --status
    std::string plot;           ///< --plot METRIC
    std::string by;             ///< --by AXIS
    std::optional<int> threads; ///< --threads: overrides the file's
    bool quiet = false;
    bool progress = false;
};

/// Runs `tumble sweep`; returns the exit code. Throws ScenarioError for bad input.
int commandSweep(const Catalog& catalog, const SweepOptions& options);

// ---- the pieces commandSweep is made of (app/sweep_run.cpp), for the tests

/// OUT/cases/NNNNN.
std::string caseFolder(const std::string& out, std::size_t c);
/// The case's result, if it has ended as a case of this sweep (a result another sweep left in the folder is
/// none: two sweeps started in one folder before either had a result mixed their rows in one table).
std::optional<CaseResult> readCaseResult(const std::string& out, std::size_t c, const Sweep& sweep);
/// The cases of shard i of n: those whose index is i modulo n.
std::vector<std::size_t> shardCases(std::size_t caseCount, std::size_t shard, std::size_t shards);
/// Writes the case's result.json whole (a temporary file renamed).
void writeCaseResult(const std::string& out, std::size_t c, const CaseResult& result);
/// Each metric's value in the last line of a dump ("" for one it lacks).
std::vector<std::string> readMetrics(const std::string& dumpPath, const std::vector<SweepMetric>& metrics);
/// Why a metric cannot be read from a dump line, or "" (particles' indices are not checked: they come and
/// go).
std::string metricProblem(const std::string& dumpLine, const SweepMetric& metric);
/// Each metric's value in a dump line ("" for one it lacks).
std::vector<std::string> metricValues(const std::string& dumpLine, const std::vector<SweepMetric>& metrics);
/// results.csv's columns, and one case's cells.
std::vector<std::string> resultColumns(const Sweep& sweep);
std::vector<std::string> resultRow(const Sweep& sweep, std::size_t c, const CaseResult& result);
/// Writes a file whole or not at all.
void writeSweepFile(const std::string& path, const std::string& text);
/// A hash as results.csv shows it: 16 hex digits.
std::string hash16(std::uint64_t h);
/// The command of run `repeat` of case `c` by the program `exe`, its outputs in `folder`.
std::vector<std::string> caseRunCommand(const Sweep& sweep, const std::string& exe, const std::string& folder,
                                        std::size_t c, int repeat);
/// This program's own path (each case runs it again).
std::string selfExecutable();

/// How runCases shows itself.
struct ProgressStyle {
    bool bar = false;   ///< the one-line progress, redrawn in place
    bool quiet = false; ///< not even the failing cases' lines
};

/// What runCases did.
struct CaseTally {
    std::size_t skipped = 0;  ///< cases that had a result already
    std::size_t ran = 0;      ///< cases run to a result now
    bool interrupted = false; ///< stopped by SIGINT or SIGTERM (the cases under way keep no result)
    double wallSeconds = 0.0; ///< the whole call
    double runSeconds = 0.0;  ///< the runs' own wall time, summed
};

/// Runs the given cases that have no result yet, `jobs` at a time, writing each one's result.json as it
/// ends. SIGINT or SIGTERM stops it: the runs under way are stopped and keep no result.
CaseTally runCases(const Sweep& sweep, const std::string& out, const std::vector<std::size_t>& cases,
                   int jobs, const ProgressStyle& style);

/// Throws ScenarioError (exit 2) naming what is missing when Slurm's client is not on the PATH.
void requireSlurm();
/// --slurm: the array script written (OUT/slurm/sweep.sbatch), submitted, waited for (unless --no-wait), its
/// unfinished tasks submitted once more, the table merged. Returns the exit code.
int sweepSlurm(const Sweep& sweep, const std::string& out, const SweepOptions& options);

/// --plot: writes OUT/plot_METRIC_by_AXIS.svg from the cases that have ended; returns its path.
std::string plotSweep(const Sweep& sweep, const std::string& out, const std::string& metric,
                      const std::string& by, double budgetMs);

/// Writes OUT/results.csv from every ended case (in case order); returns how many have not ended.
std::size_t mergeResults(const Sweep& sweep, const std::string& out);

} // namespace tumble
