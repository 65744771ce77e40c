#pragma once
// The schedule: systems registered into phases, in a stated order. Order within a phase is stated by
// registration (systems/builtin.cpp lists the fixed phase in the order docs/architecture.md explains),
// never by systems naming each other. Each system and each phase runs inside a profiler timer. While a
// system runs, the world holds its declared access (engine/access.h) and refuses anything undeclared.
//
// Side by side. A system conflicts with an earlier one of its phase when either writes a type the other
// reads or writes (Access::conflictsWith). With more than one thread, systems start in table order as
// threads come free, and each starts only once every earlier system it conflicts with has finished. So
// every type is written by its systems in table order and read between the same writes as on one thread:
// the world ends each phase with the same bits at any thread count. Each system queues its structural
// changes in its own queue; the queues are applied in table order when the phase ends, then the world's
// own (changes queued while applying them).
//
// Side by side only where it can pay: the first run of a phase is, and after it a phase runs side by
// side while its systems' total time exceeds their critical path by kSideBySideGainNs (handing systems
// between threads costs some microseconds each; a light scene runs faster on one thread). The choice
// changes only the speed, never a bit. Systems split their own loops over the threads either way.
//
// The frame's critical path: for every run of the fixed phase, the longest chain of systems each waiting
// for the one before (by the conflicts above), with the times they took: what that phase would cost with
// a thread for every system. The profiler sums it over the frame's steps (FrameStats::criticalP50Ms).

#include "engine/access.h"
#include "engine/phase.h"
#include "engine/profiler.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <atomic>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace tumble {

/// What a system is: a function of the world and the step.
using SystemFn = std::function<void(World& world, const StepContext& ctx)>;

/// Systems by phase, in registration order; see the header comment.
class Schedule {
public:
    explicit Schedule(Profiler& profiler);

    /// Register a system at the end of a phase, with what it reads and writes. Names must be unique; they
    /// label the profile and trace.
    void add(Phase phase, std::string name, SystemFn fn, Access access);

    /// Run every system of the phase (side by side where ctx.pool has threads and they do not conflict),
    /// then apply the queued structural changes; see the header comment.
    void run(Phase phase, World& world, const StepContext& ctx);

    /// Run systems side by side at every run, not only where it pays (for the tests of the bits).
    void setAlwaysSideBySide(bool always) { m_alwaysSideBySide = always; }

    /// Names of a phase's systems, in run order.
    std::vector<std::string> names(Phase phase) const;
    /// For each system of a phase, the earlier systems of the phase it waits for (their indices).
    std::vector<std::vector<std::size_t>> waitsFor(Phase phase) const;

private:
    struct Entry {
        std::string name;
        SystemFn fn;
        Access access;
        int slot;                       ///< profiler slot
        std::vector<std::size_t> after; ///< earlier systems of the phase it conflicts with
    };
    /// What a run of a phase keeps per system (kept between runs, so a step allocates nothing here).
    struct Run {
        World* world = nullptr; ///< the queues' world
        std::unique_ptr<std::atomic<bool>[]> done;
        std::vector<std::int64_t> ns;
        std::vector<Commands> queues;
        /// What running side by side could save, judged by the last run (a first run assumes it pays).
        std::int64_t gainNs = std::numeric_limits<std::int64_t>::max();
        void prepare(World& w, std::size_t n);
    };
    static constexpr std::int64_t kSideBySideGainNs = 200'000;
    void runSystem(Entry& e, Run& run, std::size_t i, World& world, const StepContext& ctx);
    std::int64_t criticalPathNs(const std::vector<Entry>& entries, const std::vector<std::int64_t>& ns) const;

    Profiler& m_profiler;
    std::vector<Entry> m_phases[3];
    int m_phaseSlots[3];
    Run m_runs[3];
    bool m_alwaysSideBySide = false;
};

} // namespace tumble
