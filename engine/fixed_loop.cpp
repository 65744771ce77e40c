#include "engine/fixed_loop.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace tumble {

std::int64_t SteadyClock::nowNs() const {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

std::int64_t secondsToNs(double seconds) {
    return std::max<std::int64_t>(1, static_cast<std::int64_t>(std::llround(seconds * 1e9)));
}

FixedLoop::FixedLoop(std::int64_t stepNs, int maxStepsPerFrame)
    : m_stepNs(stepNs), m_maxSteps(maxStepsPerFrame) {
    if (stepNs <= 0 || maxStepsPerFrame <= 0) {
        throw std::invalid_argument("fixed loop: the step and the cap must be positive");
    }
}

Tick FixedLoop::advance(std::int64_t elapsedNs) {
    Tick t;
    // whole steps beyond the cap plus one are dropped anyway; dropping them first (keeping the fraction of a
    // step) means a clock jump cannot overflow the accumulator
    std::int64_t elapsed = std::max<std::int64_t>(elapsedNs, 0);
    const std::int64_t most = (std::int64_t(m_maxSteps) + 1) * m_stepNs;
    if (elapsed > most) {
        const std::int64_t excess = elapsed - most;
        t.droppedNs = excess - excess % m_stepNs;
        elapsed -= t.droppedNs;
    }
    m_accumulatorNs += elapsed;
    const std::int64_t whole = m_accumulatorNs / m_stepNs;
    t.steps = static_cast<int>(std::min<std::int64_t>(whole, m_maxSteps));
    m_accumulatorNs -= std::int64_t(t.steps) * m_stepNs;
    if (whole > m_maxSteps) {
        // over the cap: keep only the fraction of a step, drop the rest
        const std::int64_t keep = m_accumulatorNs % m_stepNs;
        t.droppedNs += m_accumulatorNs - keep;
        m_accumulatorNs = keep;
    }
    t.alpha = static_cast<double>(m_accumulatorNs) / static_cast<double>(m_stepNs);
    return t;
}

Tick FixedLoop::advanceTo(const Clock& clock) {
    const std::int64_t now = clock.nowNs();
    if (!m_started) {
        m_started = true;
        m_lastNs = now;
        return Tick{};
    }
    const std::int64_t elapsed = now - m_lastNs;
    m_lastNs = now;
    return advance(elapsed);
}

} // namespace tumble
