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

namespace {

/// A slot's claim word: the chunks not yet claimed, [front, back), front in the low 31 bits and back in bits
/// 32 to 62, and in the top bit that the loop is the schedule's tasks (helpers waiting for tasks leave it
/// alone, and its chunks go one a claim).
constexpr std::uint64_t kBack = std::uint64_t(1) << 32;
constexpr std::uint64_t kSpan = (std::uint64_t(1) << 31) - 1;
constexpr std::uint64_t kTasks = std::uint64_t(1) << 63;

bool anyLeft(std::uint64_t word) {
    return (word & kSpan) < ((word >> 32) & kSpan);
}

} // namespace

/// A posted loop's place, and the loop itself. Slots live as long as the pool, so a helper never reads freed
/// memory and the owner need not wait for helpers to leave. The claim word says everything a claim needs:
/// a helper that read it for one loop and claims from it once it holds another (the slot freed and taken for
/// another loop meanwhile, by any thread) claims chunks of the loop that is there, which is right. A helper
/// reads the rest of the loop after each claim: until the chunks it claimed are done the slot cannot be
/// freed, and the claim (an acquiring exchange) sees what the owner wrote before it published the chunks.
///
/// What a fork-join costs is cache lines moving between the cores (a round trip took 0.57-0.69 us between
/// this machine's two virtual cores, two threads bouncing a flag). So the loop shares its line with the claim
/// word, and a helper that sees the chunks has the loop with them; the helpers' count of finished chunks has
/// a line of its own, which the owner only clears when it posts (it counts its own chunks apart); and the
/// owner's hold on the slot shares a line with the loop's errors only, which helpers touch when a chunk
/// throws. Before, the loop was on the owner's stack, a helper counted itself into the slot before it read
/// the loop, and the owner, its chunks done, waited for the helpers to leave: a move of the slot's line more
/// on every fork-join's way. Alternating, five runs of five repetitions (medians, two threads): four chunks
/// of a little work (`BM_PoolForkJoin/2`) 1.35-1.44 -> 1.31-1.35 us, 80 small chunks
/// (`BM_PoolForkJoinManyChunks/2`) 2.14-2.38 -> 1.91-2.01 us, an empty fork-join the same (0.24-0.33 us);
/// the curtain's step within the noise. Idle workers poll the claim words; beyond two threads each poller's
/// copy of a word is one more to invalidate at a claim, which this machine cannot measure.
struct WorkerPool::Slot {
    alignas(64) std::atomic<std::uint64_t> unclaimed{0}; ///< the claim word (above)
    // the loop: written by the owner before it publishes the chunks, read by a helper holding a claim
    void* fn = nullptr;
    ChunkFn call = nullptr;
    std::size_t n = 0, grain = 0;
    std::uint64_t floatMode = 0; ///< the owner's
    std::uint64_t serial = 0;    ///< loops posted in this slot so far: tells a helper the loop has changed
    alignas(64) RunningSystem running; ///< the owner's (read by a helper after the rest of the loop)

    alignas(64) std::atomic<std::size_t> finished{0}; ///< chunks the helpers have done

    alignas(64) std::atomic<bool> owned{false}; ///< taken by a thread posting a loop, until the loop is done
    std::mutex errorMutex;
    std::exception_ptr error;
    std::size_t errorChunk = std::numeric_limits<std::size_t>::max();

    /// Keeps the lowest-numbered chunk's error.
    void fail(std::size_t chunk) {
        std::lock_guard lock(errorMutex);
        if (chunk < errorChunk) {
            errorChunk = chunk;
            error = std::current_exception();
        }
    }
};

namespace {

/// Slots for loops posted at once (a loop, the loops nested in it, the schedule's tasks and theirs); a loop
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

/// Claims chunks [first, end) of a slot's unclaimed span, from its front or its back: a share of what is
/// left (what is left over `divisor`, at least one; a task set's one at a time), so that a loop of many
/// chunks costs fewer claims than one a chunk, each of which moves the claim word's cache line between the
/// cores (guided self-scheduling: the shares shrink as the span does, and the last chunks go one at a time,
/// which keeps the threads' ends even; 80 chunks are 16 claims at two threads). The price: a claimed share
/// cannot be taken back, so a helper that loses its core holding one (a busy machine) keeps the caller
/// waiting for up to a quarter of a loop at two threads, where it waited for one chunk. False when none is
/// left, or when the slot holds tasks and `loopsOnly` is set.
bool claimChunks(std::atomic<std::uint64_t>& unclaimed, bool fromFront, bool loopsOnly, std::uint64_t divisor,
                 std::size_t& first, std::size_t& end) {
    std::uint64_t word = unclaimed.load(std::memory_order_relaxed);
    for (;;) {
        const std::uint64_t front = word & kSpan, back = (word >> 32) & kSpan;
        if (front >= back || (loopsOnly && (word & kTasks))) {
            return false;
        }
        const std::uint64_t take = (word & kTasks) ? 1 : std::max<std::uint64_t>(1, (back - front) / divisor);
        const std::uint64_t claimed = fromFront ? word + take : word - take * kBack;
        if (unclaimed.compare_exchange_weak(word, claimed, std::memory_order_acquire,
                                            std::memory_order_relaxed)) {
            first = std::size_t(fromFront ? front : back - take);
            end = first + std::size_t(take);
            return true;
        }
    }
}

} // namespace

void WorkerPool::runAlone(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call) {
    // every chunk runs, and the first error is rethrown after: the same state as with helpers
    std::exception_ptr error;
    for (std::size_t c = 0; c < chunks; ++c) {
        try {
            call(fn, c, c * grain, std::min(n, (c + 1) * grain));
        } catch (...) {
            if (!error) {
                error = std::current_exception();
            }
        }
    }
    if (error) {
        std::rethrow_exception(error);
    }
}

std::size_t WorkerPool::runChunks(Slot& slot, bool owner, bool loopsOnly) {
    // two shares a thread: claims few enough, and the last ones small enough to even out the ends
    const std::uint64_t divisor = 2 * std::uint64_t(threads());
    // a helper takes the owner's floating-point mode and running system for as long as it works for it
    const std::uint64_t ownMode = floatMode();
    std::uint64_t mode = ownMode;
    RunningSystem& running = runningSystem();
    const RunningSystem ownRunning = running;
    std::size_t first = 0, end = 0, done = 0;
    std::uint64_t loop = 0;
    while (claimChunks(slot.unclaimed, owner, loopsOnly, divisor, first, end)) {
        // the loop is read after every claim: once the loop a helper claimed from is done, another may be
        // posted in the slot, which the helper's next claim then takes chunks of (and then it goes back: a
        // thread waiting for tasks looks again at what it waits for)
        void* const fn = slot.fn;
        const ChunkFn call = slot.call;
        const std::size_t n = slot.n, grain = slot.grain;
        const bool another = done > 0 && slot.serial != loop;
        loop = slot.serial;
        if (!owner) {
            if (slot.floatMode != mode) {
                mode = slot.floatMode;
                setFloatMode(mode);
            }
            running = slot.running;
        }
        for (std::size_t c = first; c < end; ++c) {
            try {
                call(fn, c, c * grain, std::min(n, (c + 1) * grain));
            } catch (...) {
                slot.fail(c);
            }
        }
        done += end - first;
        if (!owner) {
            slot.finished.fetch_add(end - first, std::memory_order_release);
        }
        if (another) {
            break;
        }
    }
    if (!owner) {
        running = ownRunning;
        if (mode != ownMode) {
            setFloatMode(ownMode);
        }
    }
    return done;
}

WorkerPool::Slot* WorkerPool::post(std::size_t n, std::size_t grain, std::size_t chunks, void* fn,
                                   ChunkFn call, bool tasks) {
    for (std::size_t s = 0; s < kSlots; ++s) {
        Slot& slot = m_slots[s];
        if (slot.owned.load(std::memory_order_relaxed) ||
            slot.owned.exchange(true, std::memory_order_acquire)) {
            continue;
        }
        slot.fn = fn;
        slot.call = call;
        slot.n = n;
        slot.grain = grain;
        slot.floatMode = floatMode();
        ++slot.serial;
        slot.running = runningSystem();
        slot.finished.store(0, std::memory_order_relaxed);
        slot.error = nullptr;
        slot.errorChunk = std::numeric_limits<std::size_t>::max();
        std::size_t used = m_slotsUsed.load(); // sequentially consistent, as the parking reads it
        while (used <= s && !m_slotsUsed.compare_exchange_weak(used, s + 1)) {
        }
        // published (sequentially consistent, as the parking reads it: see workerMain), then a parked thread
        // woken; spinning ones see the chunks as they poll the claim words
        slot.unclaimed.store((std::uint64_t(chunks) << 32) | (tasks ? kTasks : 0));
        if (m_parked.load() > 0) {
            signal();
        }
        return &slot;
    }
    return nullptr;
}

void WorkerPool::join(Slot& slot, std::size_t chunks, std::size_t mine) {
    waitUntil([&] { return slot.finished.load(std::memory_order_acquire) == chunks - mine; });
    std::exception_ptr error = std::move(slot.error);
    slot.owned.store(false, std::memory_order_release);
    if (error) {
        std::rethrow_exception(error);
    }
}

void WorkerPool::run(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call) {
    Slot* slot = post(n, grain, chunks, fn, call, false);
    if (!slot) {
        runAlone(n, grain, chunks, fn, call);
        return;
    }
    join(*slot, chunks, runChunks(*slot, true, false));
}

bool WorkerPool::anyClaimable(bool helpableOnly) const {
    for (std::size_t s = m_slotsUsed.load(); s-- > 0;) {
        const std::uint64_t word = m_slots[s].unclaimed.load();
        if (anyLeft(word) && !(helpableOnly && (word & kTasks))) {
            return true;
        }
    }
    return false;
}

bool WorkerPool::runSomeChunk(bool helpableOnly) {
    // the highest slot first: a loop nested in a running one is posted after it, mostly in a higher slot,
    // and finishing it lets its caller go on
    for (std::size_t s = m_slotsUsed.load(std::memory_order_acquire); s-- > 0;) {
        Slot& slot = m_slots[s];
        const std::uint64_t word = slot.unclaimed.load(std::memory_order_relaxed);
        if (!anyLeft(word) || (helpableOnly && (word & kTasks))) {
            continue;
        }
        // the slot may hold another loop by the time of the claim: the claim checks `helpableOnly` again
        if (runChunks(slot, false, helpableOnly) > 0) {
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
        // nothing to do: poll the claim words a moment for the next loop, then sleep until one is posted
        auto start = std::chrono::steady_clock::now();
        bool posted = false;
        for (unsigned k = 0;; ++k) {
            if (m_epoch.load(std::memory_order_acquire) != seen || anyClaimable(false)) {
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
            // parked counted before the claim words are read again, and post() publishes its chunks before
            // it reads parked (all sequentially consistent): either this thread sees the chunks or post()
            // sees it parked and signals, bumping the epoch past `seen` and notifying under the mutex, which
            // this thread holds until it sleeps
            std::unique_lock lock(m_mutex);
            m_parked.fetch_add(1);
            if (!anyClaimable(false)) {
                m_wake.wait(lock, [&] { return m_stop.load() || m_epoch.load() != seen; });
            }
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
        m_parked.fetch_add(1); // before the claim words and the epoch are read again: see workerMain
        struct Unpark {        // also when ready() throws
            std::atomic<int>& parked;
            ~Unpark() { parked.fetch_sub(1, std::memory_order_relaxed); }
        } unpark{m_parked};
        // (the timeout only bounds the cost of a wake-up this reasoning missed)
        if (!anyClaimable(true)) {
            m_wake.wait_for(lock, std::chrono::milliseconds(1),
                            [&] { return ready() || m_epoch.load() != seen; });
        }
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
    const std::size_t chunks = std::size_t(threads());
    const ChunkFn call = [](void* f, std::size_t, std::size_t, std::size_t) {
        static_cast<TaskSet*>(f)->work();
    };
    Slot* slot = post(chunks, 1, chunks, &tasks, call, true);
    if (!slot) {
        runAlone(chunks, 1, chunks, &tasks, call); // the caller runs every task, in the order they come ready
    } else {
        const std::size_t mine = runChunks(*slot, true, false);
        // every task ended, or (ready() having thrown) every thread out of work(): then join rethrows it
        awaitReady([&] {
            return tasks.ended.load(std::memory_order_acquire) == count ||
                   slot->finished.load(std::memory_order_acquire) == chunks - mine;
        });
        join(*slot, chunks, mine);
    }
    if (tasks.error) {
        std::rethrow_exception(tasks.error);
    }
}

} // namespace tumble
