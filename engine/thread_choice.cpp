#include "engine/thread_choice.h"

#include <algorithm>

namespace tumble {

namespace {

constexpr int kTrialRuns = 2 * ThreadChoice::kTrial;

double median(std::array<double, ThreadChoice::kTrial> v) {
    std::sort(v.begin(), v.end());
    constexpr std::size_t mid = ThreadChoice::kTrial / 2;
    return ThreadChoice::kTrial % 2 ? v[mid] : 0.5 * (v[mid - 1] + v[mid]);
}

/// The trial's rule: share unless one thread is faster by more than the margin.
bool sharingWins(double shared, double alone) {
    return !(alone < (1.0 - ThreadChoice::kMargin) * shared);
}

} // namespace

bool ThreadChoice::share(int threads) {
    if (threads != m_threads) {
        // another pool: what was measured does not hold for it
        m_threads = threads;
        m_run = std::min(m_run, kSkip);
        m_alonePeriod = kAlonePeriod;
    }
    if (threads <= 1 || m_run < kSkip) {
        return true;
    }
    const int t = m_run - kSkip;
    // the trial alternates, shared first
    return t < kTrialRuns ? t % 2 == 0 : m_sharing;
}

void ThreadChoice::record(int threads, double seconds) {
    if (threads <= 1) {
        return;
    }
    const int t = m_run - kSkip;
    if (t >= 0 && t < kTrialRuns) {
        m_samples[std::size_t(t % 2)][std::size_t(t / 2)] = seconds;
        if (t == kTrialRuns - 1) {
            const double shared = median(m_samples[0]), alone = median(m_samples[1]);
            m_sharing = sharingWins(shared, alone);
            m_otherMedian = m_sharing ? alone : shared;
            if (m_sharing) {
                m_period = kPeriod;
                m_alonePeriod = kAlonePeriod;
            } else {
                m_period = m_alonePeriod;
                m_alonePeriod = std::min(2 * m_alonePeriod, kPeriod);
            }
        }
    } else if (t >= kTrialRuns) {
        // the chosen way's last runs in place of its trial median: would the trial still choose it?
        const int k = t - kTrialRuns;
        m_check[std::size_t(k % kTrial)] = seconds;
        if (k % kTrial == kTrial - 1) {
            const double now = median(m_check);
            if (m_sharing !=
                (m_sharing ? sharingWins(now, m_otherMedian) : sharingWins(m_otherMedian, now))) {
                m_run = kSkip;
                return;
            }
        }
    }
    // after the period a new trial, with nothing skipped
    m_run = m_run + 1 == kSkip + kTrialRuns + m_period ? kSkip : m_run + 1;
}

bool ThreadChoice::inTrial() const {
    return m_run >= kSkip && m_run - kSkip < kTrialRuns;
}

ThreadChoice::Run::Run(ThreadChoice& choice, WorkerPool& pool)
    : m_choice(choice), m_threads(pool.threads()), m_use(choice.share(m_threads) ? pool : serialPool()) {
    if (&m_use != &pool && m_threads > 1 && choice.inTrial()) {
        m_awake.emplace(pool); // the next run of the trial shares: its workers should not have to be woken
    }
    m_start = std::chrono::steady_clock::now();
}

ThreadChoice::Run::~Run() {
    const std::chrono::duration<double> took = std::chrono::steady_clock::now() - m_start;
    m_choice.record(m_threads, took.count());
}

} // namespace tumble
