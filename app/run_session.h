#pragma once
// One run of a world from the command line (`run`, `replay`), as a session: prepare the events (the
// scenario's, a replay's recorded ones, --input), open every output before any work, run the frames
// (recording, verifying, snapshotting, dumping and rendering after each), then finish the outputs and say
// what was written. The command line (app/cli.cpp) parses options into RunOptions and a Source.

#include "engine/catalog.h"
#include "engine/replay.h"
#include "engine/scenario.h"

#include <cstdint>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// Every option of the verbs that run a world (`run`, `replay`, `budget`, `view`, `check`).
struct RunOptions {
    std::string scenario;
    std::vector<std::string> sets;
    std::optional<std::int64_t> frames;
    std::string out;
    bool noRender = false;
    std::string profile;
    std::string trace;
    std::string dump;
    std::int64_t dumpEvery = 0;
    std::int64_t pngEvery = 0;
    std::string video;
    bool quiet = false;
    bool progress = false;
    std::string record;                     ///< --record FILE
    std::string input;                      ///< --input FILE (JSON Lines of timed actions)
    std::optional<std::int64_t> snapshotAt; ///< --snapshot-at N
    std::string from;                       ///< --from SNAPSHOT
    bool verify = false;                    ///< replay --verify
    bool realtime = false;                  ///< run --realtime
    bool checkContact = false;              ///< run/replay --check-contact
    bool paused = false;                    ///< view --paused
    std::optional<double> physicsMs;        ///< budget --physics-ms
    std::optional<double> scale;            ///< budget --scale
    std::string chart;                      ///< budget --chart FILE (SVG)
    std::int64_t memoryCapMiB = std::int64_t(kDefaultMemoryCap >> 20); ///< --memory-cap MIB
    std::optional<int> threads;                                        ///< --threads N
};

/// The threads a command runs on: --threads, else TUMBLE_THREADS, else every hardware thread. Throws
/// ScenarioError (bad input) when TUMBLE_THREADS is not a thread count.
int threadsFor(const RunOptions& o);

/// Where a run's scenario and events come from, and what it holds itself to.
struct Source {
    std::string path;                         ///< the scenario's path (for messages)
    std::string text;                         ///< the scenario
    std::vector<std::string> sets;            ///< --set overrides
    std::shared_ptr<const ReplayFile> replay; ///< replay: the recorded events and hashes
    bool verify = false;                      ///< compare every frame's hash with the replay's
    std::uint64_t resume = 0; ///< --from: frames re-simulated (and checked) before the run proper
    std::string replayPath;   ///< the replay or snapshot file, for messages
    std::uint64_t memoryCap = kDefaultMemoryCap; ///< bytes the scene may ask for (--memory-cap)
    int threads = 1;                             ///< threads the steps run on (any number: the same bits)
    /// if given: where a verified replay diverged ("" when it did not), which the run then does not print
    std::string* diverged = nullptr;
};

/// A replay file as a source (read here: throws ReplayError when it cannot be).
Source replaySource(const std::string& path, bool verify, int threads);

/// An output file opened at the start of a run, so that a bad path fails before any work is done.
class OutputFile {
public:
    /// Creates the file (and its folder); throws std::runtime_error if it cannot.
    explicit OutputFile(const std::string& path);
    void write(const std::string& text) {
        m_out << text;
        check();
    }
    std::ostream& stream() { return m_out; }
    /// Throws if anything written so far failed.
    void check() const {
        if (!m_out) {
            throw std::runtime_error("cannot write " + m_path);
        }
    }
    const std::string& path() const { return m_path; }
    void close() {
        m_out.close();
        if (!m_out) {
            throw std::runtime_error("cannot write " + m_path);
        }
    }

private:
    std::string m_path;
    std::ofstream m_out;
};

/// Runs the source under the options; returns the process exit code (app/cli.h). Throws ScenarioError or
/// ReplayError for bad input, std::runtime_error for an output that cannot be written.
int runSession(const Catalog& catalog, const RunOptions& options, const Source& source);

} // namespace tumble
