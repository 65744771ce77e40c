#pragma once
// Child processes for `tumble sweep`: a case's runs (their output into a log file, each dying with the
// sweep that started it, so a killed sweep leaves no run writing into a case it will start again) and the
// Slurm commands (their output captured).

#include <string>
#include <sys/types.h>
#include <vector>

namespace tumble {

/// Starts argv[0] (a path) with stdout and stderr into `logPath` (created or truncated) and stdin from
/// /dev/null; the child is killed when this process dies. Throws std::runtime_error if it cannot start.
pid_t spawnLogged(const std::vector<std::string>& argv, const std::string& logPath);

/// What a finished command printed, and how it ended.
struct Captured {
    int exitCode = 0; ///< exit status, or 128 + N for signal N, or 127 when it could not start
    std::string out;  ///< its stdout
    std::string err;  ///< its stderr
};

/// Runs argv[0] (looked up on PATH) to its end and captures its stdout and stderr apart.
Captured runCaptured(const std::vector<std::string>& argv);

/// The exit code of a waitpid status: the exit status, or 128 + N for a death by signal N.
int exitCodeOf(int waitStatus);

/// The program's path on $PATH, or "" when it is not there.
std::string findOnPath(const std::string& program);

/// One word for a POSIX shell: quoted when it needs to be.
std::string shellQuote(const std::string& word);

} // namespace tumble
