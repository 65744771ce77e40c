#include "app/run_loop.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <mutex>
#include <thread>

namespace tumble {

namespace {

std::atomic<bool> g_stop{false};

static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void onStopSignal(int) {
    g_stop.store(true);
}

// The StopSignals alive and the handlers from before the first of them. The handlers are the process's, not
// a thread's: runs that overlap (two Python threads each verifying a replay) share one installation, put
// back when the last of them ends, whichever order they end in (each putting back what it found left ours
// installed when the first to start ended first: the second then put back the first's, ours).
std::mutex g_stopMutex;
int g_stopUsers = 0;
struct sigaction g_previousInt {
}, g_previousTerm{};

} // namespace

FramePacer::FramePacer(const Clock& clock, std::int64_t periodNs)
    : m_clock(clock), m_periodNs(periodNs), m_nextNs(clock.nowNs()) {}

void FramePacer::wait() {
    m_nextNs = std::max(m_nextNs + m_periodNs, m_clock.nowNs());
    if (const std::int64_t wait = m_nextNs - m_clock.nowNs(); wait > 0) {
        std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
    }
}

StopSignal::StopSignal() {
    const std::lock_guard lock(g_stopMutex);
    if (g_stopUsers++ > 0) {
        return; // installed, by a run under way
    }
    g_stop.store(false);
    // SA_RESETHAND: the handler goes after the first signal, so a second one kills
    struct sigaction stop {};
    stop.sa_handler = onStopSignal;
    stop.sa_flags = SA_RESETHAND;
    sigemptyset(&stop.sa_mask);
    ::sigaction(SIGINT, &stop, &g_previousInt);
    ::sigaction(SIGTERM, &stop, &g_previousTerm);
}

StopSignal::~StopSignal() {
    const std::lock_guard lock(g_stopMutex);
    if (--g_stopUsers > 0) {
        return;
    }
    // the handlers from before (a program embedding the library keeps its own)
    ::sigaction(SIGINT, &g_previousInt, nullptr);
    ::sigaction(SIGTERM, &g_previousTerm, nullptr);
}

bool StopSignal::requested() const {
    return g_stop.load();
}

void ReportDrain::drain(const RunReport& report, const std::function<void(const std::string&, bool)>& say) {
    for (; m_failures < report.failures.size(); ++m_failures) {
        say(report.failures[m_failures], true);
    }
    for (; m_notes < report.notes.size(); ++m_notes) {
        say(report.notes[m_notes], false);
    }
}

} // namespace tumble
