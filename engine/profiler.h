#pragma once
// The budget profiler. Every system and every phase runs inside a ScopedTimer; each timer slot keeps its
// call count, sum and maximum over the whole run and its most recent durations in a ring buffer, from which
// p50 and p99 are taken. Per frame it sums the fixed phase (physics) and the frame phase (render and
// outputs), so a run can say how often physics overran its budget. With tracing on, every timed scope is
// also kept as a Chrome trace event (loads in Perfetto or chrome://tracing).
//
// Systems running side by side record from several threads: every record takes a mutex (uncontended
// but for the rare instant two systems end together), and each trace event keeps the thread it ran on,
// one track per worker. The frame's critical path (engine/schedule.h) is summed next to its physics time.
//
// Cost: two steady_clock reads and a few stores per scope (tens of nanoseconds; tests/bench measures it),
// far under 1% of a 16.7 ms frame for the few dozen scopes a frame has.

#include "engine/phase.h"

#include <chrono>
#include <cstdint>
#include <mutex>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace tumble {

/// Timing statistics of one timer slot (a system or a phase), in milliseconds.
struct SlotStats {
    std::string name;
    Phase phase = Phase::Fixed;
    bool isPhase = false; ///< true for a whole-phase timer, false for a system
    /// for a stage inside a system ("springs.solve"): the system ("springs"); empty for a stage of no system
    std::string stageOf;
    std::uint64_t calls = 0;
    double meanMs = 0.0; ///< over every call of the run
    double p50Ms = 0.0;  ///< over the calls still in the ring buffer
    double p99Ms = 0.0;
    double maxMs = 0.0; ///< over every call of the run
};

/// A count a system reports once a step (a figure of its work, not a time: the crossed pairs of triangles
/// cloth contact is untangling, say), summed up over the run.
struct CounterStats {
    std::string name;
    std::uint64_t samples = 0; ///< reports
    std::uint64_t nonzero = 0; ///< reports that were not zero
    double max = 0.0;
    double last = 0.0;
};

/// A slot's recent time, for a live display (tumble view's overlay).
struct RecentSlot {
    std::string name;
    Phase phase = Phase::Fixed;
    bool isPhase = false;
    double meanMs = 0.0; ///< over its last calls
};

/// Per-frame statistics, in milliseconds.
struct FrameStats {
    std::uint64_t frames = 0;
    double physicsP50Ms = 0.0;
    double physicsP99Ms = 0.0;
    double physicsMaxMs = 0.0;
    double criticalP50Ms = 0.0; ///< the fixed phase's critical path (engine/schedule.h), summed over a frame
    double criticalP99Ms = 0.0;
    double renderP50Ms = 0.0;
    std::uint64_t overBudgetFrames = 0; ///< frames whose physics took longer than the budget
};

/// Times systems and phases; see the header comment.
class Profiler {
public:
    /// ringCapacity: how many recent samples each slot and the frame record keep for percentiles (the
    /// default, 65536, is 18 minutes of frames at 60 fps; max, mean and over-budget counts cover every call).
    explicit Profiler(std::size_t ringCapacity = 1u << 16);

    /// Trace events kept at most (32 bytes each); a longer traced run keeps its first events and says so.
    static constexpr std::size_t kMaxTraceEvents = 4u << 20;

    /// A new timer slot; the returned id is what ScopedTimer takes.
    int addSlot(std::string name, Phase phase, bool isPhase);
    std::size_t slotCount() const { return m_slots.size(); }
    /// The slot of a stage inside a system ("system.stage"), made on first use: Box2D's b2Profile
    /// idea, so a system's cost can be seen stage by stage. Stages are not phases: they do not add to
    /// the frame's physics time, which their system's phase already holds. slotStats() lists each stage
    /// right after its system.
    int stageSlot(std::string_view name, Phase phase);
    /// The id of a counter, made on first use.
    int counterSlot(std::string_view name);
    /// One report of a counter.
    void count(int counter, double value) noexcept;
    std::vector<CounterStats> counterStats() const {
        std::lock_guard lock(m_mutex);
        return m_counters;
    }

    /// Keep every timed scope as a trace event (memory grows with the run).
    void enableTrace(bool on) { m_trace = on; }
    /// The budget that frames are counted against, ms of physics per frame.
    void setPhysicsBudgetMs(double ms) { m_budgetNs = static_cast<std::int64_t>(ms * 1e6); }

    void beginFrame(std::uint64_t frame);
    void endFrame();

    /// Nanoseconds since the profiler was made (steady clock).
    std::int64_t nowNs() const {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(TimeSource::now() - m_origin).count();
    }
    /// One timed scope of a slot. Never throws (it runs in destructors).
    void record(int slot, std::int64_t startNs, std::int64_t durationNs) noexcept;
    /// The critical path of one run of the fixed phase, added to the frame's.
    void addCriticalPath(std::int64_t ns) noexcept;

    std::vector<SlotStats> slotStats() const;
    FrameStats frameStats() const;
    /// Physics ms of each frame still in the ring, oldest first.
    std::vector<float> physicsHistory() const;
    /// Each slot's mean over its last n calls, and the physics ms of the last n frames (oldest first):
    /// cheap enough to ask every frame (no sorting).
    std::vector<RecentSlot> recentStats(std::size_t n) const;
    std::vector<float> recentPhysics(std::size_t n) const;
    double budgetMs() const { return static_cast<double>(m_budgetNs) * 1e-6; }

    /// Writes Chrome trace-event JSON (the "traceEvents" object form): one complete event per timed scope,
    /// and one per frame. Streams, so a long trace never exists twice in memory.
    void writeTrace(std::ostream& out) const;
    std::size_t traceEventCount() const { return m_events.size(); }
    /// True when the trace stopped keeping events at kMaxTraceEvents (or memory ran out).
    bool traceTruncated() const { return m_traceTruncated; }

private:
    using TimeSource = std::chrono::steady_clock;

    struct Ring {
        std::vector<float> samples; ///< ms, most recent ringCapacity
        std::size_t next = 0;
        void push(float ms, std::size_t capacity);
        double percentile(double p) const;
        /// The last n samples, oldest first.
        std::vector<float> last(std::size_t n) const;
    };
    struct Slot {
        std::string name;
        Phase phase;
        bool isPhase;
        std::string stageOf; ///< a stage's system, else empty
        std::uint64_t calls = 0;
        std::int64_t sumNs = 0;
        std::int64_t maxNs = 0;
        Ring recent;
    };
    struct TraceEvent {
        int slot;  ///< -1 for a whole frame
        int track; ///< the thread: 0 the caller's, 1.. the pool's workers (WorkerPool::threadIndex)
        std::uint64_t frame;
        std::int64_t startNs;
        std::int64_t durationNs;
    };

    mutable std::mutex m_mutex; ///< records come from several threads
    TimeSource::time_point m_origin;
    std::size_t m_capacity;
    std::vector<Slot> m_slots;
    std::vector<CounterStats> m_counters;
    bool m_trace = false;
    std::vector<TraceEvent> m_events;
    bool m_traceTruncated = false;
    std::int64_t m_budgetNs = 8'000'000;

    // the frame being timed
    std::uint64_t m_frame = 0;
    std::int64_t m_frameStartNs = 0;
    std::int64_t m_framePhysicsNs = 0;
    std::int64_t m_frameRenderNs = 0;
    std::int64_t m_frameCriticalNs = 0;

    // over the run
    std::uint64_t m_frames = 0;
    std::uint64_t m_overBudget = 0;
    std::int64_t m_physicsMaxNs = 0;
    Ring m_physics;
    Ring m_render;
    Ring m_critical;

    void keepTraceEvent(const TraceEvent& e) noexcept;
    int addSlotLocked(std::string name, Phase phase, bool isPhase);
};

/// Times the enclosing scope into a profiler slot.
class ScopedTimer {
public:
    ScopedTimer(Profiler& profiler, int slot)
        : m_profiler(profiler), m_slot(slot), m_start(profiler.nowNs()) {}
    ~ScopedTimer() { m_profiler.record(m_slot, m_start, m_profiler.nowNs() - m_start); }
    ScopedTimer(const ScopedTimer&) = delete;
    ScopedTimer& operator=(const ScopedTimer&) = delete;

private:
    Profiler& m_profiler;
    int m_slot;
    std::int64_t m_start;
};

#define TUMBLE_CONCAT_INNER(a, b) a##b
#define TUMBLE_CONCAT(a, b) TUMBLE_CONCAT_INNER(a, b)
/// Times a stage inside a system (name "system.stage") into its own slot, listed under the system in the
/// budget table, the profile and the trace; does nothing without a profiler (an untimed run).
class ProfileStage {
public:
    ProfileStage(Profiler* profiler, std::string_view name)
        : m_profiler(profiler), m_slot(profiler ? profiler->stageSlot(name, Phase::Fixed) : -1),
          m_startNs(profiler ? profiler->nowNs() : 0) {}
    ~ProfileStage() {
        if (m_profiler) {
            m_profiler->record(m_slot, m_startNs, m_profiler->nowNs() - m_startNs);
        }
    }
    ProfileStage(const ProfileStage&) = delete;
    ProfileStage& operator=(const ProfileStage&) = delete;

private:
    Profiler* m_profiler;
    int m_slot;
    std::int64_t m_startNs;
};

/// Times the rest of the enclosing scope into the given profiler slot.
#define TUMBLE_PROFILE_SCOPE(profiler, slot)                                                                 \
    ::tumble::ScopedTimer TUMBLE_CONCAT(tumbleScopedTimer, __LINE__)(profiler, slot)

} // namespace tumble
