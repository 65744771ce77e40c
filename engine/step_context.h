#pragma once
// What a system is told about the step it runs in. Recreated for every step; systems read the time from
// here, never from the wall clock, so that a run is the same bits every time.

#include <cstdint>

namespace tumble {

class Profiler;
class WorkerPool;

/// Context for one run of a phase.
struct StepContext {
    double dt = 1.0 / 60.0;  ///< fixed physics step, s (the scene's dt)
    std::uint64_t step = 0;  ///< index of this fixed step since the start (fixed phase)
    std::uint64_t frame = 0; ///< index of the frame being produced
    double time = 0.0;       ///< simulated time at the start of this step, s (= step * dt)
    std::uint64_t seed = 1;  ///< the scene seed; derive per-purpose streams with streamSeed()
    double alpha =
        1.0; ///< frame phase: where the frame falls between the last two fixed steps (1: at the last)
    Profiler* profiler = nullptr; ///< for a system that times its own stages (profileSlot); null when untimed
    WorkerPool* pool = nullptr;   ///< for a system's chunked loops (engine/parallel.h); null: one thread
};

} // namespace tumble
