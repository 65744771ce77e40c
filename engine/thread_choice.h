#pragma once
// Whether a piece of work that can share its loops out over the pool runs faster doing so or on the calling
// thread alone, chosen by the clock.
//
// Why: sharing a loop costs a fork-join and moves the data it writes between the cores' caches. On some
// machines that is cheap (0.3-0.5 us a fork-join on the Xeon VM of BASELINES.md, where two threads took the
// curtain's implicit step 1.4x faster); on others it is not: on a 2-vCPU AMD EPYC VM an empty fork-join
// took 1.9 us (a cache line's round trip between the two vCPUs 0.6 us), and two threads took the curtain's
// step 10-40% longer than one (BM_CurtainImplicit35, 2026-11-28), while a million particles still ran 2x
// faster. No size threshold fits both, so each piece of work measures both ways now and then and keeps
// the faster.
//
// The bits do not depend on the choice: a chunked loop's chunks and the order its partial sums are added in
// depend only on its size (engine/parallel.h), never on the thread count, so running the work on one thread
// of a pool of sixteen gives what sixteen give. The clock decides where the work runs, never what it
// computes (as the schedule's choice of running a phase side by side does).
//
// The policy: the first kSkip runs share and are not timed (the first run builds patterns and fills the
// caches); then a trial of kTrial runs each way, alternating (so that a machine slowing down or speeding up
// weighs on both alike); the way with the lower median wins, one thread only when it is faster by more than
// kMargin; after kPeriod runs of the chosen way the trial is made again, so a machine whose second core
// comes free is noticed: kTrial runs of the slower way in every kPeriod + 2 kTrial. When one thread wins, the
// next trial comes sooner: after kAlonePeriod runs, then twice as many after each trial one thread wins
// again, up to kPeriod; a trial sharing wins, or a pool of another size, starts that count again (a verdict
// against sharing on a machine with a second core is the likelier mistake: the first trial runs while the
// caches and the threads' placement settle, and a wrong verdict that way costs the period at up to half
// speed, while a trial costs kTrial runs of the slower way). Meanwhile every kTrial runs of the chosen way
// are a check: if, with their median in place of the chosen way's trial median, the trial would have gone the
// other way (a trial misled by noise, or the machine's other core taken since), the next run starts a trial
// at once. A pool of another size (Simulation::setThreads) starts a trial too. During a trial's runs on one
// thread the pool's workers are kept awake (WorkerPool::Awake): the run after each shares, and waking
// sleeping workers for it (a thread switch on each vCPU: tens of microseconds on a VM) would be counted
// against sharing, which a run after a shared one does not pay.
//
// Systems do not read the wall clock (STYLE.md) for what they compute; this reads it for where the work
// runs only, as the schedule's choice of running a phase side by side does.

#include "engine/parallel.h"

#include <array>
#include <chrono>
#include <optional>

namespace tumble {

/// The clock's choice between a pool's threads and the calling thread alone; see the header comment.
class ThreadChoice {
public:
    static constexpr int kSkip = 2;     ///< runs at the start that share and are not timed
    static constexpr int kTrial = 5;    ///< runs of each way in a trial
    static constexpr int kPeriod = 300; ///< runs of the chosen way between two trials (5 s at 60 Hz)
    /// runs alone after a trial one thread wins, when the trial before it went to sharing (or there was none,
    /// or the pool changed size); doubled after each next one it wins, up to kPeriod
    static constexpr int kAlonePeriod = 30;
    static constexpr double kMargin = 0.03; ///< one thread wins only when its median is this much lower

    /// Whether the next run should share out over a pool of `threads` threads (always, with one); a count
    /// other than the last one's starts a trial.
    bool share(int threads);
    /// How long the run that share() was last asked about took, in seconds; with a pool of one thread
    /// nothing is recorded.
    void record(int threads, double seconds);
    /// The way the last trial chose (true before the first trial ends).
    bool sharing() const { return m_sharing; }
    /// Whether the next run is one of a trial's.
    bool inTrial() const;

    /// Times one run: picks the pool it should use and records its time when it ends.
    class Run {
    public:
        Run(ThreadChoice& choice, WorkerPool& pool);
        ~Run();
        Run(const Run&) = delete;
        Run& operator=(const Run&) = delete;
        /// The pool to run on: the one given, or the serial pool.
        WorkerPool& pool() const { return m_use; }

    private:
        ThreadChoice& m_choice;
        int m_threads;
        WorkerPool& m_use;
        std::optional<WorkerPool::Awake>
            m_awake; ///< in a trial's runs on one thread (see the header comment)
        std::chrono::steady_clock::time_point m_start;
    };

private:
    /// Which run of the current cycle comes next: [0, kSkip) skipped (the first cycle only), then the trial's
    /// 2 kTrial runs, then m_period runs of the chosen way.
    int m_run = 0;
    int m_threads = 0;                ///< the pool's size at the last run
    int m_period = kPeriod;           ///< runs of the chosen way before the next trial
    int m_alonePeriod = kAlonePeriod; ///< m_period after the next trial, if one thread wins it
    bool m_sharing = true;
    std::array<std::array<double, kTrial>, 2> m_samples{}; ///< s; [0]: shared, [1]: alone
    double m_otherMedian = 0.0;                            ///< s, the way not chosen, in the last trial
    std::array<double, kTrial> m_check{};                  ///< s, the chosen way's last runs
};

} // namespace tumble
