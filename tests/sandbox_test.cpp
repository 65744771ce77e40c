// The embedding API's C++ side (include/tumble/sandbox.h) where Python cannot reach it: a moved-from
// Sandbox, a negative frame count and thread counts out of range throw instead of crashing or being
// taken silently (the Python module's own checks are in tests/python).

#include "tumble/sandbox.h"

#include "engine/replay.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
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

// verifyReplay names the file in every verdict: a divergence's began "the replay diverged at frame" alone,
// while a cut-short or stopped replay's began with the path.
TEST(Sandbox, VerifyReplayNamesTheFileOfADivergence) {
    const std::string recorded = test::tempPath("sandbox_verify.tumble");
    {
        Sandbox s("rope", {}, 1);
        s.record(recorded);
        s.step(4);
        s.finishRecording();
    }
    EXPECT_EQ(verifyReplay(recorded, 1), "");
    // the same replay with frame 3's state hashes changed (the frame's and its first entity's)
    ReplayFile file = readReplay(recorded);
    ASSERT_EQ(file.frames.size(), 4u);
    const std::string altered = test::tempPath("sandbox_verify_altered.tumble");
    {
        ReplayWriter w(altered, file.header);
        for (std::size_t k = 0; k < file.frames.size(); ++k) {
            FrameRecord f = file.frames[k];
            for (EntityHash& e : f.entities) {
                e.name = file.names[e.id].first; // as read, names are kept once in the file's table
                e.kind = file.names[e.id].second;
            }
            if (k == 2) {
                f.hash ^= 1;
                f.entities.front().hash ^= 1;
            }
            w.frame(f);
        }
        w.finish();
    }
    const std::string said = verifyReplay(altered, 1);
    EXPECT_EQ(said.rfind(altered + ": the replay diverged at frame 3", 0), 0u) << said;
}

} // namespace
} // namespace tumble
