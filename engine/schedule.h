#pragma once
// The schedule: systems registered into phases, run in the order they were registered. Order within a
// phase is stated by registration (systems/builtin.cpp lists the fixed phase in the order
// docs/architecture.md explains), never by systems naming each other. Each system and each phase runs inside
// a profiler timer, and the world's queued structural changes are applied when a phase ends. While a system
// runs, the world holds its declared access (engine/access.h) and refuses anything undeclared.

#include "engine/access.h"
#include "engine/phase.h"
#include "engine/profiler.h"
#include "engine/step_context.h"
#include "engine/world.h"

#include <functional>
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

    /// Run every system of the phase in order, then apply the world's queued changes.
    void run(Phase phase, World& world, const StepContext& ctx);

    /// Names of a phase's systems, in run order.
    std::vector<std::string> names(Phase phase) const;

private:
    struct Entry {
        std::string name;
        SystemFn fn;
        Access access;
        int slot; ///< profiler slot
    };
    Profiler& m_profiler;
    std::vector<Entry> m_phases[3];
    int m_phaseSlots[3];
};

} // namespace tumble
