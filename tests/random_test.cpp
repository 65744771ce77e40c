#include "engine/random.h"

#include <gtest/gtest.h>

#include <cmath>

namespace tumble {
namespace {

TEST(Random, SameSeedSameStream) {
    Rng a(streamSeed(7, "emitter:fountain")), b(streamSeed(7, "emitter:fountain"));
    for (int i = 0; i < 1000; ++i) {
        ASSERT_EQ(a.next(), b.next());
    }
}

TEST(Random, PurposesAndSeedsGiveDifferentStreams) {
    EXPECT_NE(streamSeed(7, "emitter:a"), streamSeed(7, "emitter:b"));
    EXPECT_NE(streamSeed(7, "emitter:a"), streamSeed(8, "emitter:a"));
    Rng a(streamSeed(7, "x")), b(streamSeed(7, "y"));
    int same = 0;
    for (int i = 0; i < 1000; ++i) {
        same += a.next() == b.next();
    }
    EXPECT_LT(same, 3);
}

TEST(Random, UniformIsInRangeWithTheRightMeanAndVariance) {
    Rng r(42);
    const int n = 200000;
    double sum = 0.0, sumSq = 0.0;
    for (int i = 0; i < n; ++i) {
        const double u = r.uniform(-2.0, 4.0);
        ASSERT_GE(u, -2.0);
        ASSERT_LT(u, 4.0);
        sum += u;
        sumSq += u * u;
    }
    const double mean = sum / n, var = sumSq / n - mean * mean;
    // U(-2, 4): mean 1, variance 36/12 = 3; the mean's standard error is sqrt(3/n) = 0.004
    EXPECT_NEAR(mean, 1.0, 0.02);
    EXPECT_NEAR(var, 3.0, 0.05);
}

} // namespace
} // namespace tumble
