#include "engine/fixed_loop.h"

#include <gtest/gtest.h>

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
    // 60 steps of 1/60 s fed as 60 frames of 16'666'667 ns: an hour of frames gives an hour of steps
    FixedLoop loop(kStep, 8);
    std::int64_t steps = 0;
    for (int i = 0; i < 60 * 60 * 60; ++i) {
        steps += loop.advance(kStep).steps;
    }
    EXPECT_EQ(steps, 60 * 60 * 60);
    EXPECT_EQ(loop.accumulatorNs(), 0);
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
