#pragma once
// The worker pool: persistent worker threads plus the thread that asks, sharing loops cut into chunks.
//
// The same bits on any number of threads. A loop over [0, n) is cut into chunks of `grain` indices
// (chunk c covers [c * grain, min(n, (c + 1) * grain))): the boundaries depend only on n and the grain,
// never on how many threads there are. Threads claim chunks as they come free (the asking thread from the
// first chunk up, helpers from the last down, so that on two threads each tends to get the same rows, still
// in its cache, loop after loop), a share of what is left at a time (what is left over twice the thread
// count, at least one chunk: a loop of 80 chunks is 16 claims at two threads, not 80, each moving the claims'
// cache line between cores), so which thread runs a chunk varies, but a chunk's work does not depend on it. A
// loop of 2^31 chunks or more runs on the caller alone, and so does one posted while loops are nested so
// deep that the pool's 64 slots for posted loops are all taken. A reduction keeps one partial per chunk and
// adds the partials in chunk order after the loop, so a sum has the same bits at 1 thread and at 16. With one
// thread the chunks simply run in order on the caller, through the same code.
//
// Why our own pool and not oneTBB: a conjugate-gradient step of the cloth makes hundreds of fork-joins of
// a few microseconds each; what they cost is waking the workers, so idle workers spin for a short while
// before they sleep on a condition variable (Box2D v3's and Jolt's samples do the same). A loop of a
// single chunk runs inline and costs no synchronisation at all.
//
// Nesting: a chunk may run a loop of its own on the same pool (a system running beside others splits its
// work further); the thread that asks always works on its own loop, so a nested loop never waits for a
// thread that is busy elsewhere. A chunk that throws does not stop the others; after the loop the
// exception of the lowest-numbered chunk that threw is rethrown, the same one at any thread count.
//
// Each worker takes, for every chunk, the floating-point mode (denormals flushed) and the running system
// of the thread that asked, so the world's access check and the arithmetic are those of the caller. A
// chunk may read the world and write what its system declared, each chunk its own part; the system's
// command queue is one per system, so structural changes (world.commands()) are made outside the loop.

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace tumble {

/// Threads a run uses when not told: TUMBLE_THREADS if set, else every hardware thread. Throws
/// std::invalid_argument with a message naming TUMBLE_THREADS if it is not a whole number in [1, 256].
int defaultThreadCount();
constexpr int kMaxThreads = 256;
/// Parses a thread count ("4"): -1 when it is not a whole number in [1, kMaxThreads].
int parseThreadCount(const std::string& text);

/// Persistent workers sharing chunked loops; see the header comment.
class WorkerPool {
public:
    /// A pool of `threads` threads in all: the caller and threads - 1 workers (1: no workers).
    explicit WorkerPool(int threads);
    ~WorkerPool();
    WorkerPool(const WorkerPool&) = delete;
    WorkerPool& operator=(const WorkerPool&) = delete;

    int threads() const { return static_cast<int>(m_workers.size()) + 1; }

    /// Chunks of [0, n) of size `grain`.
    static std::size_t chunkCount(std::size_t n, std::size_t grain) {
        return grain ? (n + grain - 1) / grain : 0;
    }

    /// Calls fn(chunk, begin, end) once for every chunk of [0, n), then returns (a fork-join).
    template <class F>
    void forChunks(std::size_t n, std::size_t grain, F&& fn) {
        const std::size_t chunks = chunkCount(n, grain);
        if (chunks <= 1) {
            if (chunks == 1) {
                fn(std::size_t(0), std::size_t(0), n);
            }
            return;
        }
        using Fn = std::remove_reference_t<F>;
        void* const f = const_cast<void*>(static_cast<const void*>(&fn));
        const ChunkFn call = [](void* g, std::size_t c, std::size_t b, std::size_t e) {
            (*static_cast<Fn*>(g))(c, b, e);
        };
        if (m_workers.empty() || std::uint64_t(chunks) > 0x7fffffffu) {
            runAlone(n, grain, chunks, f, call); // on one thread too, every chunk runs: the same state
            return;
        }
        run(n, grain, chunks, f, call);
    }

    /// Calls fn(i) for every i of [0, n), in chunks of `grain`.
    template <class F>
    void forEach(std::size_t n, std::size_t grain, F&& fn) {
        forChunks(n, grain, [&fn](std::size_t, std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                fn(i);
            }
        });
    }

    /// The sum over the chunks of [0, n) of chunkSum(begin, end), added in chunk order starting from zero:
    /// the same bits at any thread count.
    template <class T, class F>
    T sum(std::size_t n, std::size_t grain, T zero, F&& chunkSum) {
        const std::size_t chunks = chunkCount(n, grain);
        constexpr std::size_t kOnStack = 256;
        std::array<T, kOnStack> local{};
        std::vector<T> heap;
        T* partial = local.data();
        if (chunks > kOnStack) {
            heap.assign(chunks, zero);
            partial = heap.data();
        }
        forChunks(n, grain,
                  [&](std::size_t c, std::size_t b, std::size_t e) { partial[c] = chunkSum(b, e); });
        T total = zero;
        for (std::size_t c = 0; c < chunks; ++c) {
            total += partial[c];
        }
        return total;
    }

    /// Runs tasks 0..count-1, each once: a thread that comes free starts the lowest-numbered task whose
    /// dependencies have finished (ready(i) says so; it is polled), so a chain of dependent tasks stays on
    /// one thread and a thread never holds a task it cannot start. While no task is ready a thread helps
    /// with the chunked loops of running tasks, then sleeps until one ends. Used by the schedule to run
    /// systems side by side; ready() must only depend on lower-numbered tasks. With every slot for posted
    /// loops taken, the caller runs the tasks alone, each as it comes ready.
    void runTasks(std::size_t count, const std::function<bool(std::size_t)>& ready,
                  const std::function<void(std::size_t)>& task);

    /// This thread's number in the pool that runs it: 0 for a thread that is not a worker (the main
    /// thread), 1 .. threads - 1 for the workers. Labels the trace's tracks.
    static int threadIndex();

    /// While one lives, the pool's idle workers spin (yielding the core between polls after the usual
    /// moment) rather than sleep, and sleeping ones are woken: for work run on the calling thread alone
    /// that the pool will follow at once, so that the pool's first loop after it does not pay for waking
    /// them (engine/thread_choice.h's trials, which alternate the two ways).
    class Awake {
    public:
        explicit Awake(WorkerPool& pool);
        ~Awake();
        Awake(const Awake&) = delete;
        Awake& operator=(const Awake&) = delete;

    private:
        WorkerPool& m_pool;
    };

private:
    using ChunkFn = void (*)(void* fn, std::size_t chunk, std::size_t begin, std::size_t end);
    struct Slot;
    struct TaskSet;

    void run(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call);
    /// Runs every chunk on this thread, in order; rethrows the lowest-numbered chunk's error after.
    static void runAlone(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call);
    void workerMain(int index);
    /// Runs the free chunks of some posted loop (only helpable ones if `helpableOnly`); false if none was.
    bool runSomeChunk(bool helpableOnly);
    /// Whether some posted loop has chunks left to claim (helpable ones only if `helpableOnly`).
    bool anyClaimable(bool helpableOnly) const;
    /// Runs chunks of the slot's loop until none is left to claim, from its front (`owner`: the thread that
    /// posted it) or its back (a helper, which counts them in the slot's `finished`; none of the schedule's
    /// tasks if `loopsOnly`; after one claim of a loop posted there since, it stops); returns how many it
    /// ran.
    std::size_t runChunks(Slot& slot, bool owner, bool loopsOnly);
    /// Takes a free slot, writes the loop into it and publishes its chunks (waking parked threads); null when
    /// every slot is taken (the caller then runs the loop alone: the same chunks, the same bits).
    Slot* post(std::size_t n, std::size_t grain, std::size_t chunks, void* fn, ChunkFn call, bool tasks);
    /// Waits until the helpers have done the chunks the owner did not (`mine`), frees the slot and rethrows
    /// the loop's first error.
    void join(Slot& slot, std::size_t chunks, std::size_t mine);
    /// Bumps the epoch and wakes the parked threads, workers and those asleep in awaitReady (a loop was
    /// posted while one was parked, a task has ended, an Awake began).
    void signal();
    /// Waits until ready() holds, helping with loops meanwhile, then sleeping.
    void awaitReady(const std::function<bool()>& ready);

    std::vector<std::thread> m_workers;
    /// The posted loops, one a slot, taken and read without a lock (see Slot)
    std::unique_ptr<Slot[]> m_slots;
    std::atomic<std::size_t> m_slotsUsed{0}; ///< slots ever taken: helpers look at [0, this) only
    std::mutex m_mutex;                      ///< guards parking
    std::condition_variable m_wake;          ///< parked threads wait here
    /// bumped by signal(): when a loop is posted while a thread is parked, a task ends, an Awake begins, the
    /// pool stops
    std::atomic<std::uint64_t> m_epoch{0};
    std::atomic<int> m_parked{0};
    std::atomic<bool> m_stop{false};
    std::atomic<int> m_awake{0}; ///< Awake objects alive: idle workers do not sleep
};

/// A pool of one thread (no workers): for code that runs a chunked loop with no pool at hand.
WorkerPool& serialPool();
/// The pool given, or the serial pool when none is (a StepContext made by hand has none).
inline WorkerPool& poolOr(WorkerPool* pool) {
    return pool ? *pool : serialPool();
}

} // namespace tumble
