#include "engine/parallel.h"

#include "engine/access.h"
#include "engine/float_mode.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <limits>
#include <memory>
#include <stdexcept>

#if defined(__x86_64__) || defined(_M_X64)
#include <immintrin.h>
#endif

namespace tumble {

namespace {

thread_local int t_threadIndex = 0;

/// How long an idle worker (or a waiting caller) spins before it sleeps (or yields): long enough to span
/// the gap between two fork-joins of one conjugate-gradient solve, short enough not to burn a core
/// between frames.
constexpr std::chrono::microseconds kSpin{200};

void relax() {
#if defined(__x86_64__) || defined(_M_X64)
    _mm_pause();
#else
    std::this_thread::yield();
#endif
}

/// Waits until done() holds: spins for kSpin, then yields the core at every poll (so that an
/// oversubscribed machine, 16 threads on 2 cores, lets the threads with work run).
template <class Done>
void waitUntil(Done done) {
    const auto start = std::chrono::steady_clock::now();
    bool spinning = true;
    for (unsigned k = 0; !done(); ++k) {
        // the clock is read every 16th poll: reading it costs more than a poll
        if (spinning && (k & 15) == 15) {
            spinning = std::chrono::steady_clock::now() - start < kSpin;
        }
        if (spinning) {
            relax();
        } else {
            std::this_thread::yield();
        }
    }
}

} // namespace

int parseThreadCount(const std::string& text) {
    if (text.empty() || text.size() > 4 || text.find_first_not_of("0123456789") != std::string::npos) {
        return -1;
    }
    const int n = std::stoi(text);
    return n >= 1 && n <= kMaxThreads ? n : -1;
}

int defaultThreadCount() {
    if (const char* env = std::getenv("TUMBLE_THREADS"); env && *env) {
        const int n = parseThreadCount(env);
        if (n < 0) {
            throw std::invalid_argument("TUMBLE_THREADS='" + std::string(env) +
                                        "' is not a thread count: give a whole number from 1 to " +
                                        std::to_string(kMaxThreads));
        }
        return n;
    }
    const unsigned hw = std::thread::hardware_concurrency();
    return std::clamp(static_cast<int>(hw), 1, kMaxThreads);
}

/// One fork-join: a loop's chunks, claimed a share at a time (claimChunks) by whoever runs them.
struct WorkerPool::Job {
    std::size_t n = 0, grain = 0, chunks = 0;
    void* fn = nullptr;
    ChunkFn call = nullptr;
    bool helpable = true; ///< false for the schedule's tasks, which wait on each other
    /// The chunks not yet claimed, [front, back): the low 32 bits hold front, the high ones back. The
    /// thread that posted the loop claims from the front and helpers from the back, so on two threads
    /// each keeps to its own end from one loop to the next and finds its rows still in its own cache.
    std::atomic<std::uint64_t> unclaimed{0};
    std::atomic<std::size_t> finished{0}; ///< chunks done
    /// a claim takes the unclaimed chunks over this, at least one (claimChunks); the schedule's tasks, one
    /// chunk a thread that joins in, go one at a time
    std::uint64_t divisor = std::numeric_limits<std::uint64_t>::max();
    std::uint64_t floatMode = 0; ///< the caller's
    RunningSystem running;       ///< the caller's
    std::mutex errorMutex;
    std::exception_ptr error;
    std::size_t errorChunk = std::numeric_limits<std::size_t>::max();
};

/// A posted job's place. A helper enters a slot (visitors + 1) before it reads the job there; the thread
/// that posted the job, once its chunks are done, puts a mark of the slot's own in it (retiring()), waits
/// until no helper is inside, and only then empties it. The entering and the marking are sequentially
/// consistent, so either the helper sees the mark (and leaves without reading the job) or the owner sees
/// the helper and waits for it. No lock on the way of a fork-join: a mutex taken to post, to find and to
/// retire a job, as before, cost about a third of the 0.5 us an empty fork-join took at two threads. The
/// mark keeps the slot from taking a new job (a long one, the schedule's tasks) whose helpers would hold the
/// waiting owner up. `helpable` copies the job's, so that a thread waiting for tasks, which only helps
/// loops, does not enter the slot of the tasks' own job again and again.
struct alignas(64) WorkerPool::Slot {
    std::atomic<Job*> job{nullptr};
    std::atomic<int> visitors{0};
    std::atomic<bool> helpable{true};

    Job* retiring() { return reinterpret_cast<Job*>(this); } // never a job's address: compared, not read
};

namespace {

/// Slots for jobs posted at once (a loop, the loops nested in it, the schedule's tasks and theirs); a loop
/// posted when every one is taken runs on its caller alone.
constexpr std::size_t kSlots = 64;

} // namespace

WorkerPool::WorkerPool(int threads) : m_slots(std::make_unique<Slot[]>(kSlots)) {
    const int workers = std::clamp(threads, 1, kMaxThreads) - 1;
    m_workers.reserve(std::size_t(workers));
    for (int i = 1; i <= workers; ++i) {
        m_workers.emplace_back([this, i] { workerMain(i); });
    }
}

WorkerPool::~WorkerPool() {
    {
        std::lock_guard lock(m_mutex);
        m_stop.store(true);
        m_epoch.fetch_add(1);
    }
    m_wake.notify_all();
    for (std::thread& t : m_workers) {
        t.join();
    }
}

WorkerPool& serialPool() {
    static WorkerPool pool(1);
    return pool;
}

int WorkerPool::threadIndex() {
    return t_threadIndex;
}

namespace {

constexpr std::uint64_t kBack = std::uint64_t(1) << 32;

/// Claims chunks [first, end) of a job's unclaimed span, from its front or its back: a share of what is left
/// (what is left over `divisor`, at least one), so that a loop of many chunks costs fewer claims than one a
/// chunk, each of which moves the span's cache line between the cores (guided self-scheduling: the shares
/// shrink as the span does, and the last chunks go one at a time, which keeps the threads' ends even; 80
/// chunks are 16 claims at two threads). The price: a claimed share cannot be taken back, so a helper that
/// loses its core holding one (a busy machine) keeps the caller waiting for up to a quarter of a loop at two
/// threads, where it waited for one chunk. False when none is left.
bool claimChunks(std::atomic<std::uint64_t>& unclaimed, bool fromFront, std::uint64_t divisor,
                 std::size_t& first, std::size_t& end) {
    std::uint64_t span = unclaimed.load(std::memory_order_relaxed);
    for (;;) {
        const std::uint64_t front = span & (kBack - 1), back = span >> 32;
        if (front >= back) {
            return false;
        }
        const std::uint64_t take = std::max<std::uint64_t>(1, (back - front) / divisor);
        const std::uint64_t claimed = fromFront ? span + take : span - take * kBack;
        if (unclaimed.compare_exchange_weak(span, claimed, std::memory_order_relaxed)) {
            first = std::size_t(fromFront ? front : back - take);
            end = first + std::size_t(take);
            return true;
        }
    }
}

bool anyUnclaimed(const std::atomic<std::uint64_t>& unclaimed) {
    const std::uint64_t span = unclaimed.load(std::memory_order_relaxed);
    return (span & (kBack - 1)) < (span >> 32);
}

} // namespace

void WorkerPool::runChunks(Job& job, bool fromFront) {
    // take the caller's floating-point mode and running system for as long as this thread works for it
    const std::uint64_t ownMode = floatMode();
    if (ownMode != job.floatMode) {
        setFloatMode(job.floatMode);
    }
    RunningSystem& running = runningSystem();
    const RunningSystem ownRunning = running;
    running = job.running;
    std::size_t first = 0, end = 0;
    while (claimChunks(job.unclaimed, fromFront, job.divisor, first, end)) {
        for (std::size_t c = first; c < end; ++c) {
            try {
                job.call(job.fn, c, c * job.grain, std::min(job.n, (c + 1) * job.grain));
            } catch (...) {
                std::lock_guard lock(job.errorMutex);
                if (c < job.errorChunk) {
                    job.errorChunk = c;
                    job.error = std::current_exception();
                }
            }
        }
        job.finished.fetch_add(end - first, std::memory_order_acq_rel);
    }
    running = ownRunning;
    if (ownMode != job.floatMode) {
        setFloatMode(ownMode);
    }
}

WorkerPool::Slot* WorkerPool::post(Job& job) {
    job.unclaimed.store(std::uint64_t(job.chunks) << 32, std::memory_order_relaxed);
    job.floatMode = floatMode();
    job.running = runningSystem();
    for (std::size_t s = 0; s < kSlots; ++s) {
        Slot& slot = m_slots[s];
        Job* empty = nullptr;
        if (slot.job.load(std::memory_order_relaxed) != nullptr ||
            !slot.job.compare_exchange_strong(empty, &job)) {
            continue;
        }
        slot.helpable.store(job.helpable, std::memory_order_relaxed); // a hint: the job's own is checked
        std::size_t used = m_slotsUsed.load(std::memory_order_relaxed);
        while (used <= s && !m_slotsUsed.compare_exchange_weak(used, s + 1)) {
        }
        signal();
        return &slot;
    }
    return nullptr;
}

void WorkerPool::retire(Slot& slot, Job& job) {
    slot.job.store(slot.retiring());
    // a helper that entered before may still be about to see the job exhausted
    waitUntil([&] { return slot.visitors.load() == 0; });
    slot.job.store(nullptr, std::memory_order_release);
    if (job.error) {
        std::rethrow_exception(job.error);
    }
}

void WorkerPool::run(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call) {
    Job job;
    job.n = n;
    job.grain = grain;
    job.chunks = chunks;
    job.fn = fn;
    job.call = call;
    // two shares a thread: claims few enough, and the last ones small enough to even out the ends
    job.divisor = 2 * std::uint64_t(threads());
    Slot* slot = post(job);
    runChunks(job, true);
    if (!slot) {
        if (job.error) {
            std::rethrow_exception(job.error);
        }
        return;
    }
    waitUntil([&] { return job.finished.load(std::memory_order_acquire) == job.chunks; });
    retire(*slot, job);
}

bool WorkerPool::runSomeChunk(bool helpableOnly) {
    // the highest slot first: a loop nested in a running one is posted after it, mostly in a higher slot,
    // and finishing it lets its caller go on
    for (std::size_t s = m_slotsUsed.load(std::memory_order_acquire); s-- > 0;) {
        Slot& slot = m_slots[s];
        const Job* glimpse = slot.job.load(std::memory_order_relaxed);
        if (glimpse == nullptr || glimpse == slot.retiring() ||
            (helpableOnly && !slot.helpable.load(std::memory_order_relaxed))) {
            continue;
        }
        slot.visitors.fetch_add(1);
        Job* job = slot.job.load();
        const bool useful = job != nullptr && job != slot.retiring() && (!helpableOnly || job->helpable) &&
                            anyUnclaimed(job->unclaimed);
        if (useful) {
            runChunks(*job, false);
        }
        slot.visitors.fetch_sub(1, std::memory_order_release);
        if (useful) {
            return true;
        }
    }
    return false;
}

void WorkerPool::workerMain(int index) {
    t_threadIndex = index;
    for (;;) {
        const std::uint64_t seen = m_epoch.load(std::memory_order_acquire);
        if (runSomeChunk(false)) {
            continue;
        }
        // nothing to do: spin a moment for the next loop, then sleep until one is posted
        auto start = std::chrono::steady_clock::now();
        bool posted = false;
        for (unsigned k = 0;; ++k) {
            if (m_epoch.load(std::memory_order_acquire) != seen) {
                posted = true;
                break;
            }
            relax();
            if ((k & 15) == 15) {
                const auto now = std::chrono::steady_clock::now();
                if (m_awake.load(std::memory_order_relaxed) > 0) {
                    // kept awake: still polling, the core offered to threads with work, and the usual
                    // moment of spinning counted from the last poll that found an Awake
                    start = now;
                    std::this_thread::yield();
                } else if (now - start > kSpin) {
                    break;
                }
            }
        }
        if (m_stop.load(std::memory_order_acquire)) {
            return;
        }
        if (!posted) {
            // parked counted before the epoch is read again, and signal() bumps the epoch before it reads
            // parked (both sequentially consistent): either this thread sees the new epoch or signal() sees
            // it parked and notifies under the mutex, which it holds until it sleeps
            std::unique_lock lock(m_mutex);
            m_parked.fetch_add(1);
            m_wake.wait(lock, [&] { return m_stop.load() || m_epoch.load() != seen; });
            m_parked.fetch_sub(1, std::memory_order_relaxed);
            if (m_stop.load()) {
                return;
            }
        }
    }
}

WorkerPool::Awake::Awake(WorkerPool& pool) : m_pool(pool) {
    pool.m_awake.fetch_add(1, std::memory_order_relaxed);
    pool.signal(); // sleeping workers wake, find nothing, and spin while an Awake lives
}

WorkerPool::Awake::~Awake() {
    m_pool.m_awake.fetch_sub(1, std::memory_order_relaxed);
}

void WorkerPool::signal() {
    m_epoch.fetch_add(1);
    if (m_parked.load() > 0) {
        std::lock_guard lock(m_mutex);
        m_wake.notify_all();
    }
}

void WorkerPool::awaitReady(const std::function<bool()>& ready) {
    // while a task waits for those it depends on, it helps with their loops; after a moment it sleeps
    // until a task ends or a loop is posted
    auto start = std::chrono::steady_clock::now();
    for (unsigned k = 0; !ready(); ++k) {
        const std::uint64_t seen = m_epoch.load(std::memory_order_acquire);
        if (runSomeChunk(true)) {
            start = std::chrono::steady_clock::now();
            continue;
        }
        if (k < 64 || std::chrono::steady_clock::now() - start < kSpin) {
            relax();
            continue;
        }
        std::unique_lock lock(m_mutex);
        m_parked.fetch_add(1); // before the epoch is read again: see workerMain
        // (the timeout only bounds the cost of a wake-up this reasoning missed)
        m_wake.wait_for(lock, std::chrono::milliseconds(1),
                        [&] { return ready() || m_epoch.load() != seen; });
        m_parked.fetch_sub(1, std::memory_order_relaxed);
    }
}

/// The tasks of one runTasks call, as the threads running them share them.
struct WorkerPool::TaskSet {
    WorkerPool* pool;
    std::size_t count;
    const std::function<bool(std::size_t)>* ready;
    const std::function<void(std::size_t)>* task;
    std::unique_ptr<std::atomic<bool>[]> claimed;
    std::atomic<std::size_t> claimedCount{0};
    std::atomic<std::size_t> ended{0};
    std::mutex errorMutex{};
    std::exception_ptr error{};
    std::size_t errorTask = std::numeric_limits<std::size_t>::max();

    /// The lowest-numbered task not yet claimed whose dependencies are done, claimed; count if none.
    std::size_t claimReady() {
        for (std::size_t i = 0; i < count; ++i) {
            if (!claimed[i].load(std::memory_order_acquire) && (*ready)(i) &&
                !claimed[i].exchange(true, std::memory_order_acq_rel)) {
                claimedCount.fetch_add(1, std::memory_order_acq_rel);
                return i;
            }
        }
        return count;
    }
    bool anyReady() const {
        for (std::size_t i = 0; i < count; ++i) {
            if (!claimed[i].load(std::memory_order_acquire) && (*ready)(i)) {
                return true;
            }
        }
        return false;
    }
    /// Runs ready tasks until every task is claimed; a thread never holds a task it cannot start.
    void work() {
        while (claimedCount.load(std::memory_order_acquire) < count) {
            const std::size_t i = claimReady();
            if (i == count) {
                pool->awaitReady(
                    [&] { return claimedCount.load(std::memory_order_acquire) == count || anyReady(); });
                continue;
            }
            // a thread waiting for this one to end may sleep: wake it, even when this one throws
            struct Ended {
                TaskSet& t;
                ~Ended() {
                    t.ended.fetch_add(1, std::memory_order_acq_rel);
                    t.pool->signal();
                }
            } endGuard{*this};
            try {
                (*task)(i);
            } catch (...) {
                // kept, and the thread goes on with the other tasks: were it to leave, tasks could be left
                // unclaimed with every thread gone. The lowest-numbered task's error is rethrown at the end
                std::lock_guard lock(errorMutex);
                if (i < errorTask) {
                    errorTask = i;
                    error = std::current_exception();
                }
            }
        }
    }
};

void WorkerPool::runTasks(std::size_t count, const std::function<bool(std::size_t)>& ready,
                          const std::function<void(std::size_t)>& task) {
    if (m_workers.empty() || count <= 1) {
        for (std::size_t i = 0; i < count; ++i) {
            task(i);
        }
        return;
    }
    TaskSet tasks{this, count, &ready, &task, std::make_unique<std::atomic<bool>[]>(count)};
    // one chunk per thread that joins in: each runs ready tasks until none is left to claim
    Job job;
    job.n = std::size_t(threads());
    job.grain = 1;
    job.chunks = job.n;
    job.helpable = false;
    job.fn = &tasks;
    job.call = [](void* f, std::size_t, std::size_t, std::size_t) { static_cast<TaskSet*>(f)->work(); };
    Slot* slot = post(job); // none free: the caller runs every task, in the order they come ready
    runChunks(job, true);
    awaitReady([&] { return tasks.ended.load(std::memory_order_acquire) == count; });
    waitUntil([&] { return job.finished.load(std::memory_order_acquire) == job.chunks; });
    if (slot) {
        retire(*slot, job);
    } else if (job.error) {
        std::rethrow_exception(job.error); // what retire rethrows (an error of ready(), met in work())
    }
    if (tasks.error) {
        std::rethrow_exception(tasks.error);
    }
}

} // namespace tumble
