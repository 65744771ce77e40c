#include "engine/profiler.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sstream>

namespace tumble {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(Profiler, SlotStatisticsFromKnownDurations) {
    Profiler p;
    const int s = p.addSlot("springs", Phase::Fixed, false);
    // 1..100 ms: p50 = 50, p99 = 99, mean 50.5, max 100
    for (int i = 1; i <= 100; ++i) {
        p.record(s, 0, i * kMs);
    }
    const SlotStats st = p.slotStats().at(0);
    EXPECT_EQ(st.name, "springs");
    EXPECT_EQ(st.calls, 100u);
    EXPECT_NEAR(st.meanMs, 50.5, 1e-9);
    EXPECT_NEAR(st.p50Ms, 50.0, 1e-4);
    EXPECT_NEAR(st.p99Ms, 99.0, 1e-4);
    EXPECT_NEAR(st.maxMs, 100.0, 1e-9);
}

TEST(Profiler, CountersKeepTheLargestTheLastAndHowOftenNonZero) {
    Profiler p;
    const int a = p.counterSlot("stage.pairs");
    EXPECT_EQ(p.counterSlot("stage.pairs"), a);
    const int b = p.counterSlot("stage.other");
    EXPECT_NE(a, b);
    for (double v : {0.0, 5.0, 2.0, 0.0}) {
        p.count(a, v);
    }
    p.count(b, -3.0);
    const std::vector<CounterStats> stats = p.counterStats();
    ASSERT_EQ(stats.size(), 2u);
    EXPECT_EQ(stats[a].name, "stage.pairs");
    EXPECT_EQ(stats[a].samples, 4u);
    EXPECT_EQ(stats[a].nonzero, 2u);
    EXPECT_EQ(stats[a].max, 5.0);
    EXPECT_EQ(stats[a].last, 0.0);
    EXPECT_EQ(stats[b].max, -3.0); // the largest of what was reported, not of zero and it
}

TEST(Profiler, RingBufferKeepsTheMostRecentSamples) {
    Profiler p(10);
    const int s = p.addSlot("x", Phase::Fixed, false);
    for (int i = 0; i < 10; ++i) {
        p.record(s, 0, 100 * kMs); // old, slow
    }
    for (int i = 0; i < 10; ++i) {
        p.record(s, 0, 1 * kMs); // recent, fast
    }
    const SlotStats st = p.slotStats().at(0);
    EXPECT_NEAR(st.p99Ms, 1.0, 1e-6) << "percentiles come from the ring, which has forgotten the slow calls";
    EXPECT_NEAR(st.maxMs, 100.0, 1e-9) << "the maximum is over the whole run";
    EXPECT_EQ(st.calls, 20u);
}

TEST(Profiler, RecentStatisticsAreTheLastCallsOldestFirst) {
    Profiler p(8);
    const int s = p.addSlot("x", Phase::Fixed, false);
    for (int i = 1; i <= 3; ++i) {
        p.record(s, 0, i * kMs); // the ring still filling
    }
    EXPECT_NEAR(p.recentStats(2).at(0).meanMs, 2.5, 1e-9);
    for (int i = 4; i <= 13; ++i) {
        p.record(s, 0, i * kMs); // wrapped: the ring holds 6..13
    }
    EXPECT_NEAR(p.recentStats(3).at(0).meanMs, 12.0, 1e-9);
    EXPECT_NEAR(p.recentStats(100).at(0).meanMs, 9.5, 1e-9) << "no more than the ring holds";
    EXPECT_EQ(p.recentStats(3).at(0).name, "x");
    const int fixed = p.addSlot("phase:fixed", Phase::Fixed, true);
    for (int f = 1; f <= 10; ++f) {
        p.beginFrame(std::uint64_t(f));
        p.record(fixed, 0, f * kMs);
        p.endFrame();
    }
    EXPECT_EQ(p.recentPhysics(3), (std::vector<float>{8.0f, 9.0f, 10.0f}));
}

TEST(Profiler, FramePhysicsSumsFixedPhaseAndCountsOverBudget) {
    Profiler p;
    p.setPhysicsBudgetMs(5.0);
    const int fixed = p.addSlot("phase:fixed", Phase::Fixed, true);
    const int frame = p.addSlot("phase:frame", Phase::Frame, true);
    const int sys = p.addSlot("springs", Phase::Fixed, false);
    for (int f = 0; f < 10; ++f) {
        p.beginFrame(std::uint64_t(f));
        // two substeps of 2 ms each (a 6 ms frame every fifth frame)
        p.record(sys, 0, 2 * kMs);
        p.record(fixed, 0, 2 * kMs);
        p.record(fixed, 0, (f % 5 == 4 ? 4 : 2) * kMs);
        p.record(frame, 0, 1 * kMs);
        p.endFrame();
    }
    const FrameStats fs = p.frameStats();
    EXPECT_EQ(fs.frames, 10u);
    EXPECT_NEAR(fs.physicsP50Ms, 4.0, 1e-6) << "system timers must not be counted twice";
    EXPECT_NEAR(fs.physicsMaxMs, 6.0, 1e-9);
    EXPECT_NEAR(fs.renderP50Ms, 1.0, 1e-6);
    EXPECT_EQ(fs.overBudgetFrames, 2u);
}

// a percentile is one of the samples, kept in float milliseconds, the maximum in whole nanoseconds:
// 25,328,500 ns is 25.3285007 ms in float, above the maximum's 25.3285 (a sweep's table showed physics_p99_ms
// over physics_max_ms so)
TEST(Profiler, NoPercentileIsAboveTheMaximum) {
    Profiler p;
    const int fixed = p.addSlot("phase:fixed", Phase::Fixed, true);
    const int sys = p.addSlot("springs", Phase::Fixed, false);
    constexpr std::int64_t kRoundsUp = 25'328'500;
    ASSERT_GT(double(float(double(kRoundsUp) * 1e-6)), double(kRoundsUp) * 1e-6)
        << "not a case that rounds up";
    p.beginFrame(0);
    p.record(sys, 0, kRoundsUp);
    p.record(fixed, 0, kRoundsUp);
    p.endFrame();
    const FrameStats fs = p.frameStats();
    EXPECT_LE(fs.physicsP99Ms, fs.physicsMaxMs);
    EXPECT_LE(fs.physicsP50Ms, fs.physicsMaxMs);
    EXPECT_NEAR(fs.physicsP99Ms, 25.3285, 1e-5);
    for (const SlotStats& st : p.slotStats()) {
        EXPECT_LE(st.p99Ms, st.maxMs) << st.name;
        EXPECT_LE(st.p50Ms, st.maxMs) << st.name;
    }
}

// a system's stages are listed right after it, marked as its stages, and do not count twice in the
// frame's physics (their system's phase already holds their time)
TEST(Profiler, StagesAreListedUnderTheirSystemAndNotAddedToPhysics) {
    Profiler p;
    const int phase = p.addSlot("phase:fixed", Phase::Fixed, true);
    const int springs = p.addSlot("springs", Phase::Fixed, false);
    const int water = p.addSlot("water", Phase::Fixed, false);
    p.beginFrame(1);
    p.record(water, 0, 1 * kMs);
    // stages made on first use, after every system; the springs' after the water's slot
    const int solve = p.stageSlot("springs.solve", Phase::Fixed);
    p.record(solve, 0, 3 * kMs);
    { ProfileStage untimed(nullptr, "springs.assemble"); }
    { ProfileStage timed(&p, "springs.assemble"); }
    EXPECT_EQ(p.stageSlot("springs.solve", Phase::Fixed), solve) << "a stage's slot is made once";
    p.record(springs, 0, 4 * kMs);
    p.record(phase, 0, 5 * kMs);
    // a stage whose system this profiler does not have: listed last, as a row of its own (its name whole),
    // not indented under the row above it (fem_jelly's budget table showed its fem stages under "air")
    p.record(p.stageSlot("fem.solve", Phase::Fixed), 0, 1 * kMs);
    p.endFrame();
    std::vector<std::string> names, owners;
    for (const SlotStats& st : p.slotStats()) {
        names.push_back(st.name);
        owners.push_back(st.stageOf);
    }
    EXPECT_EQ(names, (std::vector<std::string>{"phase:fixed", "springs", "springs.solve", "springs.assemble",
                                               "water", "fem.solve"}));
    EXPECT_EQ(owners, (std::vector<std::string>{"", "", "springs", "springs", "", ""}));
    EXPECT_EQ(p.slotStats()[3].calls, 1u) << "the untimed stage recorded nothing";
    EXPECT_NEAR(p.frameStats().physicsMaxMs, 5.0, 1e-9) << "only the phase counts as physics";
}

TEST(Profiler, ScopedTimerMeasuresItsScope) {
    Profiler p;
    const int s = p.addSlot("sleepy", Phase::Frame, false);
    {
        TUMBLE_PROFILE_SCOPE(p, s);
        const std::int64_t until = p.nowNs() + 2 * kMs;
        while (p.nowNs() < until) {
        }
    }
    const SlotStats st = p.slotStats().at(0);
    EXPECT_EQ(st.calls, 1u);
    EXPECT_GE(st.maxMs, 2.0);
}

TEST(Profiler, TraceIsValidTraceEventJsonWithAnEventPerScopeAndFrame) {
    Profiler p;
    p.enableTrace(true);
    const int fixed = p.addSlot("phase:fixed", Phase::Fixed, true);
    const int sys = p.addSlot("springs", Phase::Fixed, false);
    for (int f = 0; f < 3; ++f) {
        p.beginFrame(std::uint64_t(f));
        p.record(sys, 10, 5);
        p.record(fixed, 8, 9);
        p.endFrame();
    }
    std::ostringstream trace;
    p.writeTrace(trace);
    const auto j = nlohmann::json::parse(trace.str());
    ASSERT_TRUE(j.contains("traceEvents"));
    int springs = 0, frames = 0;
    for (const auto& e : j["traceEvents"]) {
        ASSERT_TRUE(e.contains("ph"));
        if (e["ph"] != "X") {
            continue;
        }
        for (const char* k : {"name", "ts", "dur", "pid", "tid"}) {
            EXPECT_TRUE(e.contains(k)) << k;
        }
        springs += e["name"] == "springs";
        frames += e["name"] == "frame";
    }
    EXPECT_EQ(springs, 3);
    EXPECT_EQ(frames, 3);
}

TEST(Profiler, TraceStopsAtItsLimitAndSaysSo) {
    Profiler p(16);
    p.enableTrace(true);
    const int s = p.addSlot("x", Phase::Fixed, false);
    for (std::size_t i = 0; i < Profiler::kMaxTraceEvents + 10; ++i) {
        p.record(s, std::int64_t(i), 1);
    }
    EXPECT_EQ(p.traceEventCount(), Profiler::kMaxTraceEvents);
    EXPECT_TRUE(p.traceTruncated());
    EXPECT_EQ(p.slotStats().at(0).calls, Profiler::kMaxTraceEvents + 10) << "statistics go on past the limit";
}

TEST(Profiler, NoTraceEventsUnlessEnabled) {
    Profiler p;
    const int s = p.addSlot("x", Phase::Fixed, false);
    p.beginFrame(0);
    p.record(s, 0, 1);
    p.endFrame();
    EXPECT_EQ(p.traceEventCount(), 0u);
}

} // namespace
} // namespace tumble
