// Every demo in demos/ loads, runs a few frames headlessly and dumps a finite state, and renders a frame
// with something in it while recording a replay, which then verifies.

#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <stb/stb_image.h>

namespace tumble {
namespace {

class Demo : public ::testing::TestWithParam<std::string> {};

TEST_P(Demo, RunsHeadlesslyForAFewFrames) {
    const std::string dump = test::tempPath(GetParam() + ".jsonl");
    const auto r = test::runTumble({"run", GetParam(), "--no-render", "--frames", "10", "--quiet", "--dump",
                                    dump, "--out", test::tempPath(GetParam())});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const std::string text = test::readFile(dump);
    EXPECT_EQ(text.find("NaN"), std::string::npos);
    EXPECT_EQ(text.find("Infinity"), std::string::npos);
    const auto j = nlohmann::json::parse(text);
    EXPECT_EQ(j["frame"], 10);
    EXPECT_FALSE(j["entities"].empty());
}

TEST_P(Demo, RendersAFrameWithSomethingInItAndItsReplayVerifies) {
    const std::string out = test::tempPath(GetParam() + "_render");
    const std::string replay = test::tempPath(GetParam() + ".tumble");
    const auto r =
        test::runTumble({"run", GetParam(), "--frames", "3", "--quiet", "--out", out, "--record", replay});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    const auto v = test::runTumble(
        {"replay", replay, "--verify", "--no-render", "--out", test::tempPath(GetParam() + "_replay")});
    EXPECT_EQ(v.exitCode, 0) << v.err;
    EXPECT_NE(v.err.find("replay verified: 3 frames"), std::string::npos) << v.err;
    const std::string png = out + "/frame_00003.png";
    int w = 0, h = 0, channels = 0;
    stbi_uc* pixels = stbi_load(png.c_str(), &w, &h, &channels, 3);
    ASSERT_NE(pixels, nullptr) << png;
    // not one flat colour: the camera sees the scene
    std::size_t differ = 0;
    for (int i = 1; i < w * h; ++i) {
        differ +=
            pixels[3 * i] != pixels[0] || pixels[3 * i + 1] != pixels[1] || pixels[3 * i + 2] != pixels[2];
    }
    stbi_image_free(pixels);
    EXPECT_GT(differ, std::size_t(w) * std::size_t(h) / 200) << png;
}

TEST_P(Demo, DeclaresABudgetWithinHalfAFrameUnlessAStressScene) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + GetParam() + ".toml";
    auto sim = test::makeSimulation(test::readFile(path));
    const std::string text = test::readFile(path);
    EXPECT_NE(text.find("physics_ms"), std::string::npos) << "every demo declares its [budget] physics_ms";
    if (!sim->scene().stress) {
        EXPECT_LE(sim->scene().physicsBudgetMs, 8.0) << "half a 60 fps frame";
    }
}

TEST_P(Demo, NameMatchesItsFile) {
    const std::string path = std::string(TUMBLE_SOURCE_DIR) + "/demos/" + GetParam() + ".toml";
    EXPECT_EQ(peekScene(path, readScenarioFile(path)).name, GetParam());
}

INSTANTIATE_TEST_SUITE_P(Demos, Demo, ::testing::ValuesIn(test::demoNames()),
                         [](const ::testing::TestParamInfo<std::string>& p) { return p.param; });

} // namespace
} // namespace tumble
