// Running a sweep's cases on this machine (--local, and each Slurm task's --shard), and the `sweep` verb's
// modes (app/sweep.h).

#include "app/sweep.h"

#include "app/progress.h"
#include "app/subprocess.h"
#include "engine/dump.h"
#include "engine/replay.h"
#include "engine/table_reader.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace tumble {

namespace fs = std::filesystem;
using nlohmann::json;
using SteadyClock = std::chrono::steady_clock;

namespace {

volatile std::sig_atomic_t g_interrupted = 0;

void onInterrupt(int) {
    g_interrupted = 1;
}

/// One run of a case (one of its repeats), as it ended.
struct RunOutcome {
    int exitCode = 0;
    double wallSeconds = 0.0;
    bool timedOut = false;
    bool blowUp = false; ///< the log names a blow-up
    std::string detail;  ///< the blow-up's line, else the log's last line
    std::optional<double> p50, p99, max;
    std::string hash;
};

/// A case under way: the run going on and those done.
struct CaseRun {
    std::size_t c = 0;
    int repeat = 0;
    pid_t pid = -1;
    SteadyClock::time_point start;
    bool timedOut = false;
    std::vector<RunOutcome> done;
};

std::string repeatSuffix(int repeat) {
    return repeat == 0 ? "" : "_" + std::to_string(repeat);
}

void startRun(const Sweep& s, const std::string& out, CaseRun& run) {
    const std::string folder = caseFolder(out, run.c);
    const std::vector<std::string> argv = caseRunCommand(s, selfExecutable(), folder, run.c, run.repeat);
    if (run.repeat == 0) {
        // whatever an interrupted attempt left is not this attempt's
        std::error_code ec;
        fs::remove_all(folder, ec);
        fs::create_directories(folder);
        std::string command;
        for (const std::string& a : argv) {
            command += (command.empty() ? "" : " ") + shellQuote(a);
        }
        writeSweepFile(folder + "/command.txt", command + "\n");
    }
    run.pid = spawnLogged(argv, folder + "/log" + repeatSuffix(run.repeat) + ".txt");
    run.start = SteadyClock::now();
    run.timedOut = false;
}

/// The log's blow-up line, else its last line (less the program's name), for the detail column.
void readLog(const std::string& path, RunOutcome& o) {
    std::ifstream in(path);
    std::string line, last;
    while (std::getline(in, line)) {
        if (line.find(" blew up") != std::string::npos && !o.blowUp) {
            o.blowUp = true;
            o.detail = line;
        }
        if (line.find_first_not_of(" \t\r") != std::string::npos) {
            last = line;
        }
    }
    if (!o.blowUp) {
        o.detail = last;
    }
    for (const char* prefix : {"tumble: error: ", "tumble: "}) {
        if (o.detail.rfind(prefix, 0) == 0) {
            o.detail = o.detail.substr(std::strlen(prefix));
        }
    }
    if (o.detail.size() > 400) {
        // cut before a UTF-8 continuation byte, never inside a character
        std::size_t cut = 400;
        while (cut > 0 && (static_cast<unsigned char>(o.detail[cut]) & 0xC0) == 0x80) {
            --cut;
        }
        o.detail = o.detail.substr(0, cut) + "...";
    }
}

RunOutcome collectRun(const std::string& out, const CaseRun& run, int waitStatus) {
    const std::string folder = caseFolder(out, run.c), suffix = repeatSuffix(run.repeat);
    RunOutcome o;
    o.exitCode = exitCodeOf(waitStatus);
    o.wallSeconds = std::chrono::duration<double>(SteadyClock::now() - run.start).count();
    o.timedOut = run.timedOut;
    readLog(folder + "/log" + suffix + ".txt", o);
    if (WIFSIGNALED(waitStatus) && !o.timedOut) {
        // a process killed by a signal writes nothing of it: say which
        const int sig = WTERMSIG(waitStatus);
        const char* name = ::sigabbrev_np(sig);
        o.detail = "killed by signal " + std::to_string(sig) +
                   (name ? std::string(" (SIG") + name + ")" : "") +
                   (o.detail.empty() ? "" : "; the log's last line: " + o.detail);
    }
    std::ifstream profile(folder + "/profile" + suffix + ".json");
    const json p = json::parse(profile, nullptr, false);
    if (!p.is_discarded() && p.contains("frame")) {
        const json& f = p["frame"];
        auto read = [&](const char* key) {
            return f.contains(key) && f[key].is_number() ? std::optional<double>(f[key].get<double>())
                                                         : std::nullopt;
        };
        o.p50 = read("physics_p50_ms");
        o.p99 = read("physics_p99_ms");
        o.max = read("physics_max_ms");
    }
    if (o.exitCode == 0 || o.exitCode == 1) {
        try {
            const ReplayFile replay = readReplay(folder + "/run" + suffix + ".tumble");
            if (!replay.frames.empty()) {
                o.hash = hash16(replay.frames.back().hash);
            }
        } catch (const std::exception&) {
            // no replay, no hash: the detail says why the run ended
        }
    }
    return o;
}

std::optional<double> median(std::vector<double> v) {
    if (v.empty()) {
        return std::nullopt;
    }
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// A case's result from its runs: the first that failed decides its status; the times are the medians.
CaseResult caseResult(const Sweep& s, const std::string& out, const CaseRun& run) {
    CaseResult r;
    r.status = "ok";
    std::vector<double> p50, p99;
    for (const RunOutcome& o : run.done) {
        r.wallSeconds += o.wallSeconds;
        if (o.p50) {
            p50.push_back(*o.p50);
        }
        if (o.p99) {
            p99.push_back(*o.p99);
        }
        if (o.max) {
            r.max = std::max(r.max.value_or(*o.max), *o.max);
        }
        if (r.status == "ok" && (o.exitCode != 0 || o.timedOut)) {
            r.status = o.exitCode == 1 && o.blowUp && !o.timedOut ? "blow_up" : "error";
            r.exitCode = o.exitCode;
            char limit[64];
            std::snprintf(limit, sizeof limit, "timed out after %g s (the sweep's timeout)", s.timeout);
            r.detail = o.timedOut ? limit : o.detail;
        }
    }
    r.p50 = median(p50);
    r.p99 = median(p99);
    r.hash = r.status == "error" ? "" : run.done.front().hash;
    for (std::size_t i = 1; i < run.done.size() && r.status == "ok"; ++i) {
        if (run.done[i].hash != r.hash) {
            r.status = "error";
            r.detail = "repeat " + std::to_string(i) + " ended with hash " + run.done[i].hash +
                       ", the first run with " + r.hash + ": the runs are not deterministic";
        }
    }
    r.metrics = r.status == "error" && r.exitCode != 1
                    ? std::vector<std::string>(s.metrics.size())
                    : readMetrics(caseFolder(out, run.c) + "/state.jsonl", s.metrics);
    return r;
}

/// The one-line progress of a sweep: cases done of all, by status, and the time left.
class SweepProgress {
public:
    SweepProgress(std::string name, std::size_t total, std::size_t already, bool bar, bool quiet)
        : m_name(std::move(name)), m_total(total), m_already(already), m_bar(bar), m_quiet(quiet),
          m_start(SteadyClock::now()) {}

    void caseEnded(const Sweep& s, std::size_t c, const CaseResult& r) {
        ++m_counts[r.status];
        if (r.status != "ok" && !m_quiet) {
            clear();
            std::string sets;
            for (const std::string& set : s.caseSets(c)) {
                sets += (sets.empty() ? "" : " ") + set;
            }
            std::fprintf(stderr, "tumble sweep: case %zu (%s): %s: %s\n", c, sets.c_str(), r.status.c_str(),
                         r.detail.c_str());
        }
        draw(false);
    }
    void tick() { draw(false); }
    void finish() {
        draw(true);
        if (m_drawn) {
            std::fputc('\n', stderr);
        }
    }
    std::string counts() const {
        std::string text;
        for (const auto& [status, n] : m_counts) {
            text += (text.empty() ? "" : ", ") + std::to_string(n) + " " + status;
        }
        return text.empty() ? "none run" : text;
    }

private:
    void clear() {
        if (m_drawn) {
            std::fprintf(stderr, "\r\033[K");
        }
    }
    void draw(bool force) {
        const auto now = SteadyClock::now();
        if (!m_bar || (!force && now - m_last < std::chrono::milliseconds(100))) {
            return;
        }
        m_last = now;
        std::size_t ran = 0;
        for (const auto& [status, n] : m_counts) {
            ran += n;
        }
        const double elapsed = std::chrono::duration<double>(now - m_start).count();
        const std::size_t left = m_total - std::min(m_total, m_already + ran);
        const double eta = ran ? elapsed / double(ran) * double(left) : 0.0;
        std::fprintf(stderr, "\r\033[Ksweep %s: %zu/%zu cases (%s), %.1f s, ETA %.0f s", m_name.c_str(),
                     m_already + ran, m_total, counts().c_str(), elapsed, eta);
        std::fflush(stderr);
        m_drawn = true;
    }

    std::string m_name;
    std::size_t m_total, m_already;
    bool m_bar, m_quiet, m_drawn = false;
    std::map<std::string, std::size_t> m_counts;
    SteadyClock::time_point m_start, m_last;
};

/// SIGINT and SIGTERM set a flag while a sweep runs (the runs get Ctrl-C themselves: they share the
/// terminal's process group).
class InterruptGuard {
public:
    InterruptGuard() {
        g_interrupted = 0;
        struct sigaction sa {};
        sa.sa_handler = onInterrupt;
        sigemptyset(&sa.sa_mask);
        ::sigaction(SIGINT, &sa, &m_int);
        ::sigaction(SIGTERM, &sa, &m_term);
    }
    ~InterruptGuard() {
        ::sigaction(SIGINT, &m_int, nullptr);
        ::sigaction(SIGTERM, &m_term, nullptr);
    }

private:
    struct sigaction m_int {};
    struct sigaction m_term {};
};

/// A run ended: the next repeat starts, or the case's result is written.
void runEnded(const Sweep& s, const std::string& out, std::vector<CaseRun>& running, std::size_t at,
              int status, SweepProgress& progress, CaseTally& tally) {
    CaseRun& run = running[at];
    run.done.push_back(collectRun(out, run, status));
    const RunOutcome& o = run.done.back();
    // a run ended by the signal that is stopping the sweep (Ctrl-C reaches the whole process group, Slurm's
    // SIGTERM the task) did not fail: its case keeps no result and runs again
    const bool stopped = !o.timedOut && (o.exitCode == 130 || o.exitCode == 128 + SIGTERM);
    if (g_interrupted || stopped) {
        running.erase(running.begin() + std::ptrdiff_t(at));
        return;
    }
    if (o.exitCode == 0 && !o.timedOut && run.repeat + 1 < s.repeats) {
        ++run.repeat;
        startRun(s, out, run);
        return;
    }
    CaseResult r = caseResult(s, out, run);
    r.sweep = hash16(sweepFingerprint(s));
    writeCaseResult(out, run.c, r);
    progress.caseEnded(s, run.c, r);
    tally.runSeconds += r.wallSeconds;
    ++tally.ran;
    running.erase(running.begin() + std::ptrdiff_t(at));
}

/// Reaps every run that has ended; kills those past the timeout. False when none had ended.
bool reap(const Sweep& s, const std::string& out, std::vector<CaseRun>& running, SweepProgress& progress,
          CaseTally& tally) {
    // each run by its own pid: a wait for any child would also take children that are not runs
    for (std::size_t i = 0; i < running.size(); ++i) {
        int status = 0;
        const pid_t pid = ::waitpid(running[i].pid, &status, WNOHANG);
        if (pid == running[i].pid || (pid < 0 && errno == ECHILD)) {
            runEnded(s, out, running, i, pid > 0 ? status : (1 << 8), progress, tally);
            return true;
        }
    }
    for (CaseRun& r : running) {
        const double age = std::chrono::duration<double>(SteadyClock::now() - r.start).count();
        if (s.timeout > 0.0 && age > s.timeout && !r.timedOut) {
            r.timedOut = true;
            ::kill(r.pid, SIGKILL);
        }
    }
    return false;
}

/// An interrupted sweep: its runs asked to stop (a run stops between frames), killed after 5 s if one
/// has not (a hung frame), and waited for; their cases keep no result and run next time.
void stopRuns(std::vector<CaseRun>& running) {
    for (const CaseRun& r : running) {
        ::kill(r.pid, SIGTERM);
    }
    const auto deadline = SteadyClock::now() + std::chrono::seconds(5);
    while (!running.empty()) {
        int status = 0;
        const pid_t pid = ::waitpid(running.back().pid, &status, WNOHANG);
        if (pid == running.back().pid || (pid < 0 && errno != EINTR)) {
            running.pop_back();
        } else if (SteadyClock::now() > deadline) {
            ::kill(running.back().pid, SIGKILL);
        } else {
            std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
    }
}

} // namespace

std::vector<std::string> caseRunCommand(const Sweep& s, const std::string& exe, const std::string& folder,
                                        std::size_t c, int repeat) {
    const std::string suffix = repeatSuffix(repeat);
    std::vector<std::string> argv = {exe,
                                     "run",
                                     s.scenarioPath,
                                     "--no-render",
                                     "--quiet",
                                     "--threads",
                                     std::to_string(s.threads),
                                     "--out",
                                     folder,
                                     "--profile",
                                     folder + "/profile" + suffix + ".json",
                                     "--record",
                                     folder + "/run" + suffix + ".tumble"};
    if (s.frames > 0) {
        argv.insert(argv.end(), {"--frames", std::to_string(s.frames)});
    }
    if (repeat == 0 && !s.metrics.empty()) {
        argv.insert(argv.end(), {"--dump", folder + "/state.jsonl"});
    }
    for (const std::string& set : s.caseSets(c)) {
        argv.insert(argv.end(), {"--set", set});
    }
    return argv;
}

std::string hash16(std::uint64_t h) {
    return hashHex(h).substr(2);
}

std::string selfExecutable() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) {
        throw std::runtime_error("cannot find this program's own path (/proc/self/exe): " + ec.message());
    }
    return exe.string();
}

CaseTally runCases(const Sweep& s, const std::string& out, const std::vector<std::size_t>& cases, int jobs,
                   const ProgressStyle& style) {
    std::vector<std::size_t> todo;
    for (std::size_t c : cases) {
        if (!readCaseResult(out, c, s)) {
            todo.push_back(c);
        }
    }
    CaseTally tally;
    tally.skipped = cases.size() - todo.size();
    SweepProgress progress(s.name, cases.size(), tally.skipped, style.bar, style.quiet);
    const InterruptGuard guard;
    const auto start = SteadyClock::now();
    std::vector<CaseRun> running;
    std::size_t next = 0;
    while ((next < todo.size() && !g_interrupted) || !running.empty()) {
        while (!g_interrupted && running.size() < std::size_t(jobs) && next < todo.size()) {
            running.emplace_back();
            running.back().c = todo[next++];
            try {
                startRun(s, out, running.back());
            } catch (const std::exception&) {
                // no process, no folder, a full disk: the sweep cannot go on; the runs under way stop first
                running.pop_back();
                stopRuns(running);
                throw;
            }
        }
        if (g_interrupted) {
            stopRuns(running);
            break;
        }
        if (!reap(s, out, running, progress, tally)) {
            progress.tick();
            std::this_thread::sleep_for(std::chrono::microseconds(500));
        }
    }
    progress.finish();
    tally.interrupted = g_interrupted != 0;
    tally.wallSeconds = std::chrono::duration<double>(SteadyClock::now() - start).count();
    return tally;
}

} // namespace tumble
