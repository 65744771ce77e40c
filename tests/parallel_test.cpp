// The worker pool and the schedule's side-by-side systems: chunks that depend only on the problem size,
// sums with the same bits at any thread count, errors, nesting, and what a worker takes from its caller
// (the floating-point mode, the running system). Each test's reference is brute force or a fact of the
// setup, never the pool itself.

#include "engine/float_mode.h"
#include "engine/parallel.h"
#include "engine/schedule.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace tumble {
namespace {

constexpr int kThreadCounts[] = {1, 2, 3, 4, 7, 16};

TEST(WorkerPool, ChunksCoverTheRangeOnceWithBoundariesOfTheSizeAlone) {
    constexpr std::size_t n = 1003, grain = 64;
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        std::vector<std::atomic<int>> hits(n);
        std::vector<std::pair<std::size_t, std::size_t>> bounds(WorkerPool::chunkCount(n, grain));
        pool.forChunks(n, grain, [&](std::size_t c, std::size_t b, std::size_t e) {
            bounds[c] = {b, e};
            for (std::size_t i = b; i < e; ++i) {
                hits[i].fetch_add(1);
            }
        });
        for (std::size_t i = 0; i < n; ++i) {
            ASSERT_EQ(hits[i].load(), 1) << "index " << i << " at " << threads << " threads";
        }
        ASSERT_EQ(bounds.size(), 16u);
        for (std::size_t c = 0; c < bounds.size(); ++c) {
            EXPECT_EQ(bounds[c].first, c * grain);
            EXPECT_EQ(bounds[c].second, std::min(n, (c + 1) * grain));
        }
    }
}

TEST(WorkerPool, ASumHasTheBitsOfItsChunkPartialsAddedInOrderAtAnyThreadCount) {
    // numbers of wildly different sizes, so that any other order of addition gives other bits
    std::vector<float> x(100'000);
    for (std::size_t i = 0; i < x.size(); ++i) {
        x[i] = float((i * 2654435761u) % 1000003u) * (i % 7 == 0 ? 1e4f : 1e-3f) * (i % 2 ? 1.0f : -1.0f);
    }
    constexpr std::size_t grain = 1000;
    // the reference, by hand: partials of 1000 in order, then added in order
    float expected = 0.0f;
    for (std::size_t c = 0; c < x.size() / grain; ++c) {
        float partial = 0.0f;
        for (std::size_t i = c * grain; i < (c + 1) * grain; ++i) {
            partial += x[i];
        }
        expected += partial;
    }
    float straight = 0.0f;
    for (float v : x) {
        straight += v;
    }
    ASSERT_NE(straight, expected) << "the data should tell one order of addition from another";
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        const float got = pool.sum(x.size(), grain, 0.0f, [&](std::size_t b, std::size_t e) {
            float s = 0.0f;
            for (std::size_t i = b; i < e; ++i) {
                s += x[i];
            }
            return s;
        });
        EXPECT_EQ(std::memcmp(&got, &expected, sizeof got), 0)
            << threads << " threads: " << got << " vs " << expected;
    }
}

TEST(WorkerPool, TheLowestChunksErrorIsRethrownAfterEveryChunkRan) {
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        std::atomic<int> ran{0};
        try {
            pool.forChunks(20, 1, [&](std::size_t c, std::size_t, std::size_t) {
                ran.fetch_add(1);
                if (c == 13 || c == 5) {
                    throw std::runtime_error(std::to_string(c));
                }
            });
            FAIL() << "no error at " << threads << " threads";
        } catch (const std::runtime_error& e) {
            EXPECT_STREQ(e.what(), "5") << threads << " threads";
        }
        EXPECT_EQ(ran.load(), 20);
    }
}

// Threads claim a share of what is left of a loop (two shares a thread), not all of it: each thread, in the
// first chunk it runs, waits for the other thread to run one. Were a claim the whole loop, the first thread
// to claim would wait with every chunk in hand and the other would find none.
TEST(WorkerPool, AThreadClaimsAShareOfTheChunksLeftNotAllOfThem) {
    WorkerPool pool(2);
    std::array<std::atomic<int>, 2> ran{};
    std::array<std::atomic<bool>, 2> sawOther{};
    pool.forChunks(64, 1, [&](std::size_t, std::size_t, std::size_t) {
        const auto self = std::size_t(WorkerPool::threadIndex()), other = 1 - self;
        if (ran[self].fetch_add(1) == 0) {
            const auto start = std::chrono::steady_clock::now();
            while (ran[other].load() == 0 &&
                   std::chrono::steady_clock::now() - start < std::chrono::seconds(5)) {
                std::this_thread::yield();
            }
            sawOther[self] = ran[other].load() > 0;
        }
    });
    EXPECT_EQ(ran[0].load() + ran[1].load(), 64);
    EXPECT_TRUE(sawOther[0].load()) << "the caller's claim left the helper nothing";
    EXPECT_TRUE(sawOther[1].load()) << "the helper's claim left the caller nothing";
}

TEST(WorkerPool, NestedLoopsFinish) {
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        std::atomic<long> total{0};
        pool.forChunks(8, 1, [&](std::size_t, std::size_t, std::size_t) {
            pool.forEach(1000, 10, [&](std::size_t i) { total.fetch_add(long(i)); });
        });
        EXPECT_EQ(total.load(), 8L * 999 * 1000 / 2) << threads << " threads";
    }
}

// Loop after loop in the same slot, of other sizes and grains: a helper that finished its part of one loop
// may claim from the next one posted there, and must run the next one's work, not the one it read before
// (a helper that kept the last loop's function and bounds ran the next loop's chunks with them: caught at 3,
// 7 and 16 threads, where a helper loses its core between two claims; at 2 it was not).
TEST(WorkerPool, LoopAfterLoopEachRunsItsOwnChunksOnce) {
    constexpr int kRounds = 20000;
    constexpr std::size_t kN[2] = {40, 90}, kGrain[2] = {4, 3};
    for (int threads : {2, 3, 7, 16}) {
        WorkerPool pool(threads);
        std::array<std::vector<std::atomic<int>>, 2> hits{std::vector<std::atomic<int>>(kN[0]),
                                                          std::vector<std::atomic<int>>(kN[1])};
        long wrong = 0;
        for (int round = 0; round < kRounds && wrong == 0; ++round) {
            const int which = round % 2;
            pool.forChunks(kN[which], kGrain[which], [&](std::size_t, std::size_t b, std::size_t e) {
                for (std::size_t i = b; i < e; ++i) {
                    hits[which][i].fetch_add(1, std::memory_order_relaxed);
                }
            });
            for (int loop = 0; loop < 2; ++loop) {
                for (std::atomic<int>& h : hits[loop]) {
                    wrong += h.exchange(0, std::memory_order_relaxed) != (loop == which ? 1 : 0);
                }
            }
        }
        EXPECT_EQ(wrong, 0) << threads << " threads";
    }
}

// Loops nested deeper than the pool has slots for posted loops (64): those posted when every slot is taken
// run on their callers alone, every chunk once, and an error from the deepest still reaches the top.
TEST(WorkerPool, LoopsNestedDeeperThanItsSlotsRunEveryChunkOnce) {
    constexpr int kDepth = 100;
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        std::atomic<long> ran{0};
        std::function<void(int)> level = [&](int depth) {
            pool.forChunks(3, 1, [&](std::size_t c, std::size_t, std::size_t) {
                ran.fetch_add(1);
                if (c == 0 && depth < kDepth) {
                    level(depth + 1);
                }
                if (c == 2 && depth == kDepth) {
                    throw std::runtime_error("deepest");
                }
            });
        };
        try {
            level(1);
            FAIL() << "no error at " << threads << " threads";
        } catch (const std::runtime_error& e) {
            EXPECT_STREQ(e.what(), "deepest") << threads << " threads";
        }
        EXPECT_EQ(ran.load(), 3L * kDepth) << threads << " threads";
    }
}

// Tasks run from inside loops nested past the pool's slots run on their caller alone, every one, and an error
// of ready() still reaches the caller, as it does with a slot free (the slot's owner rethrew it; without a
// slot it was dropped).
TEST(WorkerPool, TasksPostedWithEverySlotTakenRunAndKeepTheirErrors) {
    for (const int depth : {1, 70}) {
        for (const int threads : {2, 4}) {
            WorkerPool pool(threads);
            std::atomic<int> ran{0};
            std::atomic<bool> thrown{false};
            const std::function<bool(std::size_t)> ready = [&](std::size_t i) {
                if (i == 1 && !thrown.exchange(true)) {
                    throw std::runtime_error("ready");
                }
                return true;
            };
            const std::function<void(std::size_t)> task = [&](std::size_t) { ran.fetch_add(1); };
            std::function<void(int)> level = [&](int d) {
                pool.forChunks(2, 1, [&](std::size_t c, std::size_t, std::size_t) {
                    if (c == 0 && d < depth) {
                        level(d + 1);
                    } else if (c == 0) {
                        pool.runTasks(3, ready, task);
                    }
                });
            };
            try {
                level(1);
                ADD_FAILURE() << "no error at depth " << depth << ", " << threads << " threads";
            } catch (const std::runtime_error& e) {
                EXPECT_STREQ(e.what(), "ready") << depth << ", " << threads << " threads";
            }
            EXPECT_EQ(ran.load(), 3) << depth << ", " << threads << " threads";
        }
    }
}

// A task whose readiness throws every time it is asked: the tasks before it run, the error reaches the
// caller, and nothing waits for the task that never runs (runTasks waited for every task to end: a hang).
TEST(WorkerPool, TasksWhoseReadinessAlwaysThrowsEndWithTheError) {
    for (const int threads : {2, 4}) {
        WorkerPool pool(threads);
        std::atomic<int> ran{0};
        const std::function<bool(std::size_t)> ready = [&](std::size_t i) {
            if (i == 1) {
                throw std::runtime_error("never ready");
            }
            return true;
        };
        const std::function<void(std::size_t)> task = [&](std::size_t) { ran.fetch_add(1); };
        try {
            pool.runTasks(3, ready, task);
            ADD_FAILURE() << "no error at " << threads << " threads";
        } catch (const std::runtime_error& e) {
            EXPECT_STREQ(e.what(), "never ready") << threads << " threads";
        }
        EXPECT_EQ(ran.load(), 1) << threads << " threads"; // task 0; the scan stops at task 1's error
    }
}

// Workers kept awake (WorkerPool::Awake, held by a thread-count trial's runs on one thread) still take the
// loops posted meanwhile and after, nested ones too, and the pool stops when it goes, workers asleep or not.
TEST(WorkerPool, AwakeWorkersStillTakeLoopsAndStop) {
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        std::atomic<long> total{0};
        {
            const WorkerPool::Awake first(pool);
            const WorkerPool::Awake second(pool);
            std::this_thread::sleep_for(std::chrono::milliseconds(2)); // past the workers' moment of spinning
            pool.forChunks(8, 1, [&](std::size_t, std::size_t, std::size_t) {
                pool.forEach(1000, 10, [&](std::size_t i) { total.fetch_add(long(i)); });
            });
        }
        pool.forEach(1000, 10, [&](std::size_t i) { total.fetch_add(long(i)); });
        EXPECT_EQ(total.load(), 9L * 999 * 1000 / 2) << threads << " threads";
        { const WorkerPool::Awake last(pool); }
    }
}

TEST(WorkerPool, WorkersComputeInTheCallersFloatingPointMode) {
    // with denormals flushed, the smallest normal float halved is zero; without, it is a denormal. Every
    // chunk must see the caller's mode, whichever thread runs it
    WorkerPool pool(4);
    std::vector<float> out(64, -1.0f);
    volatile float tiny = std::numeric_limits<float>::min();
    {
        const FlushDenormals flush;
        pool.forEach(out.size(), 1, [&](std::size_t i) {
            std::this_thread::sleep_for(std::chrono::microseconds(200)); // let the workers take some
            out[i] = tiny * 0.5f;
        });
    }
    for (float v : out) {
        EXPECT_EQ(v, 0.0f);
    }
    pool.forEach(out.size(), 1, [&](std::size_t i) { out[i] = tiny * 0.5f; });
    for (float v : out) {
        EXPECT_GT(v, 0.0f);
    }
}

struct Declared {
    int v = 0;
};
struct Undeclared {
    int v = 0;
};

TEST(WorkerPool, AWorkerChecksTheAccessOfTheSystemThatGaveItWork) {
    WorkerPool pool(3);
    Profiler prof;
    Schedule s(prof);
    World w;
    w.emplace<Declared>(w.create());
    w.emplace<Undeclared>(w.create());
    s.add(
        Phase::Fixed, "sneaky",
        [&](World& world, const StepContext&) {
            pool.forChunks(32, 1, [&](std::size_t, std::size_t, std::size_t) {
                std::this_thread::sleep_for(std::chrono::microseconds(100));
                // reading what it declared is fine; reading anything else must fail on any thread
                world.view<const Declared>().each([](Entity, const Declared&) {});
                world.view<const Undeclared>().each([](Entity, const Undeclared&) {});
            });
        },
        accessOf<Reads<>, Writes<Declared>>());
    StepContext ctx;
    ctx.pool = &pool;
    EXPECT_THROW(s.run(Phase::Fixed, w, ctx), AccessError);
}

TEST(WorkerPool, ThreadCountsFromTheEnvironmentAreCheckedAndBadOnesRefused) {
    EXPECT_EQ(parseThreadCount("4"), 4);
    EXPECT_EQ(parseThreadCount("256"), 256);
    for (const char* bad : {"", "0", "-1", "257", "2x", " 3", "1e3", "99999"}) {
        EXPECT_EQ(parseThreadCount(bad), -1) << "'" << bad << "'";
    }
}

struct A {};
struct B {};

/// A schedule of systems that record when they start and end, on a pool.
struct Timeline {
    std::mutex mutex;
    std::vector<std::string> events;
    void say(const std::string& e) {
        std::lock_guard lock(mutex);
        events.push_back(e);
    }
    std::size_t at(const std::string& e) const {
        return std::size_t(std::find(events.begin(), events.end(), e) - events.begin());
    }
};

TEST(Schedule, SystemsThatDoNotConflictRunSideBySide) {
    // the first waits (up to 5 s) for the second to start: only possible if they run at once
    WorkerPool pool(2);
    Profiler prof;
    Schedule s(prof);
    std::atomic<bool> secondStarted{false};
    bool sawSecond = false;
    s.add(
        Phase::Fixed, "first",
        [&](World&, const StepContext&) {
            const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
            while (!secondStarted.load() && std::chrono::steady_clock::now() < until) {
                std::this_thread::yield();
            }
            sawSecond = secondStarted.load();
        },
        accessOf<Reads<>, Writes<A>>());
    s.add(
        Phase::Fixed, "second", [&](World&, const StepContext&) { secondStarted.store(true); },
        accessOf<Reads<>, Writes<B>>());
    World w;
    StepContext ctx;
    ctx.pool = &pool;
    s.run(Phase::Fixed, w, ctx);
    EXPECT_TRUE(sawSecond);
    EXPECT_EQ(s.waitsFor(Phase::Fixed), (std::vector<std::vector<std::size_t>>{{}, {}}));
}

TEST(Schedule, ASystemWaitsForEveryEarlierOneItConflictsWith) {
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        Profiler prof;
        Schedule s(prof);
        Timeline t;
        auto timed = [&t](const std::string& name, int ms) {
            return [&t, name, ms](World&, const StepContext&) {
                t.say(name + "+");
                std::this_thread::sleep_for(std::chrono::milliseconds(ms));
                t.say(name + "-");
            };
        };
        s.add(Phase::Fixed, "writesA", timed("writesA", 20), accessOf<Reads<>, Writes<A>>());
        s.add(Phase::Fixed, "writesB", timed("writesB", 1), accessOf<Reads<>, Writes<B>>());
        s.add(Phase::Fixed, "readsA", timed("readsA", 1), accessOf<Reads<A>, Writes<>>());
        s.add(Phase::Fixed, "readsAB", timed("readsAB", 1), accessOf<Reads<A, B>, Writes<>>());
        World w;
        StepContext ctx;
        ctx.pool = &pool;
        s.run(Phase::Fixed, w, ctx);
        EXPECT_LT(t.at("writesA-"), t.at("readsA+")) << threads << " threads";
        EXPECT_LT(t.at("writesA-"), t.at("readsAB+")) << threads << " threads";
        EXPECT_LT(t.at("writesB-"), t.at("readsAB+")) << threads << " threads";
        EXPECT_EQ(s.waitsFor(Phase::Fixed), (std::vector<std::vector<std::size_t>>{{}, {}, {0}, {0, 1}}));
    }
}

TEST(Schedule, QueuedChangesOfSystemsSideBySideApplyInTableOrder) {
    // the first system queues its change late (after the second queued its own): the first's still
    // applies first, as on one thread
    for (int threads : kThreadCounts) {
        WorkerPool pool(threads);
        Profiler prof;
        Schedule s(prof);
        std::vector<std::string> applied;
        std::atomic<bool> secondQueued{false};
        s.add(
            Phase::Fixed, "late",
            [&](World& world, const StepContext&) {
                const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(100);
                while (!secondQueued.load() && std::chrono::steady_clock::now() < until) {
                    std::this_thread::yield();
                }
                world.commands().push([&](World&) { applied.push_back("late"); });
            },
            accessOf<Reads<>, Writes<A>>());
        s.add(
            Phase::Fixed, "early",
            [&](World& world, const StepContext&) {
                world.commands().push([&](World&) { applied.push_back("early"); });
                secondQueued.store(true);
            },
            accessOf<Reads<>, Writes<B>>());
        World w;
        StepContext ctx;
        ctx.pool = &pool;
        s.run(Phase::Fixed, w, ctx);
        EXPECT_EQ(applied, (std::vector<std::string>{"late", "early"})) << threads << " threads";
    }
}

TEST(Schedule, SystemsThatThrowSideBySideEndThePhaseWithTheFirstOnesError) {
    // two systems side by side both throw (each waits for the other to start, so both run at once); the
    // system after them must still be claimed (and skipped) rather than left waiting for threads that
    // have gone: the phase ends, with the first system's error
    WorkerPool pool(2);
    Profiler prof;
    Schedule s(prof);
    std::atomic<int> started{0};
    auto thrower = [&started](const char* what) {
        return [&started, what](World&, const StepContext&) {
            started.fetch_add(1);
            const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
            while (started.load() < 2 && std::chrono::steady_clock::now() < until) {
                std::this_thread::yield();
            }
            throw std::runtime_error(what);
        };
    };
    bool lastRan = false;
    s.add(Phase::Fixed, "first", thrower("first"), accessOf<Reads<>, Writes<A>>());
    s.add(Phase::Fixed, "second", thrower("second"), accessOf<Reads<>, Writes<B>>());
    s.add(
        Phase::Fixed, "after", [&](World&, const StepContext&) { lastRan = true; },
        accessOf<Reads<Declared>, Writes<>>());
    World w;
    StepContext ctx;
    ctx.pool = &pool;
    try {
        s.run(Phase::Fixed, w, ctx);
        FAIL() << "no error";
    } catch (const std::runtime_error& e) {
        EXPECT_STREQ(e.what(), "first");
    }
    EXPECT_EQ(started.load(), 2);
    EXPECT_FALSE(lastRan) << "systems not started when one has thrown are skipped";
}

TEST(Schedule, TheCriticalPathIsTheLongestChainOfWaits) {
    // a (30 ms) and b (25 ms) side by side, c after a (10 ms): the path is a then c, 40 ms, whatever the
    // threads; on one thread the phase takes all 65
    WorkerPool pool(1);
    Profiler prof;
    Schedule s(prof);
    auto sleeper = [](int ms) {
        return
            [ms](World&, const StepContext&) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); };
    };
    s.add(Phase::Fixed, "a", sleeper(30), accessOf<Reads<>, Writes<A>>());
    s.add(Phase::Fixed, "b", sleeper(25), accessOf<Reads<>, Writes<B>>());
    s.add(Phase::Fixed, "c", sleeper(10), accessOf<Reads<A>, Writes<>>());
    World w;
    StepContext ctx;
    ctx.pool = &pool;
    prof.beginFrame(0);
    s.run(Phase::Fixed, w, ctx);
    prof.endFrame();
    const FrameStats f = prof.frameStats();
    EXPECT_GE(f.criticalP50Ms, 40.0);
    EXPECT_LT(f.criticalP50Ms, 55.0); // sleeps overshoot a little; b on the path would make it 65
    EXPECT_GE(f.physicsP50Ms, 65.0);
}

} // namespace
} // namespace tumble
