#include "engine/cli.h"

#include "engine/progress.h"
#include "engine/render_output.h"
#include "engine/run_report.h"
#include "engine/simulation.h"
#include "engine/video_encoder.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>

namespace tumble {

namespace fs = std::filesystem;

namespace {

std::atomic<bool> g_interrupted{false};

static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onInterrupt(int) {
    g_interrupted.store(true);
}

/// An output file opened at the start of a run, so that a bad path fails before any work is done.
class OutputFile {
public:
    explicit OutputFile(const std::string& path) : m_path(path) {
        const fs::path p(path);
        if (p.has_parent_path()) {
            std::error_code ec;
            fs::create_directories(p.parent_path(), ec);
        }
        m_out.open(p, std::ios::binary | std::ios::trunc);
        if (!m_out) {
            throw std::runtime_error("cannot write " + path);
        }
    }
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

std::string executableDirectory() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string() : exe.parent_path().string();
}

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
};

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
    Simulation sim(catalog, path, readScenarioFile(path), o.sets);
    return kExitOk;
}

int commandRun(const Catalog& catalog, const RunOptions& o) {
    const std::string path = resolveScenario(o.scenario);
    Simulation sim(catalog, path, readScenarioFile(path), o.sets);
    const SceneDef& scene = sim.scene();
    const std::uint64_t frames = static_cast<std::uint64_t>(o.frames.value_or(scene.frames));
    const std::string outDir = o.out.empty() ? "out/" + scene.name : o.out;

    // open every output before doing any work, so a bad path costs nothing; the budget summary is always
    // written: to --profile, else into the output folder
    std::optional<OutputFile> dump, trace;
    if (!o.dump.empty()) {
        dump.emplace(o.dump);
    }
    if (!o.trace.empty()) {
        trace.emplace(o.trace);
    }
    OutputFile profile(o.profile.empty() ? outDir + "/profile.json" : o.profile);
    sim.profiler().enableTrace(trace.has_value());
    // what the renderer is asked for (it is a frame-phase system and reads this)
    RenderOutput& render = sim.world().setResource<RenderOutput>();
    render.enabled = !o.noRender;
    render.directory = outDir;
    render.pngEvery = static_cast<std::uint64_t>(o.pngEvery);
    render.lastFrame = frames;
    std::unique_ptr<VideoEncoder> video;
    if (!o.video.empty()) {
        if (o.noRender) {
            throw ScenarioError(o.video, 0, 0, "--video needs rendering; it cannot go with --no-render");
        }
        const std::string ext = fs::path(o.video).extension().string();
        if (ext != ".mp4" && ext != ".gif") {
            throw ScenarioError(o.video, 0, 0, "--video: the file must end in .mp4 or .gif");
        }
        video = std::make_unique<VideoEncoder>(o.video, scene.renderWidth, scene.renderHeight,
                                               1.0 / scene.frameSeconds());
        render.video = [&video](const std::vector<std::uint8_t>& rgba) { video->push(rgba); };
    }

    // the first Ctrl-C stops the run at the next frame and keeps the outputs; a second one kills it
    struct sigaction stop {};
    stop.sa_handler = onInterrupt;
    stop.sa_flags = SA_RESETHAND;
    sigemptyset(&stop.sa_mask);
    ::sigaction(SIGINT, &stop, nullptr);
    ::sigaction(SIGTERM, &stop, nullptr);
    ProgressBar bar(frames, scene.frameSeconds(),
                    !o.quiet && (o.progress || ProgressBar::stderrIsTerminal()));
    std::string pending;
    auto dumpNow = [&] {
        if (dump) {
            pending.clear();
            sim.appendDump(pending);
            dump->write(pending);
        }
    };
    if (o.dumpEvery > 0) {
        dumpNow(); // the initial state, frame 0
    }
    bool interrupted = false;
    std::size_t reported = 0, noted = 0;
    while (sim.frame() < frames) {
        if (g_interrupted.load()) {
            interrupted = true;
            break;
        }
        sim.runFrame();
        // problems met during the run are said as they appear (the progress bar makes way)
        const RunReport& report = sim.world().resource<RunReport>();
        for (; reported < report.failures.size(); ++reported) {
            bar.clearLine();
            std::fprintf(stderr, "tumble: error: %s\n", report.failures[reported].c_str());
        }
        for (; noted < report.notes.size(); ++noted) {
            bar.clearLine();
            std::fprintf(stderr, "tumble: note: %s\n", report.notes[noted].c_str());
        }
        if (o.dumpEvery > 0 && sim.frame() % static_cast<std::uint64_t>(o.dumpEvery) == 0) {
            dumpNow();
        }
        bar.update(sim.frame());
    }
    bar.finish(sim.frame());
    if (o.dumpEvery <= 0 || sim.frame() % static_cast<std::uint64_t>(o.dumpEvery) != 0) {
        dumpNow(); // the last frame
    }
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);

    // outputs
    std::vector<std::string> wrote;
    if (dump) {
        dump->close();
        wrote.push_back(dump->path());
    }
    profile.write(budgetSummaryJson(sim.profiler(), scene, sim.frame()));
    profile.close();
    wrote.push_back(profile.path());
    if (trace) {
        sim.profiler().writeTrace(trace->stream());
        trace->close();
        wrote.push_back(trace->path());
        if (sim.profiler().traceTruncated()) {
            std::fprintf(stderr,
                         "tumble: warning: the trace keeps only its first %zu events; trace fewer frames "
                         "to see them all\n",
                         Profiler::kMaxTraceEvents);
        }
    }
    if (video) {
        video->finish();
        wrote.push_back(video->path() + " (" + std::to_string(video->frames()) + " frames)");
    }
    const std::vector<std::string>& pngs = sim.world().resource<RenderOutput>().written;
    if (!pngs.empty()) {
        wrote.push_back(pngs.size() == 1 ? pngs[0]
                                         : std::to_string(pngs.size()) + " PNG frames in " + outDir +
                                               " (the last: " + pngs.back() + ")");
    }
    const FrameStats f = sim.profiler().frameStats();
    if (!o.quiet) {
        std::fprintf(
            stderr,
            "%s: %llu frames, %.3f s simulated; physics per frame p50 %.3f ms, p99 %.3f ms, max %.3f ms "
            "(budget %.3g ms, %llu frames over)\n",
            scene.name.c_str(), static_cast<unsigned long long>(sim.frame()), sim.time(), f.physicsP50Ms,
            f.physicsP99Ms, f.physicsMaxMs, scene.physicsBudgetMs,
            static_cast<unsigned long long>(f.overBudgetFrames));
        for (const std::string& w : wrote) {
            std::fprintf(stderr, "wrote %s\n", w.c_str());
        }
    }
    if (reported > 0) {
        std::fprintf(stderr, "tumble: the run finished with %zu failure(s), listed above\n", reported);
        return kExitFailure;
    }
    if (interrupted) {
        std::fprintf(stderr, "tumble: interrupted at frame %llu; the outputs above hold the run so far\n",
                     static_cast<unsigned long long>(sim.frame()));
        return kExitInterrupted;
    }
    return kExitOk;
}

void addScenarioOptions(CLI::App* cmd, RunOptions& o) {
    cmd->add_option("scenario", o.scenario, "A scenario file (.toml) or a demo name (see `tumble list`)")
        ->required();
    cmd->add_option("--set", o.sets,
                    "Override a scenario value, e.g. --set scene.dt=0.005 or --set bob.springs.stiffness=50 "
                    "(repeatable)")
        ->allow_extra_args(false)
        ->type_name("KEY=VALUE");
}

} // namespace

std::string demoDirectory() {
    if (const char* env = std::getenv("TUMBLE_DEMOS"); env && *env) {
        return env;
    }
    const std::string exe = executableDirectory();
    for (const std::string& candidate : {exe + "/demos", exe + "/../demos"}) {
        if (!exe.empty() && fs::is_directory(candidate)) {
            return fs::weakly_canonical(candidate).string();
        }
    }
    return std::string(TUMBLE_SOURCE_DIR) + "/demos";
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

int runCli(int argc, char** argv, const Catalog& catalog) {
    CLI::App app{"Tumble: a real-time physics sandbox that runs headlessly.\n"
                 "Scenarios are TOML files (see the README); demos are run by name.",
                 "tumble"};
    app.require_subcommand(1, 1);
    app.set_help_all_flag("--help-all", "Show the help of every verb");

    RunOptions o;
    CLI::App* list = app.add_subcommand("list", "List the demos: name and what each shows");
    CLI::App* check =
        app.add_subcommand("check", "Parse and validate a scenario; prints nothing when it is valid");
    addScenarioOptions(check, o);
    CLI::App* run =
        app.add_subcommand("run", "Simulate a scenario headlessly and write the outputs asked for");
    addScenarioOptions(run, o);
    run->add_option("--frames", o.frames, "How many frames to run (default: the scene's frames)")
        ->check(CLI::Range(std::int64_t(0), std::int64_t(1'000'000'000)));
    run->add_option("--out", o.out, "Where outputs go (default out/<scene name>/)");
    run->add_flag("--no-render", o.noRender, "Simulate only; no EGL context is created");
    run->add_option("--video", o.video, "Encode the rendered frames to FILE (.mp4 or .gif) through ffmpeg")
        ->type_name("FILE");
    run->add_option(
           "--png-every", o.pngEvery,
           "Write frame_NNNNN.png into the output folder every K frames (0: the last frame only, the "
           "default)")
        ->check(CLI::Range(std::int64_t(0), std::int64_t(1'000'000'000)))
        ->type_name("K");
    run->add_option("--profile", o.profile,
                    "Write the budget summary as JSON to FILE (default <out>/profile.json)")
        ->type_name("FILE");
    run->add_option("--trace", o.trace, "Write a Chrome trace-event JSON of every system's timing to FILE")
        ->type_name("FILE");
    CLI::Option* dumpOption =
        run->add_option("--dump", o.dump, "Write the simulation state as JSON Lines to FILE")
            ->type_name("FILE");
    run->add_option("--dump-every", o.dumpEvery,
                    "Dump every K frames, starting with the initial state (default: the last frame only)")
        ->check(CLI::Range(std::int64_t(1), std::int64_t(1'000'000'000)))
        ->type_name("K")
        ->needs(dumpOption);
    run->add_flag("--quiet", o.quiet, "No progress bar and no summary");
    run->add_flag("--progress", o.progress, "Show the progress bar even when stderr is not a terminal");

    // an unknown verb is named, rather than CLI11's "a subcommand is required"
    if (argc >= 2 && argv[1][0] != '-') {
        const std::string verb = argv[1];
        const auto verbs = app.get_subcommands([](CLI::App*) { return true; });
        if (std::none_of(verbs.begin(), verbs.end(), [&](CLI::App* v) { return v->get_name() == verb; })) {
            std::cerr << "tumble: unknown verb '" << verb << "'; the verbs are list, check and run\n"
                      << "Run `tumble --help` for usage.\n";
            return kExitBadInput;
        }
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

    try {
        if (list->parsed()) {
            return commandList();
        }
        if (check->parsed()) {
            return commandCheck(catalog, o);
        }
        return commandRun(catalog, o);
    } catch (const ScenarioError& e) {
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

} // namespace tumble
