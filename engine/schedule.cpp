#include "engine/schedule.h"

#include <stdexcept>

namespace tumble {

Schedule::Schedule(Profiler& profiler) : m_profiler(profiler) {
    for (Phase p : {Phase::Input, Phase::Fixed, Phase::Frame}) {
        m_phaseSlots[int(p)] = profiler.addSlot(std::string("phase:") + std::string(phaseName(p)), p, true);
    }
}

void Schedule::add(Phase phase, std::string name, SystemFn fn, Access access) {
    for (const auto& entries : m_phases) {
        for (const Entry& e : entries) {
            if (e.name == name) {
                throw std::logic_error("schedule: a system named '" + name + "' is already registered");
            }
        }
    }
    const int slot = m_profiler.addSlot(name, phase, false);
    m_phases[int(phase)].push_back(Entry{std::move(name), std::move(fn), std::move(access), slot});
}

void Schedule::run(Phase phase, World& world, const StepContext& ctx) {
    TUMBLE_PROFILE_SCOPE(m_profiler, m_phaseSlots[int(phase)]);
    for (Entry& e : m_phases[int(phase)]) {
        TUMBLE_PROFILE_SCOPE(m_profiler, e.slot);
        World::AccessScope declared(world, e.name, e.access);
        e.fn(world, ctx);
    }
    world.commands().flush();
}

std::vector<std::string> Schedule::names(Phase phase) const {
    std::vector<std::string> out;
    for (const Entry& e : m_phases[int(phase)]) {
        out.push_back(e.name);
    }
    return out;
}

} // namespace tumble
