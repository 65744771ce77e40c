#include "app/run_session.h"

#include "app/cli.h"
#include "app/gl_context.h"
#include "app/progress.h"
#include "app/run_loop.h"
#include "app/video_encoder.h"
#include "engine/dump.h"
#include "engine/fixed_loop.h"
#include "engine/parallel.h"
#include "engine/render_output.h"
#include "engine/run_report.h"
#include "engine/simd.h"
#include "engine/simulation.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>

namespace tumble {

namespace fs = std::filesystem;

int threadsFor(const RunOptions& o) {
    if (const char* error = simdEnvironmentError(); *error) {
        throw ScenarioError("environment", 0, 0, error);
    }
    if (o.threads) {
        return *o.threads;
    }
    try {
        return defaultThreadCount();
    } catch (const std::invalid_argument& e) {
        throw ScenarioError("environment", 0, 0, e.what());
    }
}

OutputFile::OutputFile(const std::string& path) : m_path(path) {
    const fs::path p(path);
    if (p.has_parent_path()) {
        std::error_code ec;
        fs::create_directories(p.parent_path(), ec);
    }
    m_out.open(p, std::ios::binary | std::ios::trunc);
    if (!m_out) {
        throw std::runtime_error("cannot write " + m_path);
    }
}

namespace {

/// A path as the file system resolves it, for telling whether two name the same file.
fs::path resolved(const std::string& path) {
    std::error_code ec;
    fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
    return ec || p.empty() ? fs::absolute(path, ec).lexically_normal() : p;
}

/// Refuses outputs that would write over each other or over what the run reads (its scenario, replay,
/// snapshot or --input file): the one written last would win, and the other be lost without a word.
/// The profile is always written: where --profile says, else <out>/profile.json (`profile`).
void checkOutputPaths(const RunOptions& o, const Source& src, const std::string& profile) {
    using Named = std::pair<const char*, std::string>;
    std::vector<Named> outputs;
    for (const Named& n :
         {Named{"--record", o.record}, Named{"--dump", o.dump},
          Named{o.profile.empty() ? "the profile (<out>/profile.json)" : "--profile", profile},
          Named{"--trace", o.trace}, Named{"--video", o.video}}) {
        if (!n.second.empty()) {
            outputs.push_back(n);
        }
    }
    std::vector<Named> inputs;
    std::error_code ec;
    for (const Named& n :
         {Named{"the scenario", src.path}, Named{"the replay", src.replayPath}, Named{"--input", o.input}}) {
        if (!n.second.empty() && fs::is_regular_file(n.second, ec)) {
            inputs.push_back(n);
        }
    }
    for (std::size_t a = 0; a < outputs.size(); ++a) {
        for (std::size_t b = a + 1; b < outputs.size(); ++b) {
            if (resolved(outputs[a].second) == resolved(outputs[b].second)) {
                throw ScenarioError(outputs[b].second, 0, 0,
                                    std::string(outputs[a].first) + " and " + outputs[b].first +
                                        " name the same file: one would write over the other");
            }
        }
        for (const Named& in : inputs) {
            if (resolved(outputs[a].second) == resolved(in.second)) {
                throw ScenarioError(outputs[a].second, 0, 0,
                                    std::string(outputs[a].first) + " names " + in.first +
                                        " this run reads: it would be written over");
            }
        }
    }
}

using Fail = std::function<void(const std::string&)>;

/// A finite number within +-1e9 (as a scenario's), or a failure naming the key.
double inputNumber(const nlohmann::json& v, const char* what, const Fail& fail) {
    if (!v.is_number() || !std::isfinite(v.get<double>()) || std::abs(v.get<double>()) > 1e9) {
        fail(std::string("'") + what + "' must be a finite number within +-1e9 (as in a scenario)");
    }
    return v.get<double>();
}

/// The keys of one input action: only known ones; the event fields present are listed for the checks.
std::vector<std::string> inputFields(const nlohmann::json& j, const Fail& fail) {
    std::vector<std::string> present;
    for (const auto& [key, value] : j.items()) {
        const bool field = key == "value" || key == "position" || key == "radius" || key == "amount";
        if (!field && key != "frame" && key != "t" && key != "entity" && key != "action" && key != "key") {
            fail("unknown key '" + key +
                 "'; an action has frame or t, entity, action, value, position, "
                 "radius, amount (a set: frame or t, action, key, value)");
        }
        if (field) {
            present.push_back(key);
        }
    }
    if (j.contains("frame") == j.contains("t")) {
        fail("an action needs exactly one of 'frame' and 't'");
    }
    const bool set = j.contains("action") && j["action"] == "set";
    for (const char* key : {set ? "key" : "entity", "action"}) {
        if (!j.contains(key) || !j[key].is_string()) {
            fail(std::string("an action needs '") + key + "', a string");
        }
    }
    if (set && (j.contains("entity") || !j.contains("value"))) {
        fail("a set names what it sets in 'key' (curtain.cloth.stretch) and gives a 'value'; no 'entity'");
    }
    if (!set && j.contains("key")) {
        fail("only a set takes 'key'");
    }
    return present;
}

/// The step an input action applies at: the first step of its frame, or the step reaching its time.
std::uint64_t inputStep(const nlohmann::json& j, const SceneDef& scene, const Fail& fail) {
    if (j.contains("frame")) {
        const double f = inputNumber(j["frame"], "frame", fail);
        if (f < 0 || f != std::floor(f) || f > 1e9) {
            fail("'frame' must be a whole number of frames, 0 or more");
        }
        return static_cast<std::uint64_t>(f) * static_cast<std::uint64_t>(scene.substeps);
    }
    const double t = inputNumber(j["t"], "t", fail);
    if (t < 0 || t > 1e9) {
        fail("'t' must be a time in seconds, 0 or more");
    }
    return stepReaching(t, scene.dt);
}

/// The event fields of one input action.
void readInputFields(const nlohmann::json& j, EventDef& ev, const Fail& fail) {
    if (j.contains("value")) {
        if (j["value"].is_array()) {
            if (j["value"].size() > 4096) {
                fail("'value' has too many numbers");
            }
            for (const auto& v : j["value"]) {
                ev.value.push_back(inputNumber(v, "value", fail));
            }
        } else {
            ev.value.push_back(inputNumber(j["value"], "value", fail));
        }
    }
    if (j.contains("position")) {
        if (!j["position"].is_array() || j["position"].size() != 3) {
            fail("'position' must be [x, y, z]");
        }
        for (std::size_t k = 0; k < 3; ++k) {
            ev.position[k] = inputNumber(j["position"][k], "position", fail);
        }
    }
    if (j.contains("radius")) {
        ev.radius = inputNumber(j["radius"], "radius", fail);
    }
    if (j.contains("amount")) {
        ev.amount = inputNumber(j["amount"], "amount", fail);
    }
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
        const Fail fail = [&](const std::string& what) { throw ScenarioError(path, lineNo, 0, what); };
        if (line.find_first_not_of(" \t\r") == std::string::npos) {
            continue;
        }
        const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded() || !j.is_object()) {
            fail("not a JSON object (one action a line: {\"frame\": 120, \"entity\": ..., \"action\": ...})");
        }
        const std::vector<std::string> present = inputFields(j, fail);
        EventDef ev;
        ev.step = inputStep(j, sim.scene(), fail);
        ev.action = j["action"].get<std::string>();
        if (ev.action == "set") {
            // checked with the run's other set events once they are all known (prepareEvents)
            ev.set = j["key"].get<std::string>() + "=" + j["value"].dump();
            events.push_back(std::move(ev));
            continue;
        }
        ev.entity = j["entity"].get<std::string>();
        readInputFields(j, ev, fail);
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
        return std::make_unique<Simulation>(catalog, src.path, src.text, src.sets, src.memoryCap,
                                            src.threads);
    }
    try {
        return std::make_unique<Simulation>(catalog, src.path, src.text, src.sets, src.memoryCap,
                                            src.threads);
    } catch (const ScenarioError& e) {
        throw ReplayError(src.replayPath, 0, std::string("its scenario does not load here: ") + e.what());
    }
}

/// One run; see the header comment. Each stage is a method, in the order run() calls them.
class RunSession {
public:
    RunSession(const Catalog& catalog, const RunOptions& o, const Source& src);
    int run();

private:
    void prepareEvents();
    std::vector<EventDef> recordedEvents() const;
    std::uint64_t framesToRun() const;
    bool afterFrame();
    void writeSnapshot(std::uint64_t frame);
    void openOutputs();
    void openVideo(RenderOutput& render);
    void runFrames();
    void dumpState();
    std::vector<std::string> finishOutputs();
    void sayWhatHappened(const std::vector<std::string>& wrote) const;
    int exitCode() const;

    const Catalog& m_catalog;
    const RunOptions& m_o;
    const Source& m_src;
    std::unique_ptr<Simulation> m_sim;
    std::uint64_t m_substeps = 1;
    std::uint64_t m_frames = 0;     ///< the frame the run ends at
    std::uint64_t m_snapshotAt = 0; ///< --snapshot-at, or 0
    std::string m_outDir;
    std::string m_profilePath; ///< --profile, else <out>/profile.json
    std::unique_ptr<ReplayWriter> m_recorder;
    std::vector<FrameRecord> m_history; ///< frames since the start, for --snapshot-at
    std::vector<EntityHash> m_entities; ///< scratch: each frame's entity hashes
    std::string m_diverged;             ///< why a verified replay diverged, if it did
    std::optional<OutputFile> m_dump, m_trace, m_profile;
    std::unique_ptr<VideoEncoder> m_video;
    std::string m_pending; ///< scratch: one dumped state
    ReportDrain m_drain;
    bool m_interrupted = false;
    SteadyClock m_clock;
    std::int64_t m_startNs = 0;
};

RunSession::RunSession(const Catalog& catalog, const RunOptions& o, const Source& src)
    : m_catalog(catalog), m_o(o), m_src(src), m_sim(load(catalog, src)) {
    m_sim->world().setResource<RunChecks>().contact = o.checkContact;
    m_substeps = static_cast<std::uint64_t>(m_sim->scene().substeps);
    m_frames = framesToRun();
    m_snapshotAt = o.snapshotAt ? static_cast<std::uint64_t>(*o.snapshotAt) : 0;
    if (m_snapshotAt > m_frames) {
        throw ScenarioError("--snapshot-at", 0, 0,
                            "--snapshot-at " + std::to_string(m_snapshotAt) +
                                " is past the run's last frame (" + std::to_string(m_frames) +
                                "): no snapshot would be written");
    }
    if (o.noRender && o.pngEvery > 0) {
        throw ScenarioError("--png-every", 0, 0,
                            "--png-every needs rendering; it cannot go with --no-render");
    }
    m_outDir = o.out.empty() ? "out/" + m_sim->scene().name : o.out;
    m_profilePath = o.profile.empty() ? m_outDir + "/profile.json" : o.profile;
    checkOutputPaths(o, src, m_profilePath);
    if (!o.record.empty()) {
        m_recorder = std::make_unique<ReplayWriter>(
            o.record, ReplayHeader{kReplayVersion, buildId(), src.path, src.text, src.sets});
    }
}

int RunSession::run() {
    prepareEvents();
    // --from: the frames before the snapshot again, silently, each checked against the snapshot's hash
    while (m_sim->frame() < m_src.resume) {
        m_sim->runFrame();
        if (!afterFrame()) {
            std::fprintf(stderr, "tumble: cannot resume from %s: %s\n", m_o.from.c_str(), m_diverged.c_str());
            return kExitDiverged;
        }
    }
    openOutputs();
    runFrames();
    sayWhatHappened(finishOutputs());
    if (m_src.diverged) {
        *m_src.diverged = m_diverged;
    }
    return exitCode();
}

/// A replay plays its recorded events, not the scenario's; --input adds timed actions.
void RunSession::prepareEvents() {
    if (m_src.replay) {
        std::vector<EventDef> events = recordedEvents();
        if (m_src.resume > 0) {
            // resuming: after the snapshot's frames the scenario's own events take over again
            const std::uint64_t from = m_src.resume * m_substeps;
            for (const EventDef& ev : m_sim->scenario().events) {
                if (ev.step >= from) {
                    events.push_back(ev);
                }
            }
        }
        m_sim->setEvents(std::move(events));
    }
    if (!m_o.input.empty()) {
        // resuming, the snapshot already holds the inputs applied before it
        std::vector<EventDef> input = readInputEvents(m_o.input, *m_sim);
        std::erase_if(input, [&](const EventDef& ev) { return ev.step < m_src.resume * m_substeps; });
        m_sim->addEvents(input);
    }
    // set events that did not come from the scenario file: checked with every set of the run, in order
    const std::vector<EventDef>& events = m_sim->pendingEvents();
    if (std::any_of(events.begin(), events.end(),
                    [](const EventDef& ev) { return ev.action == "set" && ev.line == 0; })) {
        if (auto problem = m_sim->checkSetEvents(events)) {
            if (m_src.replay) {
                throw ReplayError(m_src.replayPath, 0,
                                  "a recorded set does not fit its scenario: " + *problem);
            }
            throw ScenarioError(m_o.input, 0, 0, *problem);
        }
    }
}

/// The replay's events, each checked to belong to the frame it was filed under and to fit the scenario.
std::vector<EventDef> RunSession::recordedEvents() const {
    std::vector<EventDef> events;
    for (std::size_t f = 0; f < m_src.replay->frames.size(); ++f) {
        for (EventDef ev : m_src.replay->frames[f].events) {
            if (ev.step < f * m_substeps || ev.step >= (f + 1) * m_substeps) {
                throw ReplayError(m_src.replayPath, 0,
                                  "a recorded event at step " + std::to_string(ev.step) +
                                      " is filed under frame " + std::to_string(f + 1));
            }
            std::vector<std::string> present;
            if (ev.action != "set") {
                if (auto problem = resolveEvent(m_catalog, m_sim->world(), ev, present)) {
                    throw ReplayError(m_src.replayPath, 0,
                                      "a recorded event does not fit its scenario: " + *problem);
                }
            }
            events.push_back(std::move(ev));
        }
    }
    return events;
}

std::uint64_t RunSession::framesToRun() const {
    std::uint64_t frames = static_cast<std::uint64_t>(m_o.frames.value_or(m_sim->scene().frames));
    if (m_src.replay && m_src.resume == 0) {
        // a replay plays what was recorded, or less
        const std::uint64_t recorded = m_src.replay->frames.size();
        frames = std::min<std::uint64_t>(m_o.frames ? frames : recorded, recorded);
    }
    return std::max(frames, m_src.resume);
}

/// After every frame: its hashes and events, recorded, checked, kept; false stops the run (diverged).
bool RunSession::afterFrame() {
    std::vector<EventDef> applied = m_sim->takeAppliedEvents();
    if (!m_recorder && !m_src.replay && !m_o.snapshotAt) {
        return true;
    }
    FrameRecord rec{std::move(applied), frameHashes(m_sim->world(), m_catalog, m_entities, m_sim->pool()),
                    m_entities};
    const std::uint64_t f = m_sim->frame();
    if (m_src.replay && (m_src.verify || f <= m_src.resume) && f <= m_src.replay->frames.size()) {
        const FrameRecord& expected = m_src.replay->frames[f - 1];
        if (expected.hash != rec.hash) {
            m_diverged = describeDivergence(f, *m_src.replay, expected, rec.hash, rec.entities);
            return false;
        }
    }
    if (m_o.snapshotAt && f <= m_snapshotAt) {
        m_history.push_back(rec);
    }
    if (m_recorder) {
        m_recorder->frame(rec);
    }
    if (m_o.snapshotAt && f == m_snapshotAt) {
        writeSnapshot(f);
    }
    return true;
}

/// The run so far, as a replay to resume from, and the whole state at this frame.
void RunSession::writeSnapshot(std::uint64_t frame) {
    const std::string base = m_outDir + "/snapshot_" + std::to_string(frame);
    fs::create_directories(m_outDir);
    ReplayWriter snap(base + ".tumble",
                      ReplayHeader{kReplayVersion, buildId(), m_src.path, m_src.text, m_src.sets});
    for (const FrameRecord& h : m_history) {
        snap.frame(h);
    }
    snap.finish();
    std::string state;
    m_sim->appendDump(state);
    OutputFile dumpFile(base + ".jsonl");
    dumpFile.write(state);
    dumpFile.close();
    m_history.clear();
}

/// Every output opened before any work, so a bad path costs nothing; the budget summary is always
/// written: to --profile, else into the output folder.
void RunSession::openOutputs() {
    if (!m_o.dump.empty()) {
        m_dump.emplace(m_o.dump);
    }
    if (!m_o.trace.empty()) {
        m_trace.emplace(m_o.trace);
    }
    m_profile.emplace(m_profilePath);
    m_sim->profiler().enableTrace(m_trace.has_value());
    // what the renderer is asked for (it is a frame-phase system and reads this)
    RenderOutput& render = m_sim->world().setResource<RenderOutput>();
    render.enabled = !m_o.noRender;
    render.openContext = openHeadlessContext;
    render.directory = m_outDir;
    render.pngEvery = static_cast<std::uint64_t>(m_o.pngEvery);
    render.lastFrame = m_frames;
    if (!m_o.video.empty()) {
        openVideo(render);
    }
}

void RunSession::openVideo(RenderOutput& render) {
    if (m_o.noRender) {
        throw ScenarioError(m_o.video, 0, 0, "--video needs rendering; it cannot go with --no-render");
    }
    const std::string ext = fs::path(m_o.video).extension().string();
    if (ext != ".mp4" && ext != ".gif") {
        throw ScenarioError(m_o.video, 0, 0, "--video: the file must end in .mp4 or .gif");
    }
    const SceneDef& scene = m_sim->scene();
    m_video = std::make_unique<VideoEncoder>(m_o.video, scene.renderWidth, scene.renderHeight,
                                             1.0 / scene.frameSeconds());
    render.video = [this](const std::vector<std::uint8_t>& rgba) { m_video->push(rgba); };
}

/// The run proper. --realtime: one frame per frame period of the wall clock; the loop takes the steps the
/// time since the last frame completes, at most `substeps`, and drops the rest (and counts it).
void RunSession::runFrames() {
    const SceneDef& scene = m_sim->scene();
    const StopSignal stop;
    ProgressBar bar(m_frames, scene.frameSeconds(),
                    !m_o.quiet && (m_o.progress || ProgressBar::stderrIsTerminal()));
    const auto every = static_cast<std::uint64_t>(std::max<std::int64_t>(m_o.dumpEvery, 0));
    if (every > 0) {
        dumpState(); // the initial state, frame 0
    }
    m_startNs = m_clock.nowNs();
    FramePacer pacer(m_clock, secondsToNs(scene.frameSeconds()));
    while (m_sim->frame() < m_frames) {
        if (stop.requested()) {
            m_interrupted = true;
            break;
        }
        if (m_o.realtime) {
            m_sim->runFrameAt(m_clock);
            pacer.wait();
        } else {
            m_sim->runFrame();
        }
        if (!afterFrame()) {
            break;
        }
        // problems met during the run are said as they appear (the progress bar makes way)
        m_drain.drain(m_sim->world().resource<RunReport>(), [&](const std::string& said, bool failure) {
            if (m_src.diverged == nullptr) { // the library's verifyReplay prints nothing
                bar.clearLine();
                std::fprintf(stderr, "tumble: %s: %s\n", failure ? "error" : "note", said.c_str());
            }
        });
        if (every > 0 && m_sim->frame() % every == 0) {
            dumpState();
        }
        bar.update(m_sim->frame());
    }
    bar.finish(m_sim->frame());
    if (every == 0 || m_sim->frame() % every != 0) {
        dumpState(); // the last frame
    }
}

void RunSession::dumpState() {
    if (m_dump) {
        m_pending.clear();
        m_sim->appendDump(m_pending);
        m_dump->write(m_pending);
    }
}

/// Closes every output; returns what was written, for the summary.
std::vector<std::string> RunSession::finishOutputs() {
    std::vector<std::string> wrote;
    if (m_recorder) {
        m_recorder->finish();
        wrote.push_back(m_recorder->path() + " (a replay of " + std::to_string(m_recorder->frames()) +
                        " frames)");
    }
    if (m_o.snapshotAt && m_sim->frame() >= m_snapshotAt) {
        wrote.push_back(m_outDir + "/snapshot_" + std::to_string(m_snapshotAt) +
                        ".tumble (resume with run --from) and .jsonl (the state)");
    }
    if (m_dump) {
        m_dump->close();
        wrote.push_back(m_dump->path());
    }
    m_profile->write(budgetSummaryJson(m_sim->profiler(), m_sim->scene(), m_sim->frame(), m_sim->threads()));
    m_profile->close();
    wrote.push_back(m_profile->path());
    if (m_trace) {
        m_sim->profiler().writeTrace(m_trace->stream());
        m_trace->close();
        wrote.push_back(m_trace->path());
        if (m_sim->profiler().traceTruncated()) {
            std::fprintf(stderr,
                         "tumble: warning: the trace keeps only its first %zu events; trace fewer frames "
                         "to see them all\n",
                         Profiler::kMaxTraceEvents);
        }
    }
    if (m_video) {
        m_video->finish();
        wrote.push_back(m_video->path() + " (" + std::to_string(m_video->frames()) + " frames)");
    }
    const std::vector<std::string>& pngs = m_sim->world().resource<RenderOutput>().written;
    if (!pngs.empty()) {
        wrote.push_back(pngs.size() == 1 ? pngs[0]
                                         : std::to_string(pngs.size()) + " PNG frames in " + m_outDir +
                                               " (the last: " + pngs.back() + ")");
    }
    return wrote;
}

void RunSession::sayWhatHappened(const std::vector<std::string>& wrote) const {
    if (m_o.quiet) {
        return;
    }
    const SceneDef& scene = m_sim->scene();
    const FrameStats f = m_sim->profiler().frameStats();
    std::fprintf(stderr,
                 "%s: %llu frames, %.3f s simulated; physics per frame p50 %.3f ms, p99 %.3f ms, max %.3f ms "
                 "(budget %.3g ms, %llu frames over)\n",
                 scene.name.c_str(), static_cast<unsigned long long>(m_sim->frame()), m_sim->time(),
                 f.physicsP50Ms, f.physicsP99Ms, f.physicsMaxMs, scene.physicsBudgetMs,
                 static_cast<unsigned long long>(f.overBudgetFrames));
    for (const std::string& w : wrote) {
        std::fprintf(stderr, "wrote %s\n", w.c_str());
    }
    if (m_o.realtime) {
        std::fprintf(
            stderr,
            "realtime: %llu frames in %.3f s of wall time, %.3f s simulated; at most %d steps a frame "
            "(the cap is %d); %.3f s of simulated time dropped because physics ran over its frame\n",
            static_cast<unsigned long long>(m_sim->frame()),
            static_cast<double>(m_clock.nowNs() - m_startNs) * 1e-9, m_sim->time(),
            m_sim->mostStepsInAFrame(), scene.substeps, m_sim->droppedSeconds());
    }
}

int RunSession::exitCode() const {
    // a caller that takes the verdict (the library's verifyReplay) reports it itself
    const bool report = m_src.diverged == nullptr;
    if (!m_diverged.empty()) {
        if (report) {
            std::fprintf(stderr, "tumble: %s\n", m_diverged.c_str());
        }
        return kExitDiverged;
    }
    if (!report) { // all that verifyReplay needs: whether every frame was checked
        return m_interrupted ? kExitInterrupted : m_drain.failures() > 0 ? kExitFailure : kExitOk;
    }
    if (m_src.verify) {
        std::fprintf(stderr, "tumble: replay verified: %llu frames give the recorded state, bit for bit%s\n",
                     static_cast<unsigned long long>(m_sim->frame()),
                     m_src.replay->complete ? "" : " (as far as the file goes)");
    }
    if (m_drain.failures() > 0) {
        std::fprintf(stderr, "tumble: the run finished with %zu failure(s), listed above\n",
                     m_drain.failures());
        return kExitFailure;
    }
    if (m_interrupted) {
        std::fprintf(stderr, "tumble: interrupted at frame %llu; the outputs above hold the run so far\n",
                     static_cast<unsigned long long>(m_sim->frame()));
        return kExitInterrupted;
    }
    return kExitOk;
}

} // namespace

Source replaySource(const std::string& path, bool verify, int threads) {
    auto file = std::make_shared<const ReplayFile>(readReplay(path));
    Source src;
    src.threads = threads;
    src.path = file->header.scenarioPath;
    src.text = file->header.scenarioText;
    src.sets = file->header.overrides;
    src.replay = file;
    src.verify = verify;
    src.replayPath = path;
    return src;
}

int runSession(const Catalog& catalog, const RunOptions& options, const Source& source) {
    RunSession session(catalog, options, source);
    return session.run();
}

} // namespace tumble
