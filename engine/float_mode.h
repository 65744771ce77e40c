#pragma once
// Denormal numbers (magnitudes below about 1e-38 in float, 1e-308 in double) flushed to zero while the
// simulation steps. A cloth coming to rest fills the implicit solver's float vectors with them, and on some
// processors every operation on one costs a hundred times a normal one: the drape demo's springs took 10.5
// ms a step p99 (1.8 ms p50) instead of 1.0 (0.46) on the machine of 2026-11-24. Flushing is itself
// deterministic (the same bits on every machine of the architecture), so replays still verify anywhere;
// the mode is set for the step and put back after it, so that a program that embeds Tumble keeps its own.
// A worker thread that runs part of a step takes the mode of the thread that handed it the work
// (engine/parallel.cpp, with floatMode and setFloatMode), so every thread of a step computes alike.

#include <cstdint>

namespace tumble {

/// Flushes denormals to zero (FTZ and DAZ on x86-64, FZ on AArch64) from construction to destruction.
class FlushDenormals {
public:
    FlushDenormals();
    ~FlushDenormals();
    FlushDenormals(const FlushDenormals&) = delete;
    FlushDenormals& operator=(const FlushDenormals&) = delete;

private:
    std::uint64_t m_saved = 0;
};

/// This thread's floating-point control word (MXCSR on x86-64, FPCR on AArch64; 0 elsewhere).
std::uint64_t floatMode();
/// Sets this thread's floating-point control word to one floatMode() returned.
void setFloatMode(std::uint64_t mode);

} // namespace tumble
