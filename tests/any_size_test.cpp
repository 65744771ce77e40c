// The same bits at any thread count for sizes no demo has. The pinned demos (pinned_hash_test.cpp) hold
// their own sizes, and every_kind's are small (a 12 x 12 cloth, a 40 x 40 pool): the loops' chunk
// boundaries, the multigrid's levels and colourings, the particles' chunks of births and the air's slabs
// fall elsewhere at other sizes, and so could a dependence on the thread count. Here the scene of every kind
// (tests/data/every_kind.toml) is run with its sizes drawn at random (fixed seeds): cloths of 20 to 48
// masses a side (a multigrid's levels are swept by colour from 1024 rows), softbodies of 2 to 9 cells
// a side, thousands of particles a second, pools of 20 to 150 cells a side and rooms of air of 6 x 8 x 6 to
// 27 x 36 x 27 cells. (The ropes and the fem beam keep their sizes: joints hold them by a mass's number.)
// Each variant runs a few frames at 1, 2, 3 and 7 threads, with the systems side by side at the odd counts;
// every frame's state hash must equal the one-thread run's.
//
// The reference is the one-thread run of the same build, not a prediction: this proves that the bits do
// not depend on the thread count; the physics tests say whether they are right.

#include "engine/random.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <initializer_list>
#include <string>
#include <vector>

namespace tumble {
namespace {

constexpr int kFrames = 8;
constexpr int kThreadCounts[] = {2, 3, 7};

/// Overrides of every_kind's sizes, drawn from seed (one after another, so that any compiler draws the same).
std::vector<std::string> randomSizes(std::uint64_t seed) {
    Rng rng(seed);
    auto draw = [&](int low, int high) { return low + int(rng.uniform(0.0, double(high - low) + 0.999)); };
    auto list = [&](std::initializer_list<int> values) {
        std::string text = "[";
        for (int v : values) {
            text += (text.size() > 1 ? ", " : "") + std::to_string(v);
        }
        return text + "]";
    };
    const int rows = draw(20, 48), cols = draw(20, 48);
    const int jellyX = draw(2, 9), jellyY = draw(2, 9), jellyZ = draw(2, 9);
    const int rate = draw(1000, 40000), burst = draw(0, 3000);
    const int poolX = draw(20, 150), poolZ = draw(20, 150);
    const int cube = draw(2, 9); // the room is 1.5 x 2 x 1.5 m: cells of 0.5 / cube m
    return {
        "sheet.cloth.rows=" + std::to_string(rows),
        "sheet.cloth.cols=" + std::to_string(cols),
        "jelly.softbody.resolution=" + list({jellyX, jellyY, jellyZ}),
        "spray.emitter.rate=" + std::to_string(rate),
        "spray.emitter.burst=" + std::to_string(burst),
        "pool.water.cells=" + list({poolX, poolZ}),
        "room.air.cells=" + list({3 * cube, 4 * cube, 3 * cube}),
    };
}

/// The state hash after each of the first kFrames frames.
std::vector<std::uint64_t> frameHashes(const std::vector<std::string>& sizes, int threads) {
    auto sim = test::makeSimulation(test::readFile(TUMBLE_SOURCE_DIR "/tests/data/every_kind.toml"), sizes);
    sim->setThreads(threads);
    sim->schedule().setAlwaysSideBySide(threads % 2 == 1);
    std::vector<std::uint64_t> hashes;
    for (int f = 0; f < kFrames; ++f) {
        sim->runFrame();
        hashes.push_back(sim->hash());
    }
    return hashes;
}

class AnySize : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(AnySize, EveryKindAtRandomSizesHasTheSameBitsAtAnyThreadCount) {
    const std::vector<std::string> sizes = randomSizes(GetParam());
    std::string described;
    for (const std::string& s : sizes) {
        described += " --set " + s;
    }
    const std::vector<std::uint64_t> one = frameHashes(sizes, 1);
    for (int threads : kThreadCounts) {
        const std::vector<std::uint64_t> many = frameHashes(sizes, threads);
        for (int f = 0; f < kFrames; ++f) {
            ASSERT_EQ(many[std::size_t(f)], one[std::size_t(f)])
                << "frame " << f + 1 << " at " << threads
                << " threads differs from one thread; the sizes:" << described;
        }
    }
}

INSTANTIATE_TEST_SUITE_P(Seeds, AnySize, ::testing::Range(std::uint64_t(1), std::uint64_t(11)));

} // namespace
} // namespace tumble
