#include "engine/schedule.h"

#include "engine/parallel.h"

#include <algorithm>
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
    auto& entries = m_phases[int(phase)];
    std::vector<std::size_t> after;
    for (std::size_t i = 0; i < entries.size(); ++i) {
        if (entries[i].access.conflictsWith(access)) {
            after.push_back(i);
        }
    }
    const int slot = m_profiler.addSlot(name, phase, false);
    entries.push_back(Entry{std::move(name), std::move(fn), std::move(access), slot, std::move(after)});
}

void Schedule::runSystem(Entry& e, Run& run, std::size_t i, World& world, const StepContext& ctx) {
    const std::int64_t start = m_profiler.nowNs();
    {
        World::AccessScope declared(world, e.name, e.access, &run.queues[i]);
        e.fn(world, ctx);
    }
    run.ns[i] = m_profiler.nowNs() - start;
    m_profiler.record(e.slot, start, run.ns[i]);
}

void Schedule::Run::prepare(World& w, std::size_t n) {
    if (world != &w || queues.size() != n) {
        world = &w;
        done = std::make_unique<std::atomic<bool>[]>(n);
        ns.assign(n, 0);
        queues.assign(n, Commands(w));
    }
    for (std::size_t i = 0; i < n; ++i) {
        done[i].store(false, std::memory_order_relaxed);
        ns[i] = 0;
    }
}

void Schedule::run(Phase phase, World& world, const StepContext& ctx) {
    TUMBLE_PROFILE_SCOPE(m_profiler, m_phaseSlots[int(phase)]);
    auto& entries = m_phases[int(phase)];
    const std::size_t n = entries.size();
    Run& run = m_runs[int(phase)];
    run.prepare(world, n);
    // side by side only where it can pay: on the first run, and then while the last run's systems took
    // longer in all than their critical path by more than handing systems between threads costs (a
    // small scene's systems of a few microseconds each run faster on one thread). Only the speed depends
    // on this choice: the bits are the same either way.
    const bool sideBySide = ctx.pool && ctx.pool->threads() > 1 && n >= 2 &&
                            (m_alwaysSideBySide || run.gainNs >= kSideBySideGainNs);
    if (!sideBySide) {
        for (std::size_t i = 0; i < n; ++i) {
            runSystem(entries[i], run, i, world, ctx);
        }
    } else {
        std::atomic<bool> failed{false};
        ctx.pool->runTasks(
            n,
            [&](std::size_t i) {
                return std::all_of(entries[i].after.begin(), entries[i].after.end(), [&](std::size_t d) {
                    return run.done[d].load(std::memory_order_acquire);
                });
            },
            [&](std::size_t i) {
                // marked done even when it throws, so that nothing waits for it forever; once one has
                // thrown, the systems not yet started are skipped (the pool rethrows the first error)
                struct Done {
                    std::atomic<bool>& flag;
                    ~Done() { flag.store(true, std::memory_order_release); }
                } done{run.done[i]};
                if (failed.load(std::memory_order_acquire)) {
                    return;
                }
                try {
                    runSystem(entries[i], run, i, world, ctx);
                } catch (...) {
                    failed.store(true, std::memory_order_release);
                    throw;
                }
            });
    }
    const std::int64_t critical = criticalPathNs(entries, run.ns);
    std::int64_t total = 0;
    for (std::int64_t ns : run.ns) {
        total += ns;
    }
    run.gainNs = total - critical;
    if (phase == Phase::Fixed) {
        m_profiler.addCriticalPath(critical);
    }
    for (Commands& queue : run.queues) {
        queue.flush();
    }
    world.commands().flush();
}

std::int64_t Schedule::criticalPathNs(const std::vector<Entry>& entries,
                                      const std::vector<std::int64_t>& ns) const {
    // the latest each system could finish on unlimited threads: its time after the latest of those it waits
    // for
    std::vector<std::int64_t> finish(entries.size(), 0);
    std::int64_t longest = 0;
    for (std::size_t i = 0; i < entries.size(); ++i) {
        std::int64_t start = 0;
        for (std::size_t d : entries[i].after) {
            start = std::max(start, finish[d]);
        }
        finish[i] = start + ns[i];
        longest = std::max(longest, finish[i]);
    }
    return longest;
}

std::vector<std::string> Schedule::names(Phase phase) const {
    std::vector<std::string> out;
    for (const Entry& e : m_phases[int(phase)]) {
        out.push_back(e.name);
    }
    return out;
}

std::vector<std::vector<std::size_t>> Schedule::waitsFor(Phase phase) const {
    std::vector<std::vector<std::size_t>> out;
    for (const Entry& e : m_phases[int(phase)]) {
        out.push_back(e.after);
    }
    return out;
}

} // namespace tumble
