#include "app/cli.h"

#include "app/progress.h"
#include "app/run_session.h"
#include "app/sweep.h"
#include "engine/assets.h"
#include "engine/replay.h"
#include "engine/simulation.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <tuple>

namespace tumble {

namespace fs = std::filesystem;

namespace {

int commandList() {
    const std::string dir = demoDirectory();
    std::vector<fs::path> files;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
        if (entry.path().extension() == ".toml") {
            files.push_back(entry.path());
        }
    }
    if (ec) {
        std::cerr << "tumble: cannot read the demo folder " << dir << ": " << ec.message() << "\n";
        return kExitFailure;
    }
    std::sort(files.begin(), files.end());
    for (const fs::path& f : files) {
        std::string line;
        try {
            const SceneDef scene = peekScene(f.string(), readScenarioFile(f.string()));
            line = scene.description;
        } catch (const ScenarioError& e) {
            line = std::string("(does not load: ") + e.what() + ")";
        }
        std::printf("%-14s %s\n", f.stem().string().c_str(), line.c_str());
    }
    return kExitOk;
}

int commandCheck(const Catalog& catalog, const RunOptions& o) {
    const std::string path = resolveScenario(o.scenario);
    Simulation sim(catalog, path, readScenarioFile(path), o.sets, std::uint64_t(o.memoryCapMiB) << 20, 1);
    return kExitOk;
}

int commandRun(const Catalog& catalog, const RunOptions& o) {
    if (o.realtime && (!o.record.empty() || o.snapshotAt || !o.from.empty())) {
        // paced by the clock, a run drops time and takes a varying number of steps a frame: nothing it
        // records could be re-simulated frame for frame
        throw ScenarioError("--realtime", 0, 0,
                            "--realtime cannot go with --record, --snapshot-at or --from: a run paced by the "
                            "clock drops time, so it cannot be played back frame for frame");
    }
    Source src;
    src.memoryCap = std::uint64_t(o.memoryCapMiB) << 20;
    src.threads = threadsFor(o);
    if (!o.from.empty()) {
        if (!o.scenario.empty()) {
            throw ScenarioError(o.from, 0, 0,
                                "--from resumes the snapshot's own scenario: give no scenario with it");
        }
        auto snapshot = std::make_shared<const ReplayFile>(readReplay(o.from));
        src.path = snapshot->header.scenarioPath;
        src.text = snapshot->header.scenarioText;
        src.sets = snapshot->header.overrides;
        if (!o.sets.empty()) {
            throw ScenarioError(o.from, 0, 0, "--set cannot change a snapshot's scenario");
        }
        if (snapshot->frames.empty()) {
            throw ReplayError(o.from, snapshot->validBytes, "holds no whole frame to resume from");
        }
        // Bullet's and Box2D's contact caches and sleep timers are not theirs to give away, so a snapshot
        // resumes by simulating its frames again (checked against its hashes), not by loading state
        src.replay = snapshot;
        src.resume = snapshot->frames.size();
        src.replayPath = o.from;
        return runSession(catalog, o, src);
    }
    if (o.scenario.empty()) {
        throw ScenarioError("tumble run", 0, 0,
                            "give a scenario (a .toml file or a demo name) or --from SNAPSHOT");
    }
    src.path = resolveScenario(o.scenario);
    src.text = readScenarioFile(src.path);
    src.sets = o.sets;
    return runSession(catalog, o, src);
}

int commandReplay(const Catalog& catalog, const RunOptions& o) {
    Source src = replaySource(o.scenario, o.verify, threadsFor(o));
    src.memoryCap = std::uint64_t(o.memoryCapMiB) << 20;
    const ReplayFile& replay = *src.replay;
    if (!replay.complete) {
        std::fprintf(stderr,
                     "tumble: note: %s is cut short at byte %llu of %llu (a recording that was stopped); "
                     "replaying its %zu whole frames\n",
                     o.scenario.c_str(), static_cast<unsigned long long>(replay.validBytes),
                     static_cast<unsigned long long>(replay.fileBytes), replay.frames.size());
    }
    if (replay.header.buildId != buildId()) {
        std::fprintf(stderr, "tumble: note: recorded by build %s, replayed by build %s\n",
                     replay.header.buildId.c_str(), buildId());
    }
    const int code = runSession(catalog, o, src);
    if (!replay.complete && (code == kExitOk || code == kExitFailure)) {
        // played as far as it goes, but a file cut short is bad input (CONTRACT.md, "Replays"): a script must
        // not take a replay that stopped at frame 8 of 40 for a whole one
        std::fprintf(stderr, "tumble: %s: at byte %llu: the file ends there, cut short (exit 2)\n",
                     o.scenario.c_str(), static_cast<unsigned long long>(replay.validBytes));
        return kExitBadInput;
    }
    return code;
}

/// An SVG chart of physics time per frame, with the budget (and the budget times the scale) as lines.
std::string budgetChart(const std::vector<float>& ms, double budget, double scale, const std::string& title) {
    const double width = 800.0, height = 320.0, left = 60.0, right = 20.0, top = 30.0, bottom = 40.0;
    double highest = budget * std::max(scale, 1.0) * 1.2;
    for (float v : ms) {
        highest = std::max(highest, double(v) * 1.05);
    }
    auto x = [&](std::size_t i) {
        return left + (width - left - right) * (ms.size() > 1 ? double(i) / double(ms.size() - 1) : 0.0);
    };
    auto y = [&](double v) { return top + (height - top - bottom) * (1.0 - v / highest); };
    char buf[256];
    std::string svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"800\" height=\"320\" "
                      "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"800\" height=\"320\" "
                      "fill=\"white\"/>\n";
    std::snprintf(buf, sizeof buf, "<text x=\"%g\" y=\"18\">%s: physics ms per frame</text>\n", left,
                  title.c_str());
    svg += buf;
    // axes and a few labelled ticks
    std::snprintf(buf, sizeof buf, "<path d=\"M%g %g V%g H%g\" stroke=\"black\" fill=\"none\"/>\n", left, top,
                  height - bottom, width - right);
    svg += buf;
    for (int k = 0; k <= 4; ++k) {
        const double v = highest * k / 4.0;
        std::snprintf(buf, sizeof buf, "<text x=\"%g\" y=\"%g\" text-anchor=\"end\">%.2f</text>\n", left - 6,
                      y(v) + 4, v);
        svg += buf;
    }
    std::snprintf(buf, sizeof buf, "<text x=\"%g\" y=\"%g\" text-anchor=\"middle\">frame (%zu)</text>\n",
                  (left + width - right) / 2, height - 10, ms.size());
    svg += buf;
    for (const auto& [v, colour, label] :
         {std::tuple{budget, "#c0392b", "budget"}, std::tuple{budget * scale, "#e67e22", "budget x scale"}}) {
        if (label == std::string("budget x scale") && scale == 1.0) {
            continue;
        }
        std::snprintf(buf, sizeof buf,
                      "<path d=\"M%g %g H%g\" stroke=\"%s\" stroke-dasharray=\"6 4\"/>\n<text x=\"%g\" "
                      "y=\"%g\" fill=\"%s\" text-anchor=\"end\">%s %.2f ms</text>\n",
                      left, y(v), width - right, colour, width - right, y(v) - 4, colour, label, v);
        svg += buf;
    }
    svg += "<polyline fill=\"none\" stroke=\"#2c6fbb\" stroke-width=\"1\" points=\"";
    for (std::size_t i = 0; i < ms.size(); ++i) {
        std::snprintf(buf, sizeof buf, "%.1f,%.1f ", x(i), y(double(ms[i])));
        svg += buf;
    }
    svg += "\"/>\n</svg>\n";
    return svg;
}

/// `tumble budget`: runs a scenario without rendering and holds its physics p99 to its budget.
int commandBudget(const Catalog& catalog, const RunOptions& o) {
    const std::string path = resolveScenario(o.scenario);
    Simulation sim(catalog, path, readScenarioFile(path), o.sets, std::uint64_t(o.memoryCapMiB) << 20,
                   threadsFor(o));
    const SceneDef& scene = sim.scene();
    const double budget = o.physicsMs.value_or(scene.physicsBudgetMs);
    double scale = 1.0;
    if (o.scale) {
        scale = *o.scale;
    } else if (const char* env = std::getenv("TUMBLE_BUDGET_SCALE"); env && *env) {
        char* end = nullptr;
        scale = std::strtod(env, &end);
        if (end == env || *end != '\0' || !(scale >= 1e-6 && scale <= 1e6)) {
            throw ScenarioError("TUMBLE_BUDGET_SCALE", 0, 0,
                                std::string("'") + env + "' is not a number from 1e-6 to 1e6 (as --scale)");
        }
    }
    sim.profiler().setPhysicsBudgetMs(budget);
    const std::uint64_t frames = static_cast<std::uint64_t>(o.frames.value_or(scene.frames));
    std::optional<OutputFile> chart;
    if (!o.chart.empty()) {
        chart.emplace(o.chart);
    }
    ProgressBar bar(frames, scene.frameSeconds(),
                    !o.quiet && (o.progress || ProgressBar::stderrIsTerminal()));
    while (sim.frame() < frames) {
        sim.runFrame();
        sim.takeAppliedEvents();
        bar.update(sim.frame());
    }
    bar.finish(sim.frame());
    const FrameStats f = sim.profiler().frameStats();
    const double limit = budget * scale;
    const bool over = f.physicsP99Ms > limit;
    std::printf(
        "budget of '%s': %llu frames without rendering on %d thread%s, physics budget %.3f ms a frame",
        scene.name.c_str(), static_cast<unsigned long long>(sim.frame()), sim.threads(),
        sim.threads() == 1 ? "" : "s", budget);
    if (scale != 1.0) {
        std::printf(" (x %.3g scale: %.3f ms)", scale, limit);
    }
    if (scene.stress) {
        std::printf("; a stress scene, beyond the 8 ms every other scene keeps to");
    }
    std::printf("\n\n%-18s %-6s %9s %9s %9s   (a step each; %d step%s a frame)\n", "system", "phase",
                "p50 ms", "p99 ms", "max ms", scene.substeps, scene.substeps == 1 ? "" : "s");
    for (const SlotStats& st : sim.profiler().slotStats()) {
        if (st.isPhase || st.phase != Phase::Fixed || st.calls == 0) {
            continue;
        }
        // a stage of a system under it, indented: "  solve" under "springs"
        const std::string label = st.stageOf.empty() ? st.name : "  " + st.name.substr(st.stageOf.size() + 1);
        std::printf("%-18s %-6s %9.3f %9.3f %9.3f\n", label.c_str(), std::string(phaseName(st.phase)).c_str(),
                    st.p50Ms, st.p99Ms, st.maxMs);
    }
    std::printf("%-18s %-6s %9.3f %9.3f %9.3f   %s\n", "physics a frame", "", f.physicsP50Ms, f.physicsP99Ms,
                f.physicsMaxMs, over ? "OVER BUDGET" : "within budget");
    // the systems' longest chain of waits: a frame's physics on a thread for every system
    std::printf("%-18s %-6s %9.3f %9.3f %9s   (the longest chain of systems waiting on each other)\n",
                "critical path", "", f.criticalP50Ms, f.criticalP99Ms, "");
    std::printf("frames over the budget: %llu of %llu\n", static_cast<unsigned long long>(f.overBudgetFrames),
                static_cast<unsigned long long>(sim.frame()));
    if (chart) {
        chart->write(budgetChart(sim.profiler().physicsHistory(), budget, scale, scene.name));
        chart->close();
        std::printf("wrote %s\n", chart->path().c_str());
    }
    if (over) {
        std::fprintf(stderr, "tumble: '%s' is over its physics budget: p99 %.3f ms a frame > %.3f ms\n",
                     scene.name.c_str(), f.physicsP99Ms, limit);
        return kExitOverBudget;
    }
    return kExitOk;
}

/// A whole number in [lo, hi], said so when it is not one: CLI11's Range called "abc" and "2.5" "not in
/// range 0 to 1000000000", which sends a user looking for a range the value was never in. Decimal, with
/// an optional '+' and spaces around, and given to CLI11 rewritten as plain digits (CLI11 reads integers
/// with strtoll in base 0, so "010" would be stored as 8 and "0x10" as 16): use it with ->transform().
CLI::Validator wholeNumberIn(std::int64_t lo, std::int64_t hi) {
    const std::string range = "from " + std::to_string(lo) + " to " + std::to_string(hi);
    return CLI::Validator(
        [lo, hi, range](std::string& text) {
            std::string_view digits = text;
            while (!digits.empty() && (digits.front() == ' ' || digits.front() == '\t')) {
                digits.remove_prefix(1);
            }
            while (!digits.empty() && (digits.back() == ' ' || digits.back() == '\t')) {
                digits.remove_suffix(1);
            }
            if (!digits.empty() && digits.front() == '+') {
                digits.remove_prefix(1);
            }
            std::int64_t v = 0;
            const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
            if (digits.empty() || end != digits.data() + digits.size() ||
                (error != std::errc{} && error != std::errc::result_out_of_range)) {
                return "'" + text + "' is not a whole number (" + range + ")";
            }
            if (error == std::errc::result_out_of_range || v < lo || v > hi) {
                return "'" + text + "' is out of range: " + range;
            }
            text = std::to_string(v);
            return std::string();
        },
        "in [" + std::to_string(lo) + " - " + std::to_string(hi) + "]", "a whole number");
}

void addMemoryCapOption(CLI::App* cmd, RunOptions& o) {
    cmd->add_option("--memory-cap", o.memoryCapMiB,
                    "Refuse, at load, a scene whose components would need more memory than this, in MiB "
                    "(default 4096)")
        ->transform(wholeNumberIn(1, std::int64_t(1) << 24))
        ->type_name("MIB");
}

/// A path option given as "" would mean its default without a word: refused.
const CLI::Validator nonEmpty(
    [](const std::string& value) { return value.empty() ? std::string("must not be empty") : std::string(); },
    "", "not empty");

/// A number in [lo, hi]: CLI11's Range lets NaN through (no comparison with it fails), and a budget of NaN
/// passed every frame.
CLI::Validator numberIn(double lo, double hi) {
    return CLI::Validator(
        [lo, hi](const std::string& text) {
            char* end = nullptr;
            const double v = std::strtod(text.c_str(), &end);
            if (text.empty() || end != text.c_str() + text.size() || !(v >= lo && v <= hi)) {
                char message[120];
                std::snprintf(message, sizeof message, "'%s' is not a number from %g to %g", text.c_str(), lo,
                              hi);
                return std::string(message);
            }
            return std::string();
        },
        "", "a number");
}

void addThreadsOption(CLI::App* cmd, RunOptions& o) {
    cmd->add_option("--threads", o.threads,
                    "Threads the physics runs on (default: $TUMBLE_THREADS, else every hardware thread); any "
                    "number gives the same bits")
        ->transform(wholeNumberIn(1, kMaxThreads))
        ->type_name("N");
}

void addScenarioOptions(CLI::App* cmd, RunOptions& o) {
    cmd->add_option("scenario", o.scenario, "A scenario file (.toml) or a demo name (see `tumble list`)")
        ->required();
    cmd->add_option("--set", o.sets,
                    "Override a scenario value, e.g. --set scene.dt=0.005 or --set bob.springs.stiffness=50 "
                    "(repeatable)")
        ->allow_extra_args(false)
        ->type_name("KEY=VALUE");
    addMemoryCapOption(cmd, o);
}

/// The options `run` and `replay` share, then those of `run` alone.
void addRunOptions(CLI::App* run, CLI::App* replay, RunOptions& o) {
    for (CLI::App* cmd : {run, replay}) {
        addMemoryCapOption(cmd, o);
        addThreadsOption(cmd, o);
        cmd->add_option("--frames", o.frames,
                        "How many frames to run (default: the scene's frames; a replay's own)")
            ->transform(wholeNumberIn(0, 1'000'000'000));
        cmd->add_option("--out", o.out, "Where outputs go (default out/<scene name>/)")->check(nonEmpty);
        cmd->add_flag("--no-render", o.noRender, "Simulate only; no EGL context is created");
        cmd->add_option("--video", o.video,
                        "Encode the rendered frames to FILE (.mp4 or .gif) through ffmpeg")
            ->type_name("FILE");
        cmd->add_option(
               "--png-every", o.pngEvery,
               "Write frame_NNNNN.png into the output folder every K frames (0: the last frame only, the "
               "default)")
            ->transform(wholeNumberIn(0, 1'000'000'000))
            ->type_name("K");
        cmd->add_option("--profile", o.profile,
                        "Write the budget summary as JSON to FILE (default <out>/profile.json)")
            ->type_name("FILE");
        cmd->add_option("--trace", o.trace,
                        "Write a Chrome trace-event JSON of every system's timing to FILE")
            ->type_name("FILE");
        CLI::Option* dumpOption =
            cmd->add_option("--dump", o.dump, "Write the simulation state as JSON Lines to FILE")
                ->type_name("FILE");
        cmd->add_option("--dump-every", o.dumpEvery,
                        "Dump every K frames, starting with the initial state (default: the last frame only)")
            ->transform(wholeNumberIn(1, 1'000'000'000))
            ->type_name("K")
            ->needs(dumpOption);
        cmd->add_option("--record", o.record,
                        "Write a replay to FILE: the scenario, every input and every frame's state hash")
            ->type_name("FILE");
        CLI::Option* quiet = cmd->add_flag("--quiet", o.quiet, "No progress bar and no summary");
        cmd->add_flag("--progress", o.progress, "Show the progress bar even when stderr is not a terminal")
            ->excludes(quiet); // the two together would leave one of them silently unheeded
        cmd->add_flag(
            "--check-contact", o.checkContact,
            "After every step, test every pair of a self-colliding cloth's triangles that share no "
            "corner for an exact crossing; the first is reported like a blow-up and the run exits 1");
    }
    run->add_flag(
        "--realtime", o.realtime,
        "Pace to the wall clock at the scene's frame rate; when physics runs over its frame, at most "
        "`substeps` steps are taken and the rest of the time is dropped (and counted)");
    run->add_option("--input", o.input,
                    "Timed actions to apply, as JSON Lines: {\"frame\": 120, \"entity\": \"crate\", "
                    "\"action\": \"impulse\", \"value\": [0, 5, 0]} (or \"t\": seconds); recorded like "
                    "the scenario's events")
        ->type_name("FILE");
    run->add_option(
           "--snapshot-at", o.snapshotAt,
           "After frame N write <out>/snapshot_N.tumble (resume it with --from) and snapshot_N.jsonl "
           "(the whole state)")
        ->transform(wholeNumberIn(1, 1'000'000'000))
        ->type_name("N");
    run->add_option("--from", o.from,
                    "Resume from a snapshot: its frames are simulated again, checked against it, and the run "
                    "goes on from there")
        ->type_name("SNAPSHOT");
}

void addBudgetVerb(CLI::App& app, RunOptions& o) {
    CLI::App* budgetCmd = app.add_subcommand(
        "budget",
        "Run a scenario without rendering and hold its physics p99 to its budget (exit 3 when over)");
    addScenarioOptions(budgetCmd, o);
    addThreadsOption(budgetCmd, o);
    budgetCmd->add_option("--frames", o.frames, "How many frames to run (default: the scene's frames)")
        ->transform(wholeNumberIn(1, 1'000'000'000));
    budgetCmd
        ->add_option("--physics-ms", o.physicsMs,
                     "The budget, ms of physics a frame (default: [budget] physics_ms)")
        ->check(numberIn(1e-6, 1e6));
    budgetCmd
        ->add_option("--scale", o.scale,
                     "Room for a slower machine: fail only above budget x S (default: $TUMBLE_BUDGET_SCALE, "
                     "else 1)")
        ->check(numberIn(1e-6, 1e6));
    budgetCmd
        ->add_option("--chart", o.chart, "Write an SVG chart of physics time per frame with the budget line")
        ->type_name("FILE");
    CLI::Option* quiet = budgetCmd->add_flag("--quiet", o.quiet, "No progress bar");
    budgetCmd->add_flag("--progress", o.progress, "Show the progress bar even when stderr is not a terminal")
        ->excludes(quiet);
}

void addViewVerb(CLI::App& app, RunOptions& o) {
    CLI::App* viewCmd = app.add_subcommand(
        "view",
        "Open a window on a scenario, live: drag things with the mouse, watch the budget (needs a display)");
    addScenarioOptions(viewCmd, o);
    addThreadsOption(viewCmd, o);
    viewCmd
        ->add_option("--record", o.record,
                     "Write a replay of the session to FILE (after R, the next one to FILE-2, ...); "
                     "`tumble replay FILE --verify` plays it back headlessly")
        ->type_name("FILE");
    viewCmd
        ->add_option("--profile", o.profile,
                     "Write the budget summary as JSON to FILE when the window closes")
        ->type_name("FILE");
    viewCmd->add_flag("--paused", o.paused, "Start paused (Space runs, N steps once)");
    viewCmd->footer(
        "Mouse: left-drag a thing to pull it on a spring, left-drag empty space to orbit, right- or "
        "middle-drag to pan, wheel to zoom.\nKeys: Space pause, N one step, R reset, S slow motion "
        "(x1/4), W wireframe, I next integrator of the held (or first) spring network, Q or Esc quit.");
}

void addSweepVerb(CLI::App& app, SweepOptions& o) {
    CLI::App* cmd = app.add_subcommand(
        "sweep", "Run a parameter sweep (a sweep file: a scenario, axes over --set keys, metrics) on this "
                 "machine or as a Slurm job array; results in OUT/results.csv");
    cmd->add_option("file", o.file, "The sweep file (.toml; README \"Sweeps\")")
        ->required()
        ->type_name("FILE");
    cmd->add_option("--out", o.out,
                    "The sweep's folder (default out/<sweep file name>/); for --slurm, on "
                    "storage every node sees")
        ->check(nonEmpty);
    cmd->add_flag("--local", o.local,
                  "Run the cases here, -j at a time; a sweep started again skips the "
                  "cases that ended");
    cmd->add_option("-j,--jobs", o.jobs,
                    "Cases at a time with --local or --shard (default: cores / threads "
                    "per case)")
        ->transform(wholeNumberIn(1, 1024))
        ->type_name("N");
    cmd->add_flag("--slurm", o.slurm,
                  "Submit the cases as a Slurm job array (sbatch), wait, run failed tasks "
                  "once more, merge");
    cmd->add_option("--partition", o.partition, "Slurm partition (default: the cluster's)")->type_name("P");
    cmd->add_option("--max-parallel", o.maxParallel, "At most K array tasks at once (Slurm's %K)")
        ->transform(wholeNumberIn(1, 1000000))
        ->type_name("K");
    cmd->add_option("--tasks", o.tasks,
                    "Array tasks (default: one per case, at most 1000); task i runs the "
                    "cases whose index is i modulo N")
        ->transform(wholeNumberIn(1, 1000))
        ->type_name("N");
    cmd->add_flag("--no-wait", o.noWait, "With --slurm: submit and return (then --status, --merge)");
    cmd->add_option("--shard", o.shard, "Run shard I of N here (what each Slurm task runs)")
        ->type_name("I/N");
    cmd->add_flag("--merge", o.merge, "Write OUT/results.csv from the cases that have ended");
    cmd->add_flag("--status", o.status,
                  "Say how many cases have ended, by status, and which tasks have "
                  "cases left");
    cmd->add_option("--plot", o.plot,
                    "Write OUT/plot_METRIC_by_AXIS.svg: a metric (physics_p99_ms, a "
                    "[[metric]]'s name, ...) against an axis")
        ->type_name("METRIC");
    cmd->add_option("--by", o.by, "The axis --plot draws along (default: the first)")->type_name("AXIS");
    cmd->add_option("--threads", o.threads,
                    "Threads each case's runs use (default: the file's threads); any "
                    "number gives the same bits")
        ->transform(wholeNumberIn(1, kMaxThreads))
        ->type_name("N");
    CLI::Option* quiet =
        cmd->add_flag("--quiet", o.quiet, "No progress, no summary, no line per failing case");
    cmd->add_flag("--progress", o.progress, "Show the progress line even when stderr is not a terminal")
        ->excludes(quiet);
}

/// An unknown verb is named, rather than CLI11's "a subcommand is required".
bool knownVerb(int argc, char** argv, CLI::App& app) {
    if (argc >= 2 && argv[1][0] != '-') {
        const std::string verb = argv[1];
        const auto verbs = app.get_subcommands([](CLI::App*) { return true; });
        if (std::none_of(verbs.begin(), verbs.end(), [&](CLI::App* v) { return v->get_name() == verb; })) {
            std::cerr << "tumble: unknown verb '" << verb
                      << "'; the verbs are list, check, run, replay, budget, view and sweep\n"
                      << "Run `tumble --help` for usage.\n";
            return false;
        }
    }
    return true;
}

int commandView(const Catalog& catalog, const RunOptions& o, const ViewerFn& viewer) {
    if (!viewer) {
        std::cerr
            << "tumble: this build has no viewer; `tumble run` simulates and writes frames headlessly\n";
        return kExitFailure;
    }
    ViewRequest request;
    request.scenarioPath = resolveScenario(o.scenario);
    request.scenarioText = readScenarioFile(request.scenarioPath);
    request.sets = o.sets;
    request.memoryCap = std::uint64_t(o.memoryCapMiB) << 20;
    request.threads = threadsFor(o);
    request.record = o.record;
    request.profile = o.profile;
    request.paused = o.paused;
    return viewer(catalog, request);
}

/// Runs the parsed verb; bad input is exit 2, anything else that stops it exit 1, each said on stderr.
int runVerb(const CLI::App& app, const Catalog& catalog, const RunOptions& o, const SweepOptions& sweep,
            const ViewerFn& viewer) {
    auto parsed = [&app](const char* verb) { return app.get_subcommand(verb)->parsed(); };
    try {
        if (parsed("sweep")) {
            return commandSweep(catalog, sweep);
        }
        if (parsed("list")) {
            return commandList();
        }
        if (parsed("check")) {
            return commandCheck(catalog, o);
        }
        if (parsed("replay")) {
            return commandReplay(catalog, o);
        }
        if (parsed("budget")) {
            return commandBudget(catalog, o);
        }
        if (parsed("view")) {
            return commandView(catalog, o, viewer);
        }
        return commandRun(catalog, o);
    } catch (const ScenarioError& e) {
        std::cerr << "tumble: " << e.what() << "\n";
        return kExitBadInput;
    } catch (const ReplayError& e) {
        std::cerr << "tumble: " << e.what() << "\n";
        return kExitBadInput;
    } catch (const std::bad_alloc&) {
        std::cerr << "tumble: error: out of memory\n";
        return kExitFailure;
    } catch (const std::exception& e) {
        std::cerr << "tumble: error: " << e.what() << "\n";
        return kExitFailure;
    }
}

} // namespace

std::string demoDirectory() {
    if (const char* env = std::getenv("TUMBLE_DEMOS"); env && *env) {
        return env;
    }
    return dataDirectory("demos");
}

std::string resolveScenario(const std::string& nameOrPath) {
    std::error_code ec;
    if (fs::is_regular_file(nameOrPath, ec)) {
        return nameOrPath;
    }
    const bool looksLikePath =
        nameOrPath.find('/') != std::string::npos || fs::path(nameOrPath).extension() == ".toml";
    if (!looksLikePath) {
        const std::string demo = demoDirectory() + "/" + nameOrPath + ".toml";
        if (fs::is_regular_file(demo, ec)) {
            return demo;
        }
    }
    if (fs::exists(nameOrPath, ec)) {
        return nameOrPath; // not a regular file: reading it says so
    }
    if (!looksLikePath) {
        throw ScenarioError(nameOrPath, 0, 0,
                            "no scenario file or demo by that name (`tumble list` shows the demos)");
    }
    throw ScenarioError(nameOrPath, 0, 0, "cannot open the scenario: no such file");
}

int runCli(int argc, char** argv, const Catalog& catalog, const ViewerFn& viewer) {
    CLI::App app{"Tumble: a real-time physics sandbox that runs headlessly.\n"
                 "Scenarios are TOML files (see the README); demos are run by name.",
                 "tumble"};
    app.require_subcommand(1, 1);
    app.set_help_all_flag("--help-all", "Show the help of every verb");

    RunOptions o;
    app.add_subcommand("list", "List the demos: name and what each shows");
    CLI::App* check =
        app.add_subcommand("check", "Parse and validate a scenario; prints nothing when it is valid");
    addScenarioOptions(check, o);
    CLI::App* run =
        app.add_subcommand("run", "Simulate a scenario headlessly and write the outputs asked for");
    run->add_option("scenario", o.scenario, "A scenario file (.toml) or a demo name (see `tumble list`)");
    run->add_option("--set", o.sets,
                    "Override a scenario value, e.g. --set scene.dt=0.005 or --set bob.springs.stiffness=50 "
                    "(repeatable)")
        ->allow_extra_args(false)
        ->type_name("KEY=VALUE");
    CLI::App* replay = app.add_subcommand(
        "replay", "Play a replay again (same outputs as run); --verify checks every frame's state hash");
    replay->add_option("file", o.scenario, "A replay written by run --record")->required()->type_name("FILE");
    replay->add_flag(
        "--verify", o.verify,
        "Compare every frame's state with the recording; exit 4 naming the first frame and entity "
        "that differ");
    addRunOptions(run, replay, o);
    addBudgetVerb(app, o);
    addViewVerb(app, o);
    SweepOptions sweep;
    addSweepVerb(app, sweep);
    if (!knownVerb(argc, argv, app)) {
        return kExitBadInput;
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::cerr << "tumble: " << e.what() << "\n";
        std::cerr << "Run `tumble --help` or `tumble VERB --help` for usage.\n";
        return kExitBadInput;
    }
    return runVerb(app, catalog, o, sweep, viewer);
}

} // namespace tumble
