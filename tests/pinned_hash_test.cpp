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
        {"avalanche", 0x6d69c19afa328e10ull},   {"bridge", 0x3408f5c575e2bedeull},
        {"chimney", 0xf2d4abc8469c2d59ull},     {"contraption2d", 0xaf1caa8504ef4438ull},
        {"crane", 0x2ec4afa5ae8257e7ull},       {"curtain", 0x867ac71c16d4953bull},
        {"drape", 0x74412b0c8b3c1103ull},       {"drape_sphere", 0xac014db4a1b3baf6ull},
        {"fan_flag", 0xac6c9241253d5f7full},    {"fem_jelly", 0x8129f6f079a8488dull},
        {"fireworks", 0x3bdcd0d4e9e2040dull},   {"flag", 0x6520a37fdfd7c441ull},
        {"fountain", 0x96c4ec7da42939c6ull},    {"harbour", 0x1658e5d030925885ull},
        {"integrators", 0x8963cf2ba1e41e6full}, {"jelly", 0x6028c919bfbf2862ull},
        {"million", 0xe0cb21353e5201fbull},     {"pendulum", 0x8fe933336facf719ull},
        {"pile", 0x22aa2bc362a7dab0ull},        {"pond", 0x90eeeb06d4d2dfa8ull},
        {"pyramid2d", 0xaaf1caf17cbaca9bull},   {"rope", 0x88334b26b042cf35ull},
        {"smoke", 0x705a8ff5adce9556ull},       {"stress_cloth", 0x95c511dfa8cbad49ull},
        {"tablecloth", 0xfb7dd1be99b6fe87ull},  {"twist", 0x9503f84857a28cc7ull},
        {"wake", 0x0d83431e8bb04badull},        {"every_kind", 0xb050df2c24a6e6ebull},
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
