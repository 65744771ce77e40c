#pragma once
// The pieces every loop that runs a world for a person shares (the command line's run and the viewer):
// a frame pacer, a stop-signal handler, and the drain that says the run's failures and notes as they
// appear. One of each, so that the two loops cannot drift apart.

#include "engine/fixed_loop.h"
#include "engine/run_report.h"

#include <signal.h> // struct sigaction (POSIX)

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>

namespace tumble {

/// Paces frames to a clock, one every period: wait() sleeps until the next frame is due. After an overrun
/// the next frame starts at once and the one after a period later: late frames are not made up in a burst.
class FramePacer {
public:
    FramePacer(const Clock& clock, std::int64_t periodNs);
    void wait();

private:
    const Clock& m_clock;
    std::int64_t m_periodNs;
    std::int64_t m_nextNs;
};

/// While it lives, the first SIGINT or SIGTERM asks the run to stop (requested() turns true; the loop ends
/// at its next frame and keeps its outputs) and a second one kills the process as usual; the handlers from
/// before are put back when it goes (when the last goes, if several live at once: the flag is the
/// process's, and a signal asks each of them to stop).
class StopSignal {
public:
    StopSignal();
    ~StopSignal();
    StopSignal(const StopSignal&) = delete;
    StopSignal& operator=(const StopSignal&) = delete;
    bool requested() const;
};

/// Says each failure and note of a run's RunReport once, in the order they were added.
class ReportDrain {
public:
    /// Hands every failure, then every note, not handed before to say(text, isFailure).
    void drain(const RunReport& report, const std::function<void(const std::string&, bool)>& say);
    std::size_t failures() const { return m_failures; } ///< failures handed so far

private:
    std::size_t m_failures = 0;
    std::size_t m_notes = 0;
};

} // namespace tumble
