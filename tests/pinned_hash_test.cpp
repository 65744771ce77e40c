// Every demo's state hashes over its first frames, pinned (as Box2D pins EXPECTED_HASH): any change of
// simulated bits fails here, so that it is made on purpose. Each demo, and a scene holding every kind of
// component (tests/data/every_kind.toml), runs at 1, 2, 3, 4, 7 and 16 threads, and every thread count
// must give the one pinned hash (as Box2D's determinism test does for 1 to 32 workers): the same bits
// on any machine's cores. When a change of bits is intended, run
//   TUMBLE_PRINT_PINNED=1 build/tests/tumble_tests --gtest_filter='*PinnedHash*'
// and paste the table it prints, saying in the commit why the bits changed.
//
// The reference is the state of an earlier build, not a prediction: this test proves only that the bits
// did not move; the physics tests say whether they are right.

#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <map>

namespace tumble {
namespace {

constexpr int kFrames = 120;     ///< frames hashed per demo
constexpr int kStressFrames = 4; ///< for the stress scenes (one frame of stress_cloth is 0.1-0.2 s)

/// The demos' hashes: FNV-1a over the state hash after each of the first frames (x86-64, g++ 12).
const std::map<std::string, std::uint64_t>& pinned() {
    static const std::map<std::string, std::uint64_t> table = {
        {"avalanche", 0x55c1fdbb295c58b6ull},   {"bridge", 0x4ee39f98ae6cf80full},
        {"chimney", 0xf5ad029d3a1c84d3ull},     {"contraption2d", 0xf68f4c5c3b907a05ull},
        {"crane", 0x56c11292c606c702ull},       {"curtain", 0x2b806649d90cce2aull},
        {"drape", 0x38e0a50832ce2409ull},       {"drape_sphere", 0xdf629cdbcd4ad5d6ull},
        {"fan_flag", 0xae08b1050bfdd4a5ull},    {"fem_jelly", 0x9e703ce775824432ull},
        {"fireworks", 0xea8c13de27cd72c5ull},   {"flag", 0xbeea6abe48feb455ull},
        {"fountain", 0xe26792894f3d3a68ull},    {"harbour", 0x8a137bc5bee95da3ull},
        {"integrators", 0x462825650b0a4cb7ull}, {"jelly", 0x7d570d3c1f75e29bull},
        {"million", 0x587ecacbf86a3bf3ull},     {"pendulum", 0x903024d1c9b6ccebull},
        {"pile", 0x28cd3349af415c55ull},        {"pond", 0x934875f3fb4a84e5ull},
        {"pyramid2d", 0x616eb2117a7da742ull},   {"rope", 0xf9ad053ddd27a71bull},
        {"smoke", 0xca8e7f1267a439adull},       {"stress_cloth", 0x55175e76fedad2a5ull},
        {"tablecloth", 0xd9cfe5375fe5d6f8ull},  {"twist", 0x24657507bc97173full},
        {"wake", 0x08375306ae93b6f5ull},        {"every_kind", 0x72673fbb4a130e8eull},
    };
    return table;
}

/// The thread counts every scene runs at.
constexpr int kThreadCounts[] = {1, 2, 3, 4, 7, 16};

std::string scenePath(const std::string& scene) {
    const std::string source = TUMBLE_SOURCE_DIR;
    return scene == "every_kind" ? source + "/tests/data/every_kind.toml"
                                 : source + "/demos/" + scene + ".toml";
}

std::uint64_t framesHash(const std::string& scene, int threads) {
    auto sim = test::makeSimulation(test::readFile(scenePath(scene)));
    sim->setThreads(threads);
    // at odd thread counts every step runs its systems side by side (not only where it pays): both
    // ways of running the schedule must give the pinned bits
    sim->schedule().setAlwaysSideBySide(threads % 2 == 1);
    const int frames = sim->scene().stress ? kStressFrames : kFrames;
    std::uint64_t h = 1469598103934665603ull;
    for (int f = 0; f < frames; ++f) {
        sim->runFrame();
        const std::uint64_t s = sim->hash();
        for (int b = 0; b < 8; ++b) {
            h = (h ^ ((s >> (8 * b)) & 0xffu)) * 1099511628211ull;
        }
    }
    return h;
}

class PinnedHash : public ::testing::TestWithParam<std::tuple<std::string, int>> {};

TEST_P(PinnedHash, FirstFramesHaveThePinnedBitsAtAnyThreadCount) {
    const auto& [scene, threads] = GetParam();
    const std::uint64_t h = framesHash(scene, threads);
    if (std::getenv("TUMBLE_PRINT_PINNED") && threads == 1) {
        std::printf("        {\"%s\", 0x%016llxull},\n", scene.c_str(), static_cast<unsigned long long>(h));
    }
    const auto it = pinned().find(scene);
    ASSERT_NE(it, pinned().end()) << "no pinned hash for " << scene
                                  << ": add the line printed with TUMBLE_PRINT_PINNED=1";
    EXPECT_EQ(h, it->second) << "the simulated bits of " << scene << " at " << threads
                             << " threads differ from the pinned ones: "
                             << (threads == 1 ? "if on purpose, re-pin (see the top of this file)"
                                              : "a thread count must never change a bit");
}

std::vector<std::string> scenes() {
    std::vector<std::string> out = test::demoNames();
    out.push_back("every_kind");
    return out;
}

INSTANTIATE_TEST_SUITE_P(Scenes, PinnedHash,
                         ::testing::Combine(::testing::ValuesIn(scenes()),
                                            ::testing::ValuesIn(kThreadCounts)),
                         [](const ::testing::TestParamInfo<PinnedHash::ParamType>& p) {
                             return std::get<0>(p.param) + "_threads" + std::to_string(std::get<1>(p.param));
                         });

} // namespace
} // namespace tumble
