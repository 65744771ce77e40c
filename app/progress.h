#pragma once
// The progress bar of long runs: frames done, simulated time, wall ms per frame and ETA, redrawn in place
// on a terminal at most ten times a second. It reads the wall clock, which is fine: it is output, not
// simulation.

#include <chrono>
#include <cstdint>
#include <cstdio>

namespace tumble {

/// A one-line progress bar on a stream (stderr by default).
class ProgressBar {
public:
    ProgressBar(std::uint64_t totalFrames, double frameSeconds, bool enabled, std::FILE* out = stderr);
    ~ProgressBar();

    /// Frames done so far; redraws when enough wall time has passed.
    void update(std::uint64_t framesDone);
    /// Erases the bar (if drawn) so a message can take its line; it is redrawn at the next update.
    void clearLine();
    /// Draws the final state and ends the line.
    void finish(std::uint64_t framesDone);

    /// True when stderr is a terminal.
    static bool stderrIsTerminal();

private:
    void draw(std::uint64_t framesDone);

    std::uint64_t m_total;
    double m_frameSeconds;
    bool m_enabled;
    bool m_drawn = false;
    std::FILE* m_out;
    std::chrono::steady_clock::time_point m_start;
    std::chrono::steady_clock::time_point m_last;
};

} // namespace tumble
