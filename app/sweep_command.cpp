// The `sweep` verb (app/sweep.h): one mode per call, the sweep file read and checked before any case runs.

#include "app/cli.h"
#include "app/sweep.h"
#include "engine/table_reader.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sched.h>
#include <sys/file.h>
#include <thread>
#include <unistd.h>

namespace tumble {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string manifestPath(const std::string& out) {
    return out + "/sweep.json";
}

/// True when some case of the folder has a result.
bool anyResult(const std::string& out) {
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(out + "/cases", ec)) {
        if (fs::exists(entry.path() / "result.json", ec)) {
            return true;
        }
    }
    return false;
}

/// OUT/sweep.json ties the folder to one sweep: results of a sweep whose cases have since changed would
/// be merged into the wrong rows. Returns false when there is none (nothing has run yet), or when it is
/// another sweep's but no case of that one has a result (nothing would be lost: it is replaced).
bool checkManifest(const Sweep& s, const std::string& out) {
    std::ifstream in(manifestPath(out));
    if (!in) {
        return false;
    }
    const json m = json::parse(in, nullptr, false);
    const std::string want = hash16(sweepFingerprint(s));
    // a fingerprint that is not a string (a hand-edited file) is another sweep's, not a crash
    const bool ours = m.is_object() && m.contains("fingerprint") && m["fingerprint"].is_string() &&
                      m["fingerprint"].get<std::string>() == want;
    if (!ours) {
        if (!anyResult(out)) {
            return false;
        }
        throw ScenarioError(s.path, 0, 0,
                            out +
                                " holds the results of another sweep (its scenario, frames, repeats, axes or "
                                "metrics differ from this file's): give another --out, or delete " +
                                out + " to start again");
    }
    return true;
}

/// A flock(2) held while it lives. `wait`: block until it is free, else give up at once (held() false).
/// `create`: make the file if it is missing (else a missing file is free: held() true, nothing locked). A
/// file that cannot be opened (another user's, a file system without locks) locks nothing and counts as
/// held: nothing is stopped then, as FolderLock notes.
class FileLock {
public:
    FileLock(const std::string& path, int operation, bool wait, bool create = true) {
        // read-only is enough for flock, and opens another user's lock file in a shared folder
        m_fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | (create ? O_CREAT : 0), 0644);
        if (m_fd < 0) {
            return;
        }
        int status = 0;
        do {
            status = ::flock(m_fd, operation | (wait ? 0 : LOCK_NB));
        } while (status != 0 && errno == EINTR);
        m_held = status == 0 || errno != EWOULDBLOCK;
    }
    ~FileLock() {
        if (m_fd >= 0) {
            ::close(m_fd);
        }
    }
    FileLock(const FileLock&) = delete;
    FileLock& operator=(const FileLock&) = delete;
    bool held() const { return m_held; }

private:
    int m_fd = -1;
    bool m_held = true;
};

std::string runningPath(const std::string& out, const std::string& fingerprint) {
    return out + "/running-" + fingerprint;
}

/// Ties OUT to this sweep (sweep.json) and returns the lock that says a run of it is under way, for the
/// caller to hold while its cases run. The check and the write are one step under OUT/manifest.lock, and
/// another sweep's manifest is replaced only when none of its runs holds its own lock: two shards of
/// different sweeps started in the same instant could otherwise both find the folder free and run their
/// cases into it.
std::unique_ptr<FileLock> writeManifest(const Sweep& s, const std::string& out) {
    fs::create_directories(out + "/cases");
    const FileLock mutex(out + "/manifest.lock", LOCK_EX, true);
    const std::string fingerprint = hash16(sweepFingerprint(s));
    if (!checkManifest(s, out)) {
        std::ifstream in(manifestPath(out));
        const json was = in ? json::parse(in, nullptr, false) : json();
        const json* other = was.is_object() && was.contains("fingerprint") ? &was["fingerprint"] : nullptr;
        const bool named =
            other && other->is_string() && other->get<std::string>().size() == 16 &&
            other->get<std::string>().find_first_not_of("0123456789abcdef") == std::string::npos;
        if (named && other->get<std::string>() != fingerprint &&
            !FileLock(runningPath(out, other->get<std::string>()), LOCK_EX, false, false).held()) {
            throw ScenarioError(s.path, 0, 0,
                                "another sweep is running in " + out +
                                    " (its cases have no results yet): wait for it, or give another --out");
        }
        const json m = {{"fingerprint", fingerprint},
                        {"sweep", s.file},
                        {"scenario", s.scenarioPath},
                        {"cases", s.caseCount()}};
        writeSweepFile(manifestPath(out), m.dump(1) + "\n");
    }
    return std::make_unique<FileLock>(runningPath(out, fingerprint), LOCK_SH, true);
}

/// A lock on OUT: --local holds it alone, shards share it, so that a sweep started twice in one folder
/// (a second --local, --local beside a Slurm array) is refused rather than two runs of a case meeting
/// in its folder. A file system without locks (some shared ones) goes unlocked, saying so.
class FolderLock {
public:
    FolderLock(const Sweep& s, const std::string& out, bool shared) {
        fs::create_directories(out);
        m_fd = ::open((out + "/lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (m_fd < 0 || ::flock(m_fd, (shared ? LOCK_SH : LOCK_EX) | LOCK_NB) == 0) {
            return;
        }
        if (errno == EWOULDBLOCK) {
            throw ScenarioError(s.path, 0, 0,
                                "another sweep is running in " + out +
                                    (shared ? " (a --local sweep)" : " (a --local sweep or Slurm tasks)") +
                                    ": wait for it, or give another --out");
        }
        std::fprintf(stderr,
                     "tumble sweep: note: %s cannot be locked here (%s); nothing stops a second sweep in "
                     "it\n",
                     out.c_str(), std::strerror(errno));
    }
    ~FolderLock() {
        if (m_fd >= 0) {
            ::close(m_fd);
        }
    }
    FolderLock(const FolderLock&) = delete;
    FolderLock& operator=(const FolderLock&) = delete;

private:
    int m_fd = -1;
};

std::pair<std::size_t, std::size_t> parseShard(const std::string& text) {
    // digits only: sscanf's %llu takes a sign ('1/-3' read as shard 1 of 2^64 - 3) and leading blanks
    const std::size_t slash = text.find('/');
    const auto digits = [](const std::string& part) {
        return !part.empty() && part.size() <= 18 &&
               part.find_first_not_of("0123456789") == std::string::npos;
    };
    unsigned long long i = 0, n = 0;
    const bool form =
        slash != std::string::npos && digits(text.substr(0, slash)) && digits(text.substr(slash + 1));
    if (form) {
        i = std::stoull(text.substr(0, slash));
        n = std::stoull(text.substr(slash + 1));
    }
    if (!form || n == 0 || i >= n) {
        throw ScenarioError("--shard", 0, 0,
                            "'" + text + "' is not a shard: I/N with 0 <= I < N (task I of N, from 0)");
    }
    return {std::size_t(i), std::size_t(n)};
}

int defaultJobs(const Sweep& s) {
    // the cores this process may use (a cgroup or taskset may give it fewer than the machine has)
    cpu_set_t set;
    CPU_ZERO(&set);
    const int cores = ::sched_getaffinity(0, sizeof set, &set) == 0
                          ? std::max(1, CPU_COUNT(&set))
                          : int(std::max(1u, std::thread::hardware_concurrency()));
    return std::max(1, cores / s.threads);
}

/// "22 ok, 2 blow_up, 1 not run" over the given cases; a case whose folder is there but holds no result has
/// started (it is running now, or was stopped before it ended).
std::string statusCounts(const Sweep& s, const std::string& out, const std::vector<std::size_t>& cases) {
    std::map<std::string, std::size_t> counts;
    for (std::size_t c : cases) {
        const auto r = readCaseResult(out, c, s);
        std::error_code ec;
        ++counts[r                                    ? r->status
                 : fs::exists(caseFolder(out, c), ec) ? "started (running, or stopped before its end)"
                                                      : "not run"];
    }
    std::string text;
    for (const auto& [status, n] : counts) {
        text += (text.empty() ? "" : ", ") + std::to_string(n) + " " + status;
    }
    return text;
}

int sweepStatus(const Sweep& s, const std::string& out) {
    const bool started = checkManifest(s, out);
    std::vector<std::size_t> left;
    for (std::size_t c = 0; c < s.caseCount(); ++c) {
        if (!readCaseResult(out, c, s)) {
            left.push_back(c);
        }
    }
    std::printf("sweep %s (%s): %zu cases: %s\n", s.name.c_str(), out.c_str(), s.caseCount(),
                statusCounts(s, out, shardCases(s.caseCount(), 0, 1)).c_str());
    if (!started) {
        std::printf("nothing has run yet: start it with --local or --slurm\n");
    }
    std::ifstream tasksFile(out + "/slurm/tasks");
    std::size_t tasks = 0;
    if (tasksFile >> tasks && tasks > 0 && !left.empty()) {
        std::vector<std::size_t> shards;
        for (std::size_t c : left) {
            if (std::find(shards.begin(), shards.end(), c % tasks) == shards.end()) {
                shards.push_back(c % tasks);
            }
        }
        std::sort(shards.begin(), shards.end());
        std::string list;
        for (std::size_t t : shards) {
            list += (list.empty() ? "" : ", ") + std::to_string(t);
        }
        std::printf("Slurm array of %zu tasks: tasks with cases left: %s\n", tasks, list.c_str());
    }
    return kExitOk;
}

int sweepMerge(const Sweep& s, const std::string& out) {
    if (!checkManifest(s, out)) {
        // no folder of this sweep's runs: a results.csv of empty rows written there (any folder --out
        // named, made if missing) would only mislead
        std::fprintf(
            stderr,
            "tumble sweep: %s holds no run of this sweep (its sweep.json is missing, or another "
            "sweep's with no result): nothing to merge; run it first (--local, --slurm or --shard)\n",
            out.c_str());
        return kExitFailure;
    }
    const std::size_t missing = mergeResults(s, out);
    std::printf("%s/results.csv: %zu of %zu cases\n", out.c_str(), s.caseCount() - missing, s.caseCount());
    if (missing) {
        std::fprintf(stderr, "tumble sweep: %zu cases have not run (--status says which tasks hold them)\n",
                     missing);
        return kExitFailure;
    }
    return kExitOk;
}

/// --local (every case) or --shard I/N (its share), on this machine.
int sweepHere(const Sweep& s, const std::string& out, const SweepOptions& o) {
    std::vector<std::size_t> cases;
    if (o.shard.empty()) {
        cases = shardCases(s.caseCount(), 0, 1);
    } else {
        const auto [i, n] = parseShard(o.shard);
        cases = shardCases(s.caseCount(), i, n);
    }
    const int jobs = o.jobs > 0 ? o.jobs : defaultJobs(s);
    const ProgressStyle style{!o.quiet && (o.progress || ::isatty(2) != 0), o.quiet};
    const CaseTally t = runCases(s, out, cases, jobs, style);
    std::size_t missing = 0;
    if (o.shard.empty()) {
        missing = mergeResults(s, out);
    }
    if (!o.quiet) {
        std::printf("sweep %s%s: %zu cases: %s (%zu run now, %zu from before) in %.1f s\n", s.name.c_str(),
                    o.shard.empty() ? "" : (" shard " + o.shard).c_str(), cases.size(),
                    statusCounts(s, out, cases).c_str(), t.ran, t.skipped, t.wallSeconds);
        if (jobs == 1 && t.ran > 0 && !t.interrupted) {
            std::printf("the sweep's own time beyond its runs: %.1f ms a case\n",
                        1e3 * (t.wallSeconds - t.runSeconds) / double(t.ran));
        }
        if (o.shard.empty()) {
            std::printf("results: %s/results.csv\n", out.c_str());
        }
    }
    if (t.interrupted) {
        std::fprintf(stderr, "tumble sweep: interrupted; the cases that ended are kept: run the same command "
                             "again to run the rest\n");
        return kExitInterrupted;
    }
    return missing ? kExitFailure : kExitOk;
}

/// One mode, and no option of another mode's (it would be silently ignored).
void checkModes(const SweepOptions& o) {
    const int modes = int(o.local) + int(o.slurm) + int(!o.shard.empty()) + int(o.merge) + int(o.status) +
                      int(!o.plot.empty());
    if (modes != 1) {
        throw ScenarioError(
            "sweep", 0, 0,
            std::string(modes ? "give only one of" : "say how to run the sweep:") +
                " --local (on this machine), --slurm (as a Slurm job array), --shard I/N (one "
                "task's share), --merge, --status or --plot METRIC");
    }
    auto refuse = [](bool given, const char* option, const char* mode) {
        if (given) {
            throw ScenarioError("sweep", 0, 0, std::string(option) + " goes with " + mode);
        }
    };
    refuse(!o.by.empty() && o.plot.empty(), "--by AXIS", "--plot METRIC");
    refuse(!o.slurm && (!o.partition.empty() || o.maxParallel > 0 || o.tasks > 0 || o.noWait),
           "--partition, --max-parallel, --tasks and --no-wait", "--slurm");
    refuse(o.jobs > 0 && !o.local && o.shard.empty(), "-j", "--local or --shard");
    refuse(o.threads && (o.merge || o.status || !o.plot.empty()), "--threads", "--local, --slurm or --shard");
}

} // namespace

int commandSweep(const Catalog& catalog, const SweepOptions& o) {
    checkModes(o);
    // runs are waited for by their own pids; a SIGCHLD ignored by whoever started us would reap them first
    std::signal(SIGCHLD, SIG_DFL);
    Sweep s = readSweep(o.file);
    if (o.threads) {
        s.threads = *o.threads;
    }
    const std::string out = fs::absolute(o.out.empty() ? "out/" + s.name : o.out).lexically_normal().string();
    if (o.status) {
        return sweepStatus(s, out);
    }
    if (o.merge) {
        return sweepMerge(s, out);
    }
    // before any case runs: every axis's values as --set takes them, every metric; a shard of a sweep whose
    // folder is made was checked by whoever made it
    const bool checked = !o.shard.empty() && checkManifest(s, out);
    const double budgetMs = checked ? 0.0 : checkSweep(catalog, s);
    if (!o.plot.empty()) {
        checkManifest(s, out);
        const std::string svg = plotSweep(s, out, o.plot, o.by, budgetMs);
        std::printf("%s\n", svg.c_str());
        return kExitOk;
    }
    if (o.slurm) {
        requireSlurm();
        // held while the array is submitted; its tasks hold it as they run (not while they wait in the queue)
        const std::unique_ptr<FileLock> running = writeManifest(s, out);
        return sweepSlurm(s, out, o);
    }
    const FolderLock lock(s, out, !o.shard.empty());
    const std::unique_ptr<FileLock> running = writeManifest(s, out);
    return sweepHere(s, out, o);
}

} // namespace tumble
