#include "engine/fixed_loop.h"

#include <gtest/gtest.h>

#include <limits>

namespace tumble {
namespace {

class FakeClock final : public Clock {
public:
    std::int64_t now = 1'000'000;
    std::int64_t nowNs() const override { return now; }
};

constexpr std::int64_t kStep = 16'666'667; // 1/60 s

TEST(FixedLoop, FirstTickOnlyStartsTheClock) {
    FixedLoop loop(kStep, 8);
    FakeClock clock;
    const Tick t = loop.advanceTo(clock);
    EXPECT_EQ(t.steps, 0);
    EXPECT_EQ(t.alpha, 0.0);
}

TEST(FixedLoop, ZeroStepsWhenLessThanAStepElapsed) {
    FixedLoop loop(kStep, 8);
    FakeClock clock;
    loop.advanceTo(clock);
    clock.now += kStep / 2;
    const Tick t = loop.advanceTo(clock);
    EXPECT_EQ(t.steps, 0);
    EXPECT_NEAR(t.alpha, 0.5, 1e-6);
    // the half step is kept: another half makes one step
    clock.now += kStep / 2 + 1;
    EXPECT_EQ(loop.advanceTo(clock).steps, 1);
}

TEST(FixedLoop, OneStepPerFramePeriod) {
    FixedLoop loop(kStep, 8);
    FakeClock clock;
    loop.advanceTo(clock);
    for (int i = 0; i < 100; ++i) {
        clock.now += kStep;
        const Tick t = loop.advanceTo(clock);
        EXPECT_EQ(t.steps, 1);
        EXPECT_EQ(t.droppedNs, 0);
        EXPECT_EQ(t.alpha, 0.0);
    }
}

TEST(FixedLoop, ManyStepsInASlowFrame) {
    FixedLoop loop(kStep, 8);
    FakeClock clock;
    loop.advanceTo(clock);
    clock.now += 3 * kStep + kStep / 4;
    const Tick t = loop.advanceTo(clock);
    EXPECT_EQ(t.steps, 3);
    EXPECT_EQ(t.droppedNs, 0);
    EXPECT_NEAR(t.alpha, 0.25, 1e-6);
}

TEST(FixedLoop, CapDropsTimeBeyondIt) {
    FixedLoop loop(kStep, 4);
    FakeClock clock;
    loop.advanceTo(clock);
    clock.now += 10 * kStep + kStep / 2;
    const Tick t = loop.advanceTo(clock);
    EXPECT_EQ(t.steps, 4);
    EXPECT_EQ(t.droppedNs, 6 * kStep);
    EXPECT_NEAR(t.alpha, 0.5, 1e-6);
    // after the slow frame the loop is back to one step per period: no spiral
    clock.now += kStep;
    EXPECT_EQ(loop.advanceTo(clock).steps, 1);
}

TEST(FixedLoop, IntegerAccumulatorNeverDrifts) {
    // 60 Hz frames driving a 144 Hz step for an hour: no period divides the other, yet every nanosecond fed
    // in is either in a step taken or still in the accumulator
    constexpr std::int64_t kStep144 = 6'944'444, kFrame60 = 16'666'667;
    FixedLoop loop(kStep144, 8);
    std::int64_t steps = 0, fed = 0;
    for (int i = 0; i < 60 * 60 * 60; ++i) {
        const Tick t = loop.advance(kFrame60);
        fed += kFrame60;
        steps += t.steps;
        ASSERT_EQ(t.droppedNs, 0);
        ASSERT_TRUE(t.steps == 2 || t.steps == 3) << "2.4 steps a frame on average";
    }
    EXPECT_EQ(steps * kStep144 + loop.accumulatorNs(), fed);
    EXPECT_EQ(steps, fed / kStep144);
}

TEST(FixedLoop, AHugeClockJumpNeitherOverflowsNorSpirals) {
    FixedLoop loop(kStep, 4);
    const Tick t = loop.advance(std::numeric_limits<std::int64_t>::max() - 5);
    EXPECT_EQ(t.steps, 4);
    EXPECT_GT(t.droppedNs, 0);
    EXPECT_GE(t.alpha, 0.0);
    EXPECT_LT(t.alpha, 1.0);
    EXPECT_EQ(loop.advance(kStep).steps, 1);
}

TEST(FixedLoop, NegativeElapsedIsIgnored) {
    FixedLoop loop(kStep, 8);
    EXPECT_EQ(loop.advance(-5 * kStep).steps, 0);
    EXPECT_EQ(loop.accumulatorNs(), 0);
}

TEST(FixedLoop, RejectsNonPositiveStepOrCap) {
    EXPECT_THROW(FixedLoop(0, 4), std::invalid_argument);
    EXPECT_THROW(FixedLoop(kStep, 0), std::invalid_argument);
}

TEST(FixedLoop, SecondsToNsRounds) {
    EXPECT_EQ(secondsToNs(1.0 / 60.0), 16'666'667);
    EXPECT_EQ(secondsToNs(0.005), 5'000'000);
    EXPECT_EQ(secondsToNs(0.0), 1);
}

} // namespace
} // namespace tumble
