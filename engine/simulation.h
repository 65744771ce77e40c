#pragma once
// A simulation: one loaded scenario in one world, with the schedule built from the catalog's systems and
// the fixed-step loop that drives them. A frame runs, for each of its fixed steps, the input phase (events
// due at that step are applied at its start) and the fixed phase; then the frame phase once. Headless
// runs feed the loop exactly one frame period per frame, so every frame has `substeps` steps and no time
// is ever dropped: the same scenario gives the same bits.

#include "engine/catalog.h"
#include "engine/fixed_loop.h"
#include "engine/parallel.h"
#include "engine/profiler.h"
#include "engine/scenario.h"
#include "engine/schedule.h"
#include "engine/world.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace tumble {

/// The scripted events of a run, as a world resource; the engine's "events" input system applies them.
struct EventQueue {
    std::vector<EventDef> events;  ///< sorted by step
    std::size_t next = 0;          ///< first event not yet applied
    std::vector<EventDef> applied; ///< applied since the recorder last took them (in the order applied)
};

/// One scenario running in one world; see the header comment.
class Simulation {
public:
    /// Loads the scenario (throws ScenarioError), under a memory cap in bytes, and builds the schedule; the
    /// steps run on `threads` threads (0: defaultThreadCount(), which throws std::invalid_argument on a bad
    /// TUMBLE_THREADS).
    Simulation(const Catalog& catalog, const std::string& path, std::string text,
               const std::vector<std::string>& overrides, std::uint64_t memoryCap = kDefaultMemoryCap,
               int threads = 0);

    /// Threads the steps use (engine/parallel.h): any number gives the same bits.
    void setThreads(int threads);
    int threads() const { return m_pool->threads(); }
    /// The steps' workers, for other work between steps (the state hash).
    WorkerPool* pool() const { return m_pool.get(); }

    /// Advance one frame: exactly `substeps` fixed steps (headless, deterministic).
    void runFrame();
    /// Advance one frame paced by a clock: the steps the time since the last call completes, at most
    /// `substeps` (time beyond that is dropped and counted); the frame is drawn between the last two steps.
    void runFrameAt(const Clock& clock);
    /// A frame taken apart, for a caller that paces steps itself (the viewer): begin it, run any number
    /// of fixed steps, then end it, which runs the frame phase at `alpha` between the last two steps.
    void beginFrame();
    void runStep();
    void endFrame(double alpha);
    /// Real time dropped so far by runFrameAt, s, and the most steps any one frame took.
    double droppedSeconds() const { return static_cast<double>(m_droppedNs) * 1e-9; }
    int mostStepsInAFrame() const { return m_mostSteps; }

    /// Replaces the events still to come (resolved, sorted by step) with these: a replay's recorded ones.
    void setEvents(std::vector<EventDef> events);
    /// Adds events (resolved) to those still to come, after any due at the same step.
    void addEvents(const std::vector<EventDef>& events);
    /// The run's events, those applied and those to come, in the order they apply.
    const std::vector<EventDef>& pendingEvents();
    /// The events applied since the last call, in the order applied.
    std::vector<EventDef> takeAppliedEvents();
    /// Whether the `set` events among these (in the order they apply, from the start of the run) can be set:
    /// a message for the first that cannot (engine/retune.h). For events not from the scenario file.
    std::optional<std::string> checkSetEvents(const std::vector<EventDef>& events) const;

    const Scenario& scenario() const { return m_scenario; }
    const SceneDef& scene() const { return m_scenario.scene; }
    World& world() { return m_world; }
    const World& world() const { return m_world; }
    Profiler& profiler() { return m_profiler; }
    const Schedule& schedule() const { return m_schedule; }
    Schedule& schedule() { return m_schedule; }
    const Catalog& catalog() const { return m_catalog; }

    std::uint64_t frame() const { return m_frame; } ///< frames completed
    std::uint64_t step() const { return m_step; }   ///< fixed steps completed
    double time() const { return static_cast<double>(m_step) * m_scenario.scene.dt; } ///< simulated, s

    std::uint64_t hash() const;
    void appendDump(std::string& out) const;

private:
    const Catalog& m_catalog;
    std::unique_ptr<WorkerPool> m_pool;
    World m_world;
    Profiler m_profiler;
    Schedule m_schedule;
    Scenario m_scenario;
    FixedLoop m_loop;
    std::uint64_t m_frame = 0;
    std::int64_t m_droppedNs = 0;
    int m_mostSteps = 0;
    void runSteps(int steps, double alpha);
    std::uint64_t m_step = 0;
    StepContext m_ctx; ///< the frame being run
    std::uint64_t m_memoryCap;
    std::vector<std::string> m_sets; ///< the set events applied so far, in order (each retune loads them)
    /// The input phase's "events" system: applies the events due at this step, in file order.
    void applyEvents(const StepContext& ctx);
};

/// The budget summary (README, "Budgets"), as JSON.
std::string budgetSummaryJson(const Profiler& profiler, const SceneDef& scene, std::uint64_t frames,
                              int threads);

} // namespace tumble
