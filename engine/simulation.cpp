#include "engine/simulation.h"

#include "engine/dump.h"
#include "engine/float_mode.h"
#include "engine/json.h"
#include "engine/retune.h"
#include "engine/run_report.h"

#include <algorithm>
#include <cmath>

namespace tumble {

namespace {} // namespace

void Simulation::applyEvents(const StepContext& ctx) {
    EventQueue& queue = m_world.resource<EventQueue>();
    while (queue.next < queue.events.size() && queue.events[queue.next].step <= ctx.step) {
        const EventDef& ev = queue.events[queue.next++];
        if (ev.action == "set") {
            // checked when it was loaded, against the sets before it (engine/retune.h)
            applySet(m_catalog, m_scenario, m_sets, ev.set, m_memoryCap, m_world, m_scenario.scene);
            m_sets.push_back(ev.set);
            m_profiler.setPhysicsBudgetMs(m_scenario.scene.physicsBudgetMs);
        } else if (m_world.alive(ev.target)) {
            // the loader resolved the entity and the action; the entity may have been destroyed since
            m_catalog.actions()[ev.actionIndex].apply(m_world, ev.target, ev);
        }
        queue.applied.push_back(ev);
    }
}

std::optional<std::string> Simulation::checkSetEvents(const std::vector<EventDef>& events) const {
    const auto sets = std::size_t(
        std::count_if(events.begin(), events.end(), [](const EventDef& ev) { return ev.action == "set"; }));
    if (sets > Limits::kMaxSetEvents) { // (the scenario's own and those of --input or a replay, together)
        return std::to_string(sets) + " set events; at most " + std::to_string(Limits::kMaxSetEvents) +
               " (each loads the scene twice to see what it changes)";
    }
    std::vector<std::string> earlier;
    for (const EventDef& ev : events) {
        if (ev.action != "set") {
            continue;
        }
        if (auto problem = checkSet(m_catalog, m_scenario, earlier, ev.set, m_memoryCap)) {
            return problem;
        }
        earlier.push_back(ev.set);
    }
    return std::nullopt;
}

Simulation::Simulation(const Catalog& catalog, const std::string& path, std::string text,
                       const std::vector<std::string>& overrides, std::uint64_t memoryCap, int threads)
    : m_catalog(catalog), m_pool(std::make_unique<WorkerPool>(threads > 0 ? threads : defaultThreadCount())),
      m_schedule(m_profiler),
      m_scenario(loadScenario(catalog, path, std::move(text), overrides, m_world, memoryCap)),
      m_loop(secondsToNs(m_scenario.scene.dt), m_scenario.scene.substeps), m_memoryCap(memoryCap) {
    m_profiler.setPhysicsBudgetMs(m_scenario.scene.physicsBudgetMs);
    m_world.setResource<SceneDef>(m_scenario.scene);
    m_world.setResource<RunReport>();
    m_world.setResource<EventQueue>(EventQueue{m_scenario.events, 0, {}});
    // the event actions touch whatever the catalog's systems registered them for: nothing runs beside
    m_schedule.add(
        Phase::Input, "events", [this](World&, const StepContext& ctx) { applyEvents(ctx); },
        Access::everything());
    for (const SystemEntry& s : catalog.systems()) {
        m_schedule.add(s.phase, s.name, s.fn, s.access);
    }
}

void Simulation::runFrame() {
    // headless: exactly one frame period per frame, so exactly `substeps` steps; the frame ends exactly on
    // a step and is drawn as that step left it (alpha 1)
    const Tick tick = m_loop.advance(m_loop.stepNs() * m_scenario.scene.substeps);
    runSteps(tick.steps, 1.0);
}

void Simulation::runFrameAt(const Clock& clock) {
    const Tick tick = m_loop.advanceTo(clock);
    m_droppedNs += tick.droppedNs;
    // a loop paced by a clock draws one step behind, at leftover / step between the last two
    runSteps(tick.steps, tick.alpha);
}

void Simulation::runSteps(int steps, double alpha) {
    beginFrame();
    for (int i = 0; i < steps; ++i) {
        runStep();
    }
    m_mostSteps = std::max(m_mostSteps, steps);
    endFrame(alpha);
}

void Simulation::beginFrame() {
    const SceneDef& scene = m_scenario.scene;
    m_profiler.beginFrame(m_frame);
    m_ctx = StepContext{};
    m_ctx.dt = scene.dt;
    m_ctx.seed = scene.seed;
    m_ctx.frame = m_frame;
    m_ctx.profiler = &m_profiler;
    m_ctx.pool = m_pool.get();
}

void Simulation::setThreads(int threads) {
    if (threads != m_pool->threads()) {
        m_pool = std::make_unique<WorkerPool>(threads);
        m_ctx.pool = m_pool.get();
    }
}

void Simulation::runStep() {
    const FlushDenormals flush; // see engine/float_mode.h
    m_ctx.step = m_step;
    m_ctx.time = static_cast<double>(m_step) * m_scenario.scene.dt;
    m_schedule.run(Phase::Input, m_world, m_ctx);
    m_schedule.run(Phase::Fixed, m_world, m_ctx);
    ++m_step;
}

void Simulation::endFrame(double alpha) {
    m_ctx.time = time();
    m_ctx.alpha = alpha;
    m_schedule.run(Phase::Frame, m_world, m_ctx);
    m_profiler.endFrame();
    ++m_frame;
}

void Simulation::setEvents(std::vector<EventDef> events) {
    EventQueue& queue = m_world.resource<EventQueue>();
    queue.events = std::move(events);
    queue.next = 0;
}

void Simulation::addEvents(const std::vector<EventDef>& events) {
    EventQueue& queue = m_world.resource<EventQueue>();
    std::vector<EventDef> merged(queue.events.begin() + std::ptrdiff_t(queue.next), queue.events.end());
    merged.insert(merged.end(), events.begin(), events.end());
    std::stable_sort(merged.begin(), merged.end(),
                     [](const EventDef& a, const EventDef& b) { return a.step < b.step; });
    queue.events = std::move(merged);
    queue.next = 0;
}

const std::vector<EventDef>& Simulation::pendingEvents() {
    return m_world.resource<EventQueue>().events;
}

std::vector<EventDef> Simulation::takeAppliedEvents() {
    std::vector<EventDef> out;
    out.swap(m_world.resource<EventQueue>().applied);
    return out;
}

std::uint64_t Simulation::hash() const {
    return stateHash(m_world, m_catalog, m_pool.get());
}

void Simulation::appendDump(std::string& out) const {
    appendDumpLine(out, m_world, m_catalog, m_frame, time(), hash());
}

namespace {
/// Milliseconds to the nanosecond: the clock's resolution, and short to read.
double roundMs(double ms) {
    return std::round(ms * 1e6) / 1e6;
}
} // namespace

std::string budgetSummaryJson(const Profiler& profiler, const SceneDef& scene, std::uint64_t frames,
                              int threads) {
    std::string out;
    JsonWriter w(out);
    const FrameStats f = profiler.frameStats();
    w.beginObject().key("scene").value(scene.name).key("frames").value(frames).key("dt").value(scene.dt);
    w.key("substeps").value(scene.substeps).key("threads").value(threads);
    w.key("budget").beginObject().key("physics_ms").value(scene.physicsBudgetMs);
    w.key("frame_ms").value(roundMs(scene.frameSeconds() * 1000.0)).endObject();
    const std::vector<SlotStats> stats = profiler.slotStats();
    auto slots = [&](bool phases) {
        for (const SlotStats& s : stats) {
            if (s.isPhase != phases) {
                continue;
            }
            w.beginObject().key("name").value(s.name).key("phase").value(phaseName(s.phase));
            if (!s.stageOf.empty()) {
                w.key("stage_of").value(s.stageOf); // a stage inside that system, listed after it
            }
            w.key("calls").value(s.calls).key("mean_ms").value(roundMs(s.meanMs));
            w.key("p50_ms").value(roundMs(s.p50Ms)).key("p99_ms").value(roundMs(s.p99Ms));
            w.key("max_ms").value(roundMs(s.maxMs)).endObject();
        }
    };
    w.key("systems").beginArray();
    slots(false);
    w.endArray().key("phases").beginArray();
    slots(true);
    w.endArray();
    w.key("frame").beginObject().key("physics_p50_ms").value(roundMs(f.physicsP50Ms));
    w.key("physics_p99_ms")
        .value(roundMs(f.physicsP99Ms))
        .key("physics_max_ms")
        .value(roundMs(f.physicsMaxMs));
    w.key("critical_path_p50_ms").value(roundMs(f.criticalP50Ms));
    w.key("critical_path_p99_ms").value(roundMs(f.criticalP99Ms));
    w.key("render_p50_ms").value(roundMs(f.renderP50Ms)).key("over_budget_frames").value(f.overBudgetFrames);
    w.endObject();
    // what systems count of their work, a report a step (the crossed pairs cloth contact untangles, say)
    w.key("counters").beginArray();
    for (const CounterStats& c : profiler.counterStats()) {
        w.beginObject().key("name").value(c.name).key("samples").value(c.samples);
        w.key("nonzero").value(c.nonzero).key("max").value(c.max).key("last").value(c.last).endObject();
    }
    w.endArray().endObject();
    out += '\n';
    return out;
}

} // namespace tumble
