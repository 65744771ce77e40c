// A sweep as a Slurm job array (app/sweep.h): one sbatch script whose task i runs `tumble sweep FILE
// --shard i/n`, submitted, waited for (squeue), its failed tasks submitted once more, then merged. Slurm is
// the scheduler; this only asks it. The output folder must be on storage every node sees (README "Sweeps").

#include "app/cli.h"
#include "app/subprocess.h"
#include "app/sweep.h"
#include "engine/table_reader.h"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <thread>
#include <unistd.h>

namespace tumble {

namespace fs = std::filesystem;

namespace {

/// Slurm's default MaxArraySize is 1001: indices 0 to 1000.
constexpr std::size_t kMaxTasks = 1000;

volatile std::sig_atomic_t g_stopWaiting = 0;

void onStopWaiting(int) {
    g_stopWaiting = 1;
}

/// The array task's script: only the command. Everything Slurm reads is given on sbatch's command line
/// (submitCommand), where a path with spaces or quotes stays one argument.
std::string slurmScript(const Sweep& s, const std::string& out, std::size_t tasks) {
    return "#!/bin/sh\n# written by `tumble sweep --slurm` (sbatch's options are on its command line: " +
           out + "/slurm/submit.txt): task i of the array runs shard i of " + std::to_string(tasks) +
           ", the cases whose index is i modulo " + std::to_string(tasks) + "\nexec " +
           shellQuote(selfExecutable()) + " sweep " + shellQuote(s.file) + " --out " + shellQuote(out) +
           " --shard \"${SLURM_ARRAY_TASK_ID}/" + std::to_string(tasks) + "\" -j 1 --threads " +
           std::to_string(s.threads) + " --quiet\n";
}

/// sbatch's arguments for the array (or the listed tasks of it).
std::vector<std::string> submitCommand(const Sweep& s, const std::string& out, const SweepOptions& o,
                                       const std::string& indices) {
    // Slurm expands %-patterns in --output: a % of the folder's own is doubled
    std::string folder;
    for (char c : out) {
        folder += c == '%' ? std::string("%%") : std::string(1, c);
    }
    std::vector<std::string> argv = {"sbatch",
                                     "--parsable",
                                     "--job-name=tumble-" + s.name,
                                     "--array=" + indices +
                                         (o.maxParallel > 0 ? "%" + std::to_string(o.maxParallel) : ""),
                                     "--ntasks=1",
                                     "--cpus-per-task=" + std::to_string(s.threads),
                                     "--output=" + folder + "/slurm/task_%A_%a.log"};
    if (!o.partition.empty()) {
        argv.push_back("--partition=" + o.partition);
    }
    argv.push_back(out + "/slurm/sweep.sbatch");
    return argv;
}

/// Submits; returns the job id (sbatch --parsable prints "ID" or "ID;CLUSTER" as a line of its stdout,
/// whatever a site's plugins print besides).
std::string submit(const std::vector<std::string>& argv) {
    const Captured c = runCaptured(argv);
    std::string id;
    std::size_t start = 0;
    while (start < c.out.size()) {
        const std::size_t end = std::min(c.out.find('\n', start), c.out.size());
        const std::string line = c.out.substr(start, end - start);
        const std::string first = line.substr(0, line.find(';'));
        if (!first.empty() && first.find_first_not_of("0123456789") == std::string::npos) {
            id = first;
        }
        start = end + 1;
    }
    if (c.exitCode != 0 || id.empty()) {
        throw std::runtime_error("sbatch did not take the sweep's array (exit " + std::to_string(c.exitCode) +
                                 "): " + c.err + c.out);
    }
    return id;
}

/// Cases with a result file, by its presence alone (the progress line of a sweep of a million cases on a
/// shared file system polls this every second).
std::size_t casesDone(const Sweep& s, const std::string& out) {
    std::size_t done = 0;
    std::error_code ec;
    for (std::size_t c = 0; c < s.caseCount(); ++c) {
        done += fs::exists(caseFolder(out, c) + "/result.json", ec) ? 1 : 0;
    }
    return done;
}

/// Waits until squeue no longer lists the job (once it has aged out squeue calls its id invalid). False
/// when Ctrl-C stopped the waiting (the job goes on).
bool waitForJob(const Sweep& s, const std::string& out, const std::string& job, bool bar) {
    g_stopWaiting = 0;
    struct sigaction sa {
    }, old{};
    sa.sa_handler = onStopWaiting;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGINT, &sa, &old);
    auto lastAnswer = std::chrono::steady_clock::now();
    bool finished = false;
    while (!g_stopWaiting && !finished) {
        const Captured q = runCaptured({"squeue", "-h", "-j", job, "-o", "%i"});
        if (q.exitCode == 0) {
            finished = q.out.find_first_not_of(" \n") == std::string::npos;
            lastAnswer = std::chrono::steady_clock::now();
        } else if (q.err.find("nvalid job id") != std::string::npos) {
            finished = true;
        } else if (std::chrono::steady_clock::now() - lastAnswer > std::chrono::minutes(5)) {
            ::sigaction(SIGINT, &old, nullptr);
            throw std::runtime_error("squeue has failed for 5 minutes (job " + job +
                                     " may still run): " + q.err);
        }
        if (bar) {
            std::fprintf(stderr, "\r\033[Ksweep %s: job %s: %zu/%zu cases done", s.name.c_str(), job.c_str(),
                         casesDone(s, out), s.caseCount());
        }
        for (int i = 0; i < 10 && !finished && !g_stopWaiting; ++i) {
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
        }
    }
    ::sigaction(SIGINT, &old, nullptr);
    if (bar) {
        std::fputc('\n', stderr);
    }
    return !g_stopWaiting;
}

/// The tasks whose shard still has cases without a result, as sbatch's --array list ("1,3").
std::string unfinishedTasks(const Sweep& s, const std::string& out, std::size_t tasks) {
    std::set<std::size_t> left;
    for (std::size_t c = 0; c < s.caseCount(); ++c) {
        if (!readCaseResult(out, c, s)) {
            left.insert(c % tasks);
        }
    }
    std::string list;
    for (std::size_t t : left) {
        list += (list.empty() ? "" : ",") + std::to_string(t);
    }
    return list;
}

void noteJob(const std::string& out, const std::string& job, std::size_t tasks) {
    writeSweepFile(out + "/slurm/tasks", std::to_string(tasks) + "\n");
    writeSweepFile(out + "/slurm/job", job + "\n");
}

} // namespace

void requireSlurm() {
    for (const char* program : {"sbatch", "squeue"}) {
        if (findOnPath(program).empty()) {
            throw ScenarioError("tumble sweep --slurm", 0, 0,
                                std::string("Slurm's `") + program +
                                    "` is not on this machine's PATH (no Slurm client here: install Debian's "
                                    "slurm-client and point SLURM_CONF at the cluster, or run with --local)");
        }
    }
}

int sweepSlurm(const Sweep& s, const std::string& out, const SweepOptions& o) {
    const std::size_t tasks = std::min<std::size_t>(o.tasks > 0 ? std::size_t(o.tasks) : kMaxTasks,
                                                    std::min(s.caseCount(), kMaxTasks));
    fs::create_directories(out + "/slurm");
    const std::string script = out + "/slurm/sweep.sbatch";
    writeSweepFile(script, slurmScript(s, out, tasks));
    const std::vector<std::string> command = submitCommand(s, out, o, "0-" + std::to_string(tasks - 1));
    std::string text;
    for (const std::string& a : command) {
        text += (text.empty() ? "" : " ") + shellQuote(a);
    }
    writeSweepFile(out + "/slurm/submit.txt", text + "\n");
    const std::string job = submit(command);
    noteJob(out, job, tasks);
    std::printf("sweep %s: submitted job %s, an array of %zu tasks over %zu cases (%s)\n", s.name.c_str(),
                job.c_str(), tasks, s.caseCount(), script.c_str());
    if (o.noWait) {
        std::printf("`tumble sweep %s --out %s --status` shows its progress; --merge writes the table\n",
                    s.file.c_str(), out.c_str());
        return kExitOk;
    }
    const bool bar = !o.quiet && (o.progress || ::isatty(2) != 0);
    if (!waitForJob(s, out, job, bar)) {
        std::fprintf(stderr,
                     "tumble sweep: stopped waiting; job %s goes on (scancel %s stops it; --status, "
                     "--merge)\n",
                     job.c_str(), job.c_str());
        return kExitInterrupted;
    }
    // a task that failed (a node lost, a time limit) runs once more: its shard skips the cases it finished
    if (const std::string again = unfinishedTasks(s, out, tasks); !again.empty()) {
        const std::string retry = submit(submitCommand(s, out, o, again));
        std::printf("sweep %s: tasks %s left cases undone; submitted them again as job %s\n", s.name.c_str(),
                    again.c_str(), retry.c_str());
        noteJob(out, retry, tasks);
        if (!waitForJob(s, out, retry, bar)) {
            return kExitInterrupted;
        }
    }
    const std::size_t missing = mergeResults(s, out);
    std::printf("results: %s/results.csv (%zu of %zu cases)\n", out.c_str(), s.caseCount() - missing,
                s.caseCount());
    if (missing) {
        std::fprintf(stderr, "tumble sweep: tasks %s failed twice; their logs are %s/slurm/task_*.log\n",
                     unfinishedTasks(s, out, tasks).c_str(), out.c_str());
        return kExitFailure;
    }
    return kExitOk;
}

} // namespace tumble
