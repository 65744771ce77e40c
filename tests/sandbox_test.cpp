// The embedding API's C++ side (include/tumble/sandbox.h) where Python cannot reach it: a moved-from
// Sandbox, a negative frame count and thread counts out of range throw instead of crashing or being
// taken silently (the Python module's own checks are in tests/python).

#include "tumble/sandbox.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <utility>

namespace tumble {
namespace {

TEST(Sandbox, AMovedFromSandboxThrowsFromEveryCall) {
    // it dereferenced its null state: a segfault
    Sandbox a("rope", {}, 1);
    Sandbox b(std::move(a));
    b.step(1);
    EXPECT_EQ(b.frame(), 1u);
    EXPECT_THROW(a.step(1), std::logic_error);      // NOLINT(bugprone-use-after-move): the point
    EXPECT_THROW((void)a.hash(), std::logic_error); // NOLINT(bugprone-use-after-move)
    EXPECT_THROW((void)a.x("chain"), std::logic_error);
}

TEST(Sandbox, ANegativeFrameCountThrows) {
    // step(-5) did nothing and said nothing
    Sandbox s("rope", {}, 1);
    EXPECT_THROW(s.step(-5), std::invalid_argument);
    EXPECT_EQ(s.frame(), 0u);
}

TEST(Sandbox, AThreadCountOutOfRangeThrows) {
    // -1 ran on two threads and 100000 on 256
    for (const int threads : {-1, -1000, 257, 100000}) {
        EXPECT_THROW(Sandbox("rope", {}, threads), std::invalid_argument) << threads;
        EXPECT_THROW((void)verifyReplay("none.tumble", threads), std::invalid_argument) << threads;
    }
    EXPECT_NO_THROW(Sandbox("rope", {}, 256));
}

} // namespace
} // namespace tumble
