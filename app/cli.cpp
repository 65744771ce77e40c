#include "app/cli.h"

#include "app/gl_context.h"
#include "app/progress.h"
#include "app/video_encoder.h"
#include "engine/dump.h"
#include "engine/fixed_loop.h"
#include "engine/render_output.h"
#include "engine/replay.h"
#include "engine/run_report.h"
#include "engine/simulation.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <thread>
#include <tuple>

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
};

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
    Simulation sim(catalog, path, readScenarioFile(path), o.sets, std::uint64_t(o.memoryCapMiB) << 20);
    return kExitOk;
}

/// Reads --input: one JSON object a line, {"frame": N or "t": seconds, "entity", "action", "value",
/// "position", "radius", "amount"}, each resolved as a scenario event is. Throws ScenarioError (file:line).
std::vector<EventDef> readInputEvents(const std::string& path, const Simulation& sim) {
    std::ifstream in(path);
    if (!in) {
        throw ScenarioError(path, 0, 0, "cannot read the input file");
    }
    std::vector<EventDef> events;
    std::string line;
    int lineNo = 0;
    while (std::getline(in, line)) {
        ++lineNo;
        auto fail = [&](const std::string& what) { throw ScenarioError(path, lineNo, 0, what); };
        if (line.find_first_not_of(" \t\r") == std::string::npos) {
            continue;
        }
        const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded() || !j.is_object()) {
            fail("not a JSON object (one action a line: {\"frame\": 120, \"entity\": ..., \"action\": ...})");
        }
        EventDef ev;
        std::vector<std::string> present;
        for (const auto& [key, value] : j.items()) {
            const bool known = key == "frame" || key == "t" || key == "entity" || key == "action" ||
                               key == "value" || key == "position" || key == "radius" || key == "amount";
            if (!known) {
                fail("unknown key '" + key +
                     "'; an action has frame or t, entity, action, value, position, "
                     "radius, amount");
            }
            if (key == "value" || key == "position" || key == "radius" || key == "amount") {
                present.push_back(key);
            }
        }
        if (j.contains("frame") == j.contains("t")) {
            fail("an action needs exactly one of 'frame' and 't'");
        }
        auto number = [&](const nlohmann::json& v, const char* what) {
            if (!v.is_number() || !std::isfinite(v.get<double>()) || std::abs(v.get<double>()) > 1e9) {
                fail(std::string("'") + what + "' must be a finite number within +-1e9 (as in a scenario)");
            }
            return v.get<double>();
        };
        const SceneDef& scene = sim.scene();
        if (j.contains("frame")) {
            const double f = number(j["frame"], "frame");
            if (f < 0 || f != std::floor(f) || f > 1e9) {
                fail("'frame' must be a whole number of frames, 0 or more");
            }
            ev.step = static_cast<std::uint64_t>(f) * static_cast<std::uint64_t>(scene.substeps);
        } else {
            const double t = number(j["t"], "t");
            if (t < 0 || t > 1e9) {
                fail("'t' must be a time in seconds, 0 or more");
            }
            ev.step = stepReaching(t, scene.dt);
        }
        for (const char* key : {"entity", "action"}) {
            if (!j.contains(key) || !j[key].is_string()) {
                fail(std::string("an action needs '") + key + "', a string");
            }
        }
        ev.entity = j["entity"].get<std::string>();
        ev.action = j["action"].get<std::string>();
        if (j.contains("value")) {
            if (j["value"].is_array()) {
                if (j["value"].size() > 4096) {
                    fail("'value' has too many numbers");
                }
                for (const auto& v : j["value"]) {
                    ev.value.push_back(number(v, "value"));
                }
            } else {
                ev.value.push_back(number(j["value"], "value"));
            }
        }
        if (j.contains("position")) {
            if (!j["position"].is_array() || j["position"].size() != 3) {
                fail("'position' must be [x, y, z]");
            }
            for (std::size_t k = 0; k < 3; ++k) {
                ev.position[k] = number(j["position"][k], "position");
            }
        }
        if (j.contains("radius")) {
            ev.radius = number(j["radius"], "radius");
        }
        if (j.contains("amount")) {
            ev.amount = number(j["amount"], "amount");
        }
        if (auto problem = resolveEvent(sim.catalog(), sim.world(), ev, present)) {
            fail(*problem);
        }
        events.push_back(std::move(ev));
    }
    std::stable_sort(events.begin(), events.end(),
                     [](const EventDef& a, const EventDef& b) { return a.step < b.step; });
    return events;
}

/// Names what differs between a recorded frame and the same frame replayed.
std::string describeDivergence(std::uint64_t frame, const ReplayFile& file, const FrameRecord& recorded,
                               std::uint64_t hash, const std::vector<EntityHash>& now) {
    std::string where = "the replay diverged at frame " + std::to_string(frame) + ": ";
    std::vector<EntityHash> named;
    for (const EntityHash& e : recorded.entities) {
        named.push_back({file.names[e.id].first, file.names[e.id].second, e.hash, e.id});
    }
    for (const EntityHash& r : named) {
        const auto found =
            std::find_if(now.begin(), now.end(), [&](const EntityHash& e) { return e.name == r.name; });
        if (found == now.end()) {
            return where + "entity '" + r.name + "' (" + r.kind +
                   ") is in the recording but not in the replay";
        }
        if (found->hash != r.hash) {
            return where + "entity '" + r.name + "' differs in its " + r.kind + " state (recorded " +
                   hashHex(r.hash) + ", replayed " + hashHex(found->hash) + ")";
        }
    }
    for (const EntityHash& e : now) {
        if (std::none_of(named.begin(), named.end(), [&](const EntityHash& r) { return r.name == e.name; })) {
            return where + "entity '" + e.name + "' (" + e.kind +
                   ") is in the replay but not in the recording";
        }
    }
    return where + "the state hash differs (recorded " + hashHex(recorded.hash) + ", replayed " +
           hashHex(hash) + ") though every named entity matches: unnamed state (a joint, say) differs";
}

/// The simulation of a source; a replay's own scenario that does not load is the replay's fault (exit 2
/// naming the replay).
std::unique_ptr<Simulation> load(const Catalog& catalog, const Source& src) {
    if (!src.replay) {
        return std::make_unique<Simulation>(catalog, src.path, src.text, src.sets, src.memoryCap);
    }
    try {
        return std::make_unique<Simulation>(catalog, src.path, src.text, src.sets, src.memoryCap);
    } catch (const ScenarioError& e) {
        throw ReplayError(src.replayPath, 0, std::string("its scenario does not load here: ") + e.what());
    }
}

int simulate(const Catalog& catalog, const RunOptions& o, const Source& src) {
    const std::unique_ptr<Simulation> owned = load(catalog, src);
    Simulation& sim = *owned;
    sim.world().setResource<RunChecks>().contact = o.checkContact;
    const SceneDef& scene = sim.scene();
    const auto substeps = static_cast<std::uint64_t>(scene.substeps);
    if (src.replay) {
        // the recorded events, not the scenario's: they are what happened; each must belong to the frame
        // it was recorded in
        std::vector<EventDef> events;
        for (std::size_t f = 0; f < src.replay->frames.size(); ++f) {
            for (EventDef ev : src.replay->frames[f].events) {
                if (ev.step < f * substeps || ev.step >= (f + 1) * substeps) {
                    throw ReplayError(src.replayPath, 0,
                                      "a recorded event at step " + std::to_string(ev.step) +
                                          " is filed under frame " + std::to_string(f + 1));
                }
                std::vector<std::string> present;
                if (auto problem = resolveEvent(catalog, sim.world(), ev, present)) {
                    throw ReplayError(src.replayPath, 0,
                                      "a recorded event does not fit its scenario: " + *problem);
                }
                events.push_back(std::move(ev));
            }
        }
        if (src.resume > 0) {
            // resuming: after the snapshot's frames the scenario's own events take over again
            const std::uint64_t from = src.resume * substeps;
            for (const EventDef& ev : sim.scenario().events) {
                if (ev.step >= from) {
                    events.push_back(ev);
                }
            }
        }
        sim.setEvents(std::move(events));
    }
    if (!o.input.empty()) {
        // resuming, the snapshot already holds the inputs applied before it
        std::vector<EventDef> input = readInputEvents(o.input, sim);
        std::erase_if(input, [&](const EventDef& ev) { return ev.step < src.resume * substeps; });
        sim.addEvents(input);
    }
    std::uint64_t frames = static_cast<std::uint64_t>(o.frames.value_or(scene.frames));
    if (src.replay && src.resume == 0) {
        // a replay plays what was recorded, or less
        frames =
            std::min<std::uint64_t>(o.frames ? frames : src.replay->frames.size(), src.replay->frames.size());
    }
    frames = std::max(frames, src.resume);
    const std::string outDir = o.out.empty() ? "out/" + scene.name : o.out;
    std::unique_ptr<ReplayWriter> recorder;
    if (!o.record.empty()) {
        recorder = std::make_unique<ReplayWriter>(
            o.record, ReplayHeader{kReplayVersion, buildId(), src.path, src.text, src.sets});
    }
    std::vector<FrameRecord> history; // for --snapshot-at
    const std::uint64_t snapshotAt = o.snapshotAt ? static_cast<std::uint64_t>(*o.snapshotAt) : 0;
    std::vector<EntityHash> entities;
    // after every frame: its hashes and events, recorded, checked, kept; false stops the run (diverged)
    std::string diverged;
    auto afterFrame = [&]() {
        std::vector<EventDef> applied = sim.takeAppliedEvents();
        if (!recorder && !src.replay && !o.snapshotAt) {
            return true;
        }
        FrameRecord rec{std::move(applied), frameHashes(sim.world(), catalog, entities), entities};
        const std::uint64_t f = sim.frame();
        if (src.replay && (src.verify || f <= src.resume) && f <= src.replay->frames.size()) {
            const FrameRecord& expected = src.replay->frames[f - 1];
            if (expected.hash != rec.hash) {
                diverged = describeDivergence(f, *src.replay, expected, rec.hash, rec.entities);
                return false;
            }
        }
        if (o.snapshotAt && f <= snapshotAt) {
            history.push_back(rec);
        }
        if (recorder) {
            recorder->frame(rec);
        }
        if (o.snapshotAt && f == snapshotAt) {
            // the run so far, as a replay to resume from, and the whole state at this frame
            const std::string base = outDir + "/snapshot_" + std::to_string(f);
            fs::create_directories(outDir);
            ReplayWriter snap(base + ".tumble",
                              ReplayHeader{kReplayVersion, buildId(), src.path, src.text, src.sets});
            for (const FrameRecord& h : history) {
                snap.frame(h);
            }
            snap.finish();
            std::string state;
            sim.appendDump(state);
            OutputFile dumpFile(base + ".jsonl");
            dumpFile.write(state);
            dumpFile.close();
            history.clear();
        }
        return true;
    };

    // --from: the frames before the snapshot again, silently, each checked against the snapshot's hash
    while (sim.frame() < src.resume) {
        sim.runFrame();
        if (!afterFrame()) {
            std::fprintf(stderr, "tumble: cannot resume from %s: %s\n", o.from.c_str(), diverged.c_str());
            return kExitDiverged;
        }
    }

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
    render.openContext = openHeadlessContext;
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
    // --realtime: one frame per frame period of the wall clock; the loop takes the steps the time since the
    // last frame completes, at most `substeps`, and drops the rest (and counts it)
    const SteadyClock clock;
    const std::int64_t periodNs = secondsToNs(scene.frameSeconds());
    const std::int64_t startNs = clock.nowNs();
    std::int64_t nextFrameNs = startNs;
    while (sim.frame() < frames) {
        if (g_interrupted.load()) {
            interrupted = true;
            break;
        }
        if (o.realtime) {
            sim.runFrameAt(clock);
            // the next frame one period on; after an overrun, one period from now (no burst of catch-up
            // frames that would each take no step)
            nextFrameNs = std::max(nextFrameNs + periodNs, clock.nowNs());
            const std::int64_t wait = nextFrameNs - clock.nowNs();
            if (wait > 0) {
                std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
            }
        } else {
            sim.runFrame();
        }
        if (!afterFrame()) {
            break;
        }
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
    if (recorder) {
        recorder->finish();
        wrote.push_back(recorder->path() + " (a replay of " + std::to_string(recorder->frames()) +
                        " frames)");
    }
    if (o.snapshotAt && sim.frame() >= snapshotAt) {
        wrote.push_back(outDir + "/snapshot_" + std::to_string(snapshotAt) +
                        ".tumble (resume with run --from) and .jsonl (the state)");
    }
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
    if (o.realtime && !o.quiet) {
        std::fprintf(
            stderr,
            "realtime: %llu frames in %.3f s of wall time, %.3f s simulated; at most %d steps a frame "
            "(the cap is %d); %.3f s of simulated time dropped because physics ran over its frame\n",
            static_cast<unsigned long long>(sim.frame()), static_cast<double>(clock.nowNs() - startNs) * 1e-9,
            sim.time(), sim.mostStepsInAFrame(), scene.substeps, sim.droppedSeconds());
    }
    if (!diverged.empty()) {
        std::fprintf(stderr, "tumble: %s\n", diverged.c_str());
        return kExitDiverged;
    }
    if (src.verify) {
        std::fprintf(stderr, "tumble: replay verified: %llu frames give the recorded state, bit for bit%s\n",
                     static_cast<unsigned long long>(sim.frame()),
                     src.replay->complete ? "" : " (as far as the file goes)");
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
        return simulate(catalog, o, src);
    }
    if (o.scenario.empty()) {
        throw ScenarioError("tumble run", 0, 0,
                            "give a scenario (a .toml file or a demo name) or --from SNAPSHOT");
    }
    src.path = resolveScenario(o.scenario);
    src.text = readScenarioFile(src.path);
    src.sets = o.sets;
    return simulate(catalog, o, src);
}

int commandReplay(const Catalog& catalog, const RunOptions& o) {
    auto file = std::make_shared<const ReplayFile>(readReplay(o.scenario));
    const ReplayFile& replay = *file;
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
    Source src;
    src.memoryCap = std::uint64_t(o.memoryCapMiB) << 20;
    src.path = replay.header.scenarioPath;
    src.text = replay.header.scenarioText;
    src.sets = replay.header.overrides;
    src.replay = file;
    src.verify = o.verify;
    src.replayPath = o.scenario;
    return simulate(catalog, o, src);
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
    Simulation sim(catalog, path, readScenarioFile(path), o.sets, std::uint64_t(o.memoryCapMiB) << 20);
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
    std::printf("budget of '%s': %llu frames without rendering, physics budget %.3f ms a frame",
                scene.name.c_str(), static_cast<unsigned long long>(sim.frame()), budget);
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
        std::printf("%-18s %-6s %9.3f %9.3f %9.3f\n", st.name.c_str(),
                    std::string(phaseName(st.phase)).c_str(), st.p50Ms, st.p99Ms, st.maxMs);
    }
    std::printf("%-18s %-6s %9.3f %9.3f %9.3f   %s\n", "physics a frame", "", f.physicsP50Ms, f.physicsP99Ms,
                f.physicsMaxMs, over ? "OVER BUDGET" : "within budget");
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

void addMemoryCapOption(CLI::App* cmd, RunOptions& o) {
    cmd->add_option("--memory-cap", o.memoryCapMiB,
                    "Refuse, at load, a scene whose components would need more memory than this, in MiB "
                    "(default 4096)")
        ->check(CLI::Range(std::int64_t(1), std::int64_t(1) << 24))
        ->type_name("MIB");
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

int runCli(int argc, char** argv, const Catalog& catalog, const ViewerFn& viewer) {
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
    for (CLI::App* cmd : {run, replay}) {
        addMemoryCapOption(cmd, o);
        cmd->add_option("--frames", o.frames,
                        "How many frames to run (default: the scene's frames; a replay's own)")
            ->check(CLI::Range(std::int64_t(0), std::int64_t(1'000'000'000)));
        cmd->add_option("--out", o.out, "Where outputs go (default out/<scene name>/)");
        cmd->add_flag("--no-render", o.noRender, "Simulate only; no EGL context is created");
        cmd->add_option("--video", o.video,
                        "Encode the rendered frames to FILE (.mp4 or .gif) through ffmpeg")
            ->type_name("FILE");
        cmd->add_option(
               "--png-every", o.pngEvery,
               "Write frame_NNNNN.png into the output folder every K frames (0: the last frame only, the "
               "default)")
            ->check(CLI::Range(std::int64_t(0), std::int64_t(1'000'000'000)))
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
            ->check(CLI::Range(std::int64_t(1), std::int64_t(1'000'000'000)))
            ->type_name("K")
            ->needs(dumpOption);
        cmd->add_option("--record", o.record,
                        "Write a replay to FILE: the scenario, every input and every frame's state hash")
            ->type_name("FILE");
        cmd->add_flag("--quiet", o.quiet, "No progress bar and no summary");
        cmd->add_flag("--progress", o.progress, "Show the progress bar even when stderr is not a terminal");
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
        ->check(CLI::Range(std::int64_t(1), std::int64_t(1'000'000'000)))
        ->type_name("N");
    run->add_option("--from", o.from,
                    "Resume from a snapshot: its frames are simulated again, checked against it, and the run "
                    "goes on from there")
        ->type_name("SNAPSHOT");

    CLI::App* budgetCmd = app.add_subcommand(
        "budget",
        "Run a scenario without rendering and hold its physics p99 to its budget (exit 3 when over)");
    addScenarioOptions(budgetCmd, o);
    budgetCmd->add_option("--frames", o.frames, "How many frames to run (default: the scene's frames)")
        ->check(CLI::Range(std::int64_t(1), std::int64_t(1'000'000'000)));
    budgetCmd
        ->add_option("--physics-ms", o.physicsMs,
                     "The budget, ms of physics a frame (default: [budget] physics_ms)")
        ->check(CLI::Range(1e-6, 1e6));
    budgetCmd
        ->add_option("--scale", o.scale,
                     "Room for a slower machine: fail only above budget x S (default: $TUMBLE_BUDGET_SCALE, "
                     "else 1)")
        ->check(CLI::Range(1e-6, 1e6));
    budgetCmd
        ->add_option("--chart", o.chart, "Write an SVG chart of physics time per frame with the budget line")
        ->type_name("FILE");
    budgetCmd->add_flag("--quiet", o.quiet, "No progress bar");
    budgetCmd->add_flag("--progress", o.progress, "Show the progress bar even when stderr is not a terminal");

    CLI::App* viewCmd = app.add_subcommand(
        "view",
        "Open a window on a scenario, live: drag things with the mouse, watch the budget (needs a display)");
    addScenarioOptions(viewCmd, o);
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

    // an unknown verb is named, rather than CLI11's "a subcommand is required"
    if (argc >= 2 && argv[1][0] != '-') {
        const std::string verb = argv[1];
        const auto verbs = app.get_subcommands([](CLI::App*) { return true; });
        if (std::none_of(verbs.begin(), verbs.end(), [&](CLI::App* v) { return v->get_name() == verb; })) {
            std::cerr << "tumble: unknown verb '" << verb
                      << "'; the verbs are list, check, run, replay, budget and view\n"
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
        if (replay->parsed()) {
            return commandReplay(catalog, o);
        }
        if (budgetCmd->parsed()) {
            return commandBudget(catalog, o);
        }
        if (viewCmd->parsed()) {
            if (!viewer) {
                std::cerr << "tumble: this build has no viewer; `tumble run` simulates and writes frames "
                             "headlessly\n";
                return kExitFailure;
            }
            ViewRequest request;
            request.scenarioPath = resolveScenario(o.scenario);
            request.scenarioText = readScenarioFile(request.scenarioPath);
            request.sets = o.sets;
            request.memoryCap = std::uint64_t(o.memoryCapMiB) << 20;
            request.record = o.record;
            request.profile = o.profile;
            request.paused = o.paused;
            return viewer(catalog, request);
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

} // namespace tumble
