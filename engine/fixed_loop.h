#pragma once
// The fixed-timestep loop (Fiedler, "Fix your timestep!"). Elapsed time goes into an accumulator counted in
// whole nanoseconds, so it never drifts; each whole step in it is one fixed step of physics. Steps per
// frame are capped so that a slow frame cannot cause a slower next one (the spiral of death): time beyond
// the cap is dropped and reported. What is left in the accumulator, as a fraction of a step, is the
// interpolation factor that rendering uses between the last two fixed states.
//
// Headless runs feed exactly one frame period per frame, so they take the same number of steps every
// frame and never drop any; only real-time pacing reads a clock.

#include <cstdint>

namespace tumble {

/// A source of monotonic time; the loop is tested with a fake one.
class Clock {
public:
    virtual ~Clock() = default;
    virtual std::int64_t nowNs() const = 0;
};

/// The process's steady clock.
class SteadyClock final : public Clock {
public:
    std::int64_t nowNs() const override;
};

/// Converts seconds to whole nanoseconds (rounded to nearest, at least 1).
std::int64_t secondsToNs(double seconds);

/// How far one frame advances: see the header comment.
struct Tick {
    int steps = 0;              ///< fixed steps to run now
    std::int64_t droppedNs = 0; ///< time thrown away by the cap this frame
    double alpha = 0.0;         ///< leftover / step, in [0, 1)
};

/// Integer-nanosecond accumulator with a cap on steps per frame.
class FixedLoop {
public:
    FixedLoop(std::int64_t stepNs, int maxStepsPerFrame);

    /// Add elapsed time and take the whole steps it completes.
    Tick advance(std::int64_t elapsedNs);
    /// Advance by the time since the previous call (the first call only starts the clock: zero steps).
    Tick advanceTo(const Clock& clock);

    std::int64_t stepNs() const { return m_stepNs; }
    int maxStepsPerFrame() const { return m_maxSteps; }
    std::int64_t accumulatorNs() const { return m_accumulatorNs; }

private:
    std::int64_t m_stepNs;
    int m_maxSteps;
    std::int64_t m_accumulatorNs = 0;
    std::int64_t m_lastNs = 0;
    bool m_started = false;
};

} // namespace tumble
