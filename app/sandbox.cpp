// The embedding API (include/tumble/sandbox.h): a Simulation of the built-in systems, stepped by the
// caller, with the command line's own pieces for events, dumps, profiles and replays.

#include "tumble/sandbox.h"

#include "app/cli.h"
#include "app/run_session.h"
#include "engine/dump.h"
#include "engine/json.h"
#include "engine/name.h"
#include "engine/parallel.h"
#include "engine/replay.h"
#include "engine/run_report.h"
#include "engine/simulation.h"
#include "engine/table_reader.h"
#include "systems/builtin.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace tumble {

namespace {

/// The dump's words for non-finite numbers are not JSON: quoted, they parse (as strings, read back below).
double jsonNumber(const nlohmann::json& j) {
    if (j.is_number()) {
        return j.get<double>();
    }
    const std::string s = j.is_string() ? j.get<std::string>() : "NaN";
    return s == "Infinity" ? HUGE_VAL : s == "-Infinity" ? -HUGE_VAL : std::nan("");
}

/// A thread count as Sandbox and verifyReplay take it: 0 for the default, else 1 to kMaxThreads.
int threadCount(int threads) {
    if (threads < 0 || threads > kMaxThreads) {
        throw std::invalid_argument("threads must be 0 (every hardware thread, or $TUMBLE_THREADS) or 1 to " +
                                    std::to_string(kMaxThreads) + ", not " + std::to_string(threads));
    }
    return threads > 0 ? threads : defaultThreadCount();
}

/// An action's number as --input and [[event]] take it: finite, within +-1e9.
double actionNumber(double v, const char* what) {
    if (!std::isfinite(v) || std::abs(v) > 1e9) {
        throw ScenarioError("apply", 0, 0,
                            std::string("'") + what +
                                "' must be a finite number within +-1e9 (as in a scenario)");
    }
    return v;
}

} // namespace

struct Sandbox::State {
    std::string path;
    std::string text;
    std::vector<std::string> sets;
    std::unique_ptr<Simulation> sim;
    std::unique_ptr<ReplayWriter> recorder;
    std::string recordingTo;          ///< the recorder's file
    std::vector<EntityHash> entities; ///< scratch: a frame's entity hashes

    /// The named entity the dump lists and the codec that writes it (the first that claims it, as the dump
    /// takes), or a ScenarioError.
    std::pair<Entity, const StateCodec*> dumped(const std::string& name) const {
        const World& world = sim->world();
        for (Entity e : world.entities()) {
            const Name* n = world.tryGet<Name>(e);
            if (!n || n->value != name) {
                continue;
            }
            for (const StateCodec& codec : sim->catalog().states()) {
                if (codec.has(world, e)) {
                    return {e, &codec};
                }
            }
        }
        std::vector<std::string> names; // those with a state, for a did-you-mean
        for (Entity e : world.entities()) {
            const Name* n = world.tryGet<Name>(e);
            if (!n) {
                continue;
            }
            if (n->value == name) {
                throw ScenarioError(path, 0, 0,
                                    "entity '" + name +
                                        "' has no state the dump lists (no positions or velocities)");
            }
            const auto& states = sim->catalog().states();
            if (std::any_of(states.begin(), states.end(),
                            [&](const StateCodec& codec) { return codec.has(world, e); })) {
                names.push_back(n->value);
            }
        }
        const std::string near = nearestName(name, names);
        throw ScenarioError(path, 0, 0,
                            "no entity '" + name + "' in the scene" +
                                (near.empty() ? "" : " (did you mean '" + near + "'?)"));
    }

    /// One entity's table of the dump (as the whole dump line has it), or a ScenarioError.
    nlohmann::json entityDump(const std::string& name) const {
        const Entity e = dumped(name).first;
        std::string out;
        JsonWriter w(out);
        dumpEntity(w, sim->world(), sim->catalog(), e);
        return nlohmann::json::parse(quoteNonFinite(std::move(out)));
    }

    std::vector<std::array<double, 3>> rows(const std::string& name, const char* field) const {
        // straight from the component where its codec can (springs, particles: the large ones)
        const auto [entity, codec] = dumped(name);
        if (Catalog::Rows direct; codec->rows && codec->rows(sim->world(), entity, field, direct)) {
            return direct;
        }
        const nlohmann::json e = entityDump(name);
        if (!e.contains(field)) {
            throw ScenarioError(path, 0, 0,
                                "entity '" + name + "' (" + e.value("kind", std::string("?")) + ") has no " +
                                    field);
        }
        std::vector<std::array<double, 3>> out;
        for (const nlohmann::json& row : e[field]) {
            if (!row.is_array()) {
                throw ScenarioError(path, 0, 0,
                                    "entity '" + name + "': its " + field + " is not rows of numbers");
            }
            std::array<double, 3> r{0.0, 0.0, 0.0};
            for (std::size_t i = 0; i < std::min<std::size_t>(3, row.size()); ++i) {
                r[i] = jsonNumber(row[i]);
            }
            out.push_back(r);
        }
        return out;
    }

    void afterFrame() {
        std::vector<EventDef> applied = sim->takeAppliedEvents();
        if (recorder) {
            FrameRecord rec{std::move(applied),
                            frameHashes(sim->world(), sim->catalog(), entities, sim->pool()), entities};
            recorder->frame(rec);
        }
    }
};

Sandbox::Sandbox(const std::string& scenario, const std::vector<std::string>& sets, int threads)
    : m(std::make_unique<State>()) {
    m->path = resolveScenario(scenario);
    m->text = readScenarioFile(m->path);
    m->sets = sets;
    m->sim = std::make_unique<Simulation>(builtinCatalog(), m->path, m->text, sets, kDefaultMemoryCap,
                                          threadCount(threads));
}

Sandbox::State& Sandbox::live() const {
    if (!m) {
        throw std::logic_error("tumble::Sandbox: used after it was moved from");
    }
    return *m;
}

Sandbox::~Sandbox() {
    if (m && m->recorder) {
        try {
            m->recorder->finish();
        } catch (const std::exception&) {
            // a destructor cannot say it: finishRecording() does
        }
    }
}

Sandbox::Sandbox(Sandbox&&) noexcept = default;
Sandbox& Sandbox::operator=(Sandbox&&) noexcept = default;

void Sandbox::step(int frames) {
    State& s = live();
    if (frames < 0) {
        throw std::invalid_argument("step: frames must be 0 or more, not " + std::to_string(frames));
    }
    for (int i = 0; i < frames; ++i) {
        s.sim->runFrame();
        s.afterFrame();
    }
}

std::uint64_t Sandbox::frame() const {
    return live().sim->frame();
}

double Sandbox::time() const {
    return live().sim->time();
}

double Sandbox::dt() const {
    return live().sim->scene().dt;
}

std::map<std::string, std::string> Sandbox::entities() const {
    const State& s = live();
    std::vector<EntityHash> hashes;
    frameHashes(s.sim->world(), s.sim->catalog(), hashes, s.sim->pool());
    std::map<std::string, std::string> out;
    for (const EntityHash& e : hashes) {
        out[e.name] = e.kind;
    }
    return out;
}

std::vector<std::array<double, 3>> Sandbox::x(const std::string& entity) const {
    return live().rows(entity, "x");
}

std::vector<std::array<double, 3>> Sandbox::v(const std::string& entity) const {
    return live().rows(entity, "v");
}

int Sandbox::dimensions(const std::string& entity) const {
    return live().dumped(entity).second->kind == "rigid2d" ? 2 : 3;
}

void Sandbox::apply(const std::string& entity, const std::string& action, const std::vector<double>& value,
                    std::optional<std::array<double, 3>> position, std::optional<double> radius,
                    std::optional<double> amount) {
    State& s = live();
    EventDef ev;
    ev.step = s.sim->step();
    ev.entity = entity;
    ev.action = action;
    // the numbers as --input and a scenario take them (a replay refuses any other)
    if (value.size() > 4096) {
        throw ScenarioError("apply", 0, 0, "'value' has too many numbers (at most 4096)");
    }
    for (const double v : value) {
        ev.value.push_back(actionNumber(v, "value"));
    }
    std::vector<std::string> present;
    if (!value.empty()) {
        present.push_back("value");
    }
    if (position) {
        for (std::size_t k = 0; k < 3; ++k) {
            ev.position[k] = actionNumber((*position)[k], "position");
        }
        present.push_back("position");
    }
    if (radius) {
        ev.radius = actionNumber(*radius, "radius");
        present.push_back("radius");
    }
    if (amount) {
        ev.amount = actionNumber(*amount, "amount");
        present.push_back("amount");
    }
    if (action == "set") {
        throw ScenarioError("apply", 0, 0, "a set takes KEY=VALUE: call set(\"" + entity + ".KEY=VALUE\")");
    }
    if (auto problem = resolveEvent(s.sim->catalog(), s.sim->world(), ev, present)) {
        throw ScenarioError("apply", 0, 0, *problem);
    }
    s.sim->addEvents({ev});
}

void Sandbox::set(const std::string& keyValue) {
    State& s = live();
    EventDef ev;
    ev.step = s.sim->step();
    ev.action = "set";
    ev.set = keyValue;
    std::vector<EventDef> events = s.sim->pendingEvents();
    events.push_back(ev);
    if (auto problem = s.sim->checkSetEvents(events)) {
        throw ScenarioError("set", 0, 0, *problem);
    }
    s.sim->addEvents({ev});
}

std::uint64_t Sandbox::hash() const {
    return live().sim->hash();
}

std::string Sandbox::dump() const {
    std::string line;
    live().sim->appendDump(line);
    while (!line.empty() && line.back() == '\n') {
        line.pop_back();
    }
    return line;
}

std::string Sandbox::profile() const {
    Simulation& sim = *live().sim;
    return budgetSummaryJson(sim.profiler(), sim.scene(), sim.frame(), sim.threads());
}

std::vector<std::string> Sandbox::failures() const {
    return live().sim->world().resource<RunReport>().failures;
}

void Sandbox::record(const std::string& path) {
    State& s = live();
    if (s.sim->frame() > 0) {
        throw ScenarioError(path, 0, 0, "record before the first step: a replay starts at frame 0");
    }
    if (s.recorder) {
        throw ScenarioError(path, 0, 0,
                            "a replay is already being recorded here (" + s.recordingTo +
                                "): finish it first (finishRecording(); finish_recording() in Python)");
    }
    s.recorder =
        std::make_unique<ReplayWriter>(path, ReplayHeader{kReplayVersion, buildId(), s.path, s.text, s.sets});
    s.recordingTo = path;
}

void Sandbox::finishRecording() {
    State& s = live();
    if (s.recorder) {
        std::unique_ptr<ReplayWriter> recorder = std::move(s.recorder);
        recorder->finish();
    }
}

std::string verifyReplay(const std::string& path, int threads) {
    RunOptions o;
    o.scenario = path;
    o.verify = true;
    o.noRender = true;
    o.quiet = true;
    o.profile = "/dev/null"; // a run writes its budget summary somewhere: here nowhere
    std::string diverged;
    Source src = replaySource(path, true, threadCount(threads));
    src.diverged = &diverged;
    const bool complete = src.replay->complete;
    const std::uint64_t validBytes = src.replay->validBytes;
    const int code = runSession(builtinCatalog(), o, src);
    if (!diverged.empty()) {
        diverged = path + ": " + diverged; // which file, as the messages below say
    }
    if (diverged.empty() && code != kExitOk && code != kExitFailure) {
        // not a divergence, but not every frame checked either (an interrupt stopped it); a failure (a
        // blow-up) does not stop a run, and the recording met it too
        diverged =
            path + ": the replay's run stopped before its end (exit code " + std::to_string(code) + ")";
    }
    if (diverged.empty() && !complete) {
        diverged = path + ": the replay is cut short at byte " + std::to_string(validBytes) +
                   " (a recording that was stopped): the frames it holds match, the rest are not in it";
    }
    return diverged;
}

} // namespace tumble
