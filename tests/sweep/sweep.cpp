// The extreme-parameter sweep (README "Hostile input"): random scenarios that are valid in form, with
// stiffness from 1e-3 to 1e9 N/m, dt from 1e-5 to 0.1 s, masses from 1e-6 to 1e6 kg, scales from 1e-4 to
// 1e4 m and, now and then, thousands of entities, each run by the real `tumble` program. Every run must end
// in one of three ways:
//   ok          exit 0, and the dumped state holds no NaN or infinity (no silent nonsense)
//   error       exit 2 with a message naming the file (a value the schema refuses, a cap, CFL)
//   blow-up     exit 1 with a message naming the entity that blew up
// Anything else (a signal, another exit code, an exit 1 of another kind, a run past the time limit) is a
// failure: the scenario is kept for reproduction and the sweep exits 1.
//
//   tumble_sweep TUMBLE_BINARY WORK_DIR [--count N] [--seed S] [--jobs J] [--frames F] [--timeout SECONDS]
//   tumble_sweep TUMBLE_BINARY WORK_DIR --print SEED     (the scenario of one seed, to reproduce it)

#include "engine/random.h"

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace {

namespace fs = std::filesystem;
using tumble::Rng;

/// Log-uniform in [lo, hi]: every decade as likely as any other.
double logUniform(Rng& rng, double lo, double hi) {
    return std::exp(rng.uniform(std::log(lo), std::log(hi)));
}

std::string num(double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.6g", v); // an integer where a number is read is fine
    return b;
}

std::string vec3(double x, double y, double z) {
    return "[" + num(x) + ", " + num(y) + ", " + num(z) + "]";
}

const char* pick(Rng& rng, const std::vector<const char*>& from) {
    return from[std::min<std::size_t>(from.size() - 1, std::size_t(rng.uniform() * double(from.size())))];
}

int intIn(Rng& rng, int lo, int hi) {
    return std::min(hi, lo + int(rng.uniform() * double(hi - lo + 1)));
}

/// One random scenario; `seed` alone decides it.
std::string scenario(std::uint64_t seed) {
    Rng rng(seed);
    const double scale = logUniform(rng, 1e-4, 1e4);
    const double dt = logUniform(rng, 1e-5, 0.1);
    std::ostringstream s;
    s << "[scene]\nname = \"sweep_" << seed << "\"\ndt = " << num(dt) << "\nsubsteps = " << intIn(rng, 1, 3)
      << "\ngravity = " << vec3(0.0, -logUniform(rng, 1e-3, 100.0), 0.0) << "\nseed = " << seed << "\n";
    s << "[budget]\nphysics_ms = 100.0\n";
    const bool crowd = rng.uniform() < 0.05; // thousands of entities of one cheap kind
    const int entities = crowd ? intIn(rng, 1000, 3000) : intIn(rng, 1, 6);
    const char* crowdKind = pick(rng, {"rope", "sphere", "emitter", "disc"});
    auto position = [&] {
        return vec3(rng.uniform(-1.0, 1.0) * scale, rng.uniform(0.0, 2.0) * scale,
                    rng.uniform(-1.0, 1.0) * scale);
    };
    if (rng.uniform() < 0.5) {
        s << "[[entity]]\nname = \"ground\"\n[entity.rigid_body]\nshape = \"plane\"\n";
    }
    if (rng.uniform() < 0.02) {
        // a long line of bodies by `repeat` (sorted along a line, they once made Bullet's tree degenerate:
        // 30,000 took 13 s to add)
        const double r = scale * logUniform(rng, 1e-3, 0.5);
        const bool twoD = rng.uniform() < 0.3;
        s << "[[entity]]\nname = \"line\"\nrepeat = { count = " << intIn(rng, 1000, 20000)
          << ", offset = " << vec3(r * logUniform(rng, 0.5, 4.0), 0.0, 0.0)
          << " }\n[entity.transform]\nposition = " << vec3(0.0, r * 2.0, 0.0) << "\n"
          << (twoD ? "[entity.rigid_body_2d]\nshape = \"circle\"\n"
                   : "[entity.rigid_body]\nshape = \"sphere\"\n")
          << "radius = " << num(r) << "\nmass = " << num(logUniform(rng, 1e-3, 1e3)) << "\n";
    }
    for (int e = 0; e < entities; ++e) {
        const std::string kind = crowd ? crowdKind
                                       : pick(rng, {"rope", "cloth", "softbody", "emitter", "sphere", "box",
                                                    "disc", "water", "wind"});
        s << "[[entity]]\nname = \"e" << e << "\"\n[entity.transform]\nposition = " << position() << "\n";
        const double k = logUniform(rng, 1e-3, 1e9);
        const double m = logUniform(rng, 1e-6, 1e6);
        const char* integrator =
            pick(rng, {"explicit_euler", "midpoint", "rk4", "symplectic_euler", "implicit_euler"});
        if (kind == "rope") {
            const int n = crowd ? 2 : intIn(rng, 2, 30);
            const double step = scale * logUniform(rng, 1e-3, 1.0);
            s << "[entity.springs]\nintegrator = \"" << integrator << "\"\nstiffness = " << num(k)
              << "\ndamping = " << num(logUniform(rng, 1e-4, 1e3)) << "\nmasses = [";
            for (int i = 0; i < n; ++i) {
                s << (i ? ", " : "") << "{ x = " << vec3(step * i, 0.0, 0.0) << ", m = " << num(m / n)
                  << (i == 0 ? ", pinned = true" : "") << " }";
            }
            s << "]\nlinks = [";
            for (int i = 0; i + 1 < n; ++i) {
                s << (i ? ", " : "") << "{ a = " << i << ", b = " << i + 1 << " }";
            }
            s << "]\n";
        } else if (kind == "cloth") {
            const int rows = intIn(rng, 2, 24), cols = intIn(rng, 2, 24);
            const double size = scale * logUniform(rng, 1e-2, 1.0);
            const bool self = rng.uniform() < 0.3;
            s << "[entity.cloth]\nrows = " << rows << "\ncols = " << cols << "\nsize = [" << num(size) << ", "
              << num(size) << "]\nmass = " << num(m) << "\nstretch = " << num(k)
              << "\nshear = " << num(k * 0.1) << "\nbend = " << num(k * 0.01) << "\nintegrator = \""
              << integrator << "\"\npin = \"" << pick(rng, {"top-corners", "top-row", "none"})
              << "\"\nplane = \"" << pick(rng, {"xy", "xz"}) << "\"\n";
            if (self) {
                s << "self_collision = true\nthickness = " << num(0.5 * size / std::max(rows, cols)) << "\n";
            }
        } else if (kind == "softbody") {
            s << "[entity.softbody]\nsize = " << vec3(scale * 0.5, scale * 0.5, scale * 0.5)
              << "\nresolution = [" << intIn(rng, 2, 6) << ", " << intIn(rng, 2, 6) << ", "
              << intIn(rng, 2, 6) << "]\nmass = " << num(m) << "\nstiffness = " << num(k)
              << "\nintegrator = \"" << integrator << "\"\n";
        } else if (kind == "emitter") {
            s << "[entity.emitter]\nrate = " << num(logUniform(rng, 1.0, 1e5))
              << "\nburst = " << intIn(rng, 0, 2000)
              << "\nmax_particles = " << (crowd ? 50 : intIn(rng, 1, 20000)) << "\nspeed = [0.0, "
              << num(logUniform(rng, 1e-3, 1e4)) << "]\nlifetime = [0.01, "
              << num(logUniform(rng, 0.01, 100.0)) << "]\ndrag = " << num(logUniform(rng, 1e-3, 1e3)) << "\n";
        } else if (kind == "sphere" || kind == "box") {
            const double r = scale * logUniform(rng, 1e-3, 0.5);
            s << "[entity.rigid_body]\nshape = \"" << kind << "\"\n"
              << (kind == "sphere" ? "radius = " + num(r) : "half_extents = " + vec3(r, r * 0.5, r)) << "\n";
            if (rng.uniform() < 0.1) {
                s << "mass = 0.0\n";
            } else {
                s << "mass = " << num(m)
                  << "\nlinear_velocity = " << vec3(0.0, -logUniform(rng, 1e-3, 1e3), 0.0) << "\n";
            }
        } else if (kind == "disc") {
            s << "[entity.rigid_body_2d]\nshape = \"circle\"\nradius = "
              << num(scale * logUniform(rng, 1e-3, 0.5)) << "\nmass = " << num(m) << "\n";
        } else if (kind == "water") {
            s << "[entity.water]\ncells = [" << intIn(rng, 3, 64) << ", " << intIn(rng, 3, 64)
              << "]\nsize = [" << num(scale) << ", " << num(scale)
              << "]\nwave_speed = " << num(logUniform(rng, 1e-3, 1e3)) << "\n";
        } else {
            s << "[entity.force_field]\nkind = \"wind\"\nstrength = "
              << vec3(logUniform(rng, 1e-3, 1e4), 0.0, 0.0) << "\n";
        }
    }
    return s.str();
}

enum class Outcome { Ok, Error, BlowUp, Failure };

struct Run {
    Outcome outcome = Outcome::Failure;
    std::string why; ///< for a failure: what happened
    double seconds = 0.0;
};

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// At least one error line, and every one a named blow-up (a run goes on after one, so any other failure
/// may follow it).
bool onlyBlowUps(const std::string& err) {
    std::istringstream lines(err);
    int blowUps = 0;
    for (std::string line; std::getline(lines, line);) {
        if (line.rfind("tumble: error: ", 0) != 0) {
            continue;
        }
        if (line.find("' blew up at frame ") == std::string::npos) {
            return false;
        }
        ++blowUps;
    }
    return blowUps > 0;
}

/// Runs one scenario through the program, killing it after `timeout` seconds.
Run runOne(const std::string& tumble, const std::string& dir, std::uint64_t seed, int frames,
           double timeout) {
    const std::string file = dir + "/sweep_" + std::to_string(seed) + ".toml";
    std::ofstream(file) << scenario(seed);
    const std::string errFile = dir + "/sweep_" + std::to_string(seed) + ".err";
    const std::string dump = dir + "/sweep_" + std::to_string(seed) + ".jsonl";
    std::vector<std::string> args = {tumble,
                                     "run",
                                     file,
                                     "--no-render",
                                     "--quiet",
                                     "--frames",
                                     std::to_string(frames),
                                     "--out",
                                     dir + "/out_" + std::to_string(seed),
                                     "--dump",
                                     dump};
    std::vector<char*> argv;
    for (std::string& a : args) {
        argv.push_back(a.data());
    }
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, errFile.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    pid_t pid = 0;
    const auto start = std::chrono::steady_clock::now();
    Run run;
    if (posix_spawn(&pid, tumble.c_str(), &actions, nullptr, argv.data(), environ) != 0) {
        posix_spawn_file_actions_destroy(&actions);
        run.why = "could not start " + tumble;
        return run;
    }
    posix_spawn_file_actions_destroy(&actions);
    int status = 0;
    bool timedOut = false;
    for (;;) {
        const pid_t done = waitpid(pid, &status, WNOHANG);
        if (done == pid) {
            break;
        }
        if (done < 0 && errno != EINTR) {
            run.why = std::string("waitpid failed: ") + std::strerror(errno);
            return run;
        }
        run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (run.seconds > timeout) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            timedOut = true;
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string err = slurp(errFile);
    if (timedOut) {
        run.why = "still running after " + num(timeout) + " s (a hang)";
    } else if (WIFSIGNALED(status)) {
        run.why = std::string("killed by signal ") + strsignal(WTERMSIG(status)) + "\n" + err;
    } else if (WEXITSTATUS(status) == 0) {
        const std::string state = slurp(dump);
        if (state.find("NaN") != std::string::npos || state.find("Infinity") != std::string::npos) {
            run.why = "exit 0 with a non-finite number in the dumped state (silent nonsense)";
        } else {
            run.outcome = Outcome::Ok;
        }
    } else if (WEXITSTATUS(status) == 2 && err.rfind("tumble: " + file + ":", 0) == 0) {
        run.outcome = Outcome::Error;
    } else if (WEXITSTATUS(status) == 1 && onlyBlowUps(err)) {
        run.outcome = Outcome::BlowUp;
    } else {
        run.why =
            "exit " + std::to_string(WEXITSTATUS(status)) + ", not a clear error or a named blow-up:\n" + err;
    }
    if (run.outcome != Outcome::Failure) {
        fs::remove(file);
        fs::remove(dump);
        fs::remove_all(dir + "/out_" + std::to_string(seed));
        fs::remove(errFile);
    }
    return run;
}

} // namespace

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: tumble_sweep TUMBLE_BINARY WORK_DIR [--count N] [--seed S] [--jobs J] "
                             "[--frames F] [--timeout SECONDS]\n");
        return 2;
    }
    const std::string tumble = argv[1];
    const std::string dir = argv[2];
    int count = 1000, jobs = 2, frames = 6;
    std::uint64_t seed = 1;
    double timeout = 60.0;
    for (int i = 3; i + 1 < argc; i += 2) {
        const std::string opt = argv[i];
        const std::string value = argv[i + 1];
        if (opt == "--count") {
            count = std::stoi(value);
        } else if (opt == "--seed") {
            seed = std::stoull(value);
        } else if (opt == "--jobs") {
            jobs = std::max(1, std::stoi(value));
        } else if (opt == "--frames") {
            frames = std::stoi(value);
        } else if (opt == "--print") {
            std::fputs(scenario(std::stoull(value)).c_str(), stdout);
            return 0;
        } else if (opt == "--timeout") {
            timeout = std::stod(value);
        } else {
            std::fprintf(stderr, "tumble_sweep: unknown option %s\n", opt.c_str());
            return 2;
        }
    }
    fs::create_directories(dir);
    std::vector<Run> runs(static_cast<std::size_t>(count));
    std::vector<std::thread> workers;
    std::atomic<int> next{0};
    for (int j = 0; j < jobs; ++j) {
        workers.emplace_back([&] {
            for (int i = next++; i < count; i = next++) {
                runs[std::size_t(i)] = runOne(tumble, dir, seed + std::uint64_t(i), frames, timeout);
            }
        });
    }
    for (auto& w : workers) {
        w.join();
    }
    std::map<Outcome, int> tally;
    double slowest = 0.0;
    std::uint64_t slowestSeed = 0;
    for (int i = 0; i < count; ++i) {
        const Run& r = runs[std::size_t(i)];
        ++tally[r.outcome];
        if (r.seconds > slowest) {
            slowest = r.seconds;
            slowestSeed = seed + std::uint64_t(i);
        }
        if (r.outcome == Outcome::Failure) {
            std::printf("FAILED %s/sweep_%llu.toml: %s\n", dir.c_str(),
                        static_cast<unsigned long long>(seed + i), r.why.c_str());
        }
    }
    std::printf("%d scenarios: %d ok, %d clear errors, %d caught blow-ups, %d failures (crash, hang or "
                "unclassified); slowest %.2f s (seed %llu)\n",
                count, tally[Outcome::Ok], tally[Outcome::Error], tally[Outcome::BlowUp],
                tally[Outcome::Failure], slowest, static_cast<unsigned long long>(slowestSeed));
    // a sweep whose scenarios were nearly all refused would pass while testing nothing
    if (tally[Outcome::Ok] + tally[Outcome::BlowUp] < count / 2) {
        std::printf("FAILED: fewer than half of the scenarios ran (a schema change refuses what the sweep "
                    "writes?)\n");
        return 1;
    }
    return tally[Outcome::Failure] == 0 ? 0 : 1;
}
