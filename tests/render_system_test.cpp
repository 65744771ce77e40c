// The renderer on real pixels from the real EGL context (Mesa's llvmpipe here): coverage of a sphere
// against its predicted projection, left and right, particle colours, PNG round trips, and a clear error
// when no EGL display can be had.

#include "app/gl_context.h"
#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/spring_network.h"
#include "engine/render_output.h"
#include "engine/simulation.h"
#include "systems/render_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <stb/stb_image.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>

namespace tumble {
namespace {

struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
    const std::uint8_t* at(int x, int y) const {
        return &rgba[(std::size_t(y) * std::size_t(width) + std::size_t(x)) * 4];
    }
};

/// Renders one frame of a scenario in this process and returns the image.
Image renderOnce(const std::string& text) {
    auto sim = test::makeSimulation(text);
    RenderOutput& out = sim->world().setResource<RenderOutput>();
    out.enabled = true;
    out.openContext = openHeadlessContext;
    out.directory = test::tempPath("render");
    out.lastFrame = 0; // no PNG
    sim->runFrame();
    Image img;
    EXPECT_TRUE(lastImage(sim->world(), img.width, img.height, img.rgba));
    return img;
}

const char* kCamera = R"(
[scene]
name = "view"
gravity = [0, 0, 0]
[camera]
eye = [0.0, 0.0, 5.0]
target = [0.0, 0.0, 0.0]
fov_deg = 45.0
[render]
width = 640
height = 480
background = [1.0, 1.0, 1.0]
)";

std::string sphereAt(double x, double radius) {
    return std::string(kCamera) + "[[entity]]\nname = \"ball\"\n[entity.transform]\nposition = [" +
           std::to_string(x) +
           ", 0, 0]\n[entity.rigid_body]\nshape = \"sphere\"\nradius = " + std::to_string(radius) +
           "\ncolor = [1.0, 0.0, 0.0]\n";
}

bool isBackground(const std::uint8_t* p) {
    return p[0] > 250 && p[1] > 250 && p[2] > 250;
}

TEST(RenderSystem, RedSphereCoversItsPredictedProjection) {
    const Image img = renderOnce(sphereAt(0.0, 1.0));
    ASSERT_EQ(img.width, 640);
    std::size_t covered = 0, red = 0, bright = 0;
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            const std::uint8_t* p = img.at(x, y);
            if (!isBackground(p)) {
                ++covered;
                // shaded red: green and blue stay zero however dark the side turned from the light is
                red += p[1] == 0 && p[2] == 0;
                bright += p[0] > 128;
            }
        }
    }
    // a sphere of radius 1 at distance 5 subtends asin(1/5); in pixels f tan(asin(0.2)), f = H / (2
    // tan(fov/2))
    const double f = 480.0 / (2.0 * std::tan(45.0 * std::numbers::pi / 360.0));
    const double r = f * std::tan(std::asin(0.2));
    const double predicted = std::numbers::pi * r * r;
    EXPECT_NEAR(double(covered), predicted, 0.02 * predicted);
    EXPECT_EQ(red, covered) << "every covered pixel is a shade of red";
    EXPECT_GT(bright, covered / 3) << "the lit side is bright";
}

TEST(RenderSystem, AnObjectLeftOfTheTargetAppearsOnTheLeft) {
    for (double x : {-1.5, 1.5}) {
        const Image img = renderOnce(sphereAt(x, 0.5));
        double sumX = 0.0, count = 0.0;
        for (int y = 0; y < img.height; ++y) {
            for (int px = 0; px < img.width; ++px) {
                if (!isBackground(img.at(px, y))) {
                    sumX += px;
                    count += 1.0;
                }
            }
        }
        ASSERT_GT(count, 100.0);
        if (x < 0) {
            EXPECT_LT(sumX / count, img.width / 2.0 - 50.0);
        } else {
            EXPECT_GT(sumX / count, img.width / 2.0 + 50.0);
        }
    }
}

TEST(RenderSystem, AParticleBurstShowsItsColour) {
    const Image img = renderOnce(std::string(kCamera) + R"(
[[entity]]
name = "sparks"
[entity.emitter]
burst = 2000
speed = [0.0, 0.0]
shape = "sphere"
radius = 1.0
lifetime = [100.0, 100.0]
collide = false
color = [[0.0, 0.8, 0.1, 1.0], [0.0, 0.8, 0.1, 1.0]]
size = [0.05, 0.05]
)");
    std::size_t green = 0, other = 0;
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            const std::uint8_t* p = img.at(x, y);
            if (isBackground(p)) {
                continue;
            }
            // green, blended over white at the soft edges: green dominates every drawn pixel
            (p[1] > p[0] && p[1] > p[2] ? green : other) += 1;
        }
    }
    EXPECT_GT(green, 5000u);
    EXPECT_LT(other, green / 50);
}

/// Mean column of the pixels that are not background, in pixel units (pixel centres at +0.5).
double centroidX(const Image& img) {
    double sumX = 0.0, count = 0.0;
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            if (!isBackground(img.at(x, y))) {
                sumX += x + 0.5;
                count += 1.0;
            }
        }
    }
    EXPECT_GT(count, 100.0);
    return sumX / count;
}

/// Where a point of the plane z = 0 lands across the image of kCamera (640 wide, 45 degrees, 5 m away).
double projectedX(double x) {
    const double f = 480.0 / (2.0 * std::tan(45.0 * std::numbers::pi / 360.0));
    return 320.0 + f * x / 5.0;
}

/// Draws the frame again at `alpha` between the last two fixed steps, and reads it back.
Image redrawAt(Simulation& sim, double alpha) {
    StepContext ctx;
    ctx.dt = sim.scene().dt;
    ctx.alpha = alpha;
    renderWorld(sim.world(), ctx);
    Image img;
    EXPECT_TRUE(lastImage(sim.world(), img.width, img.height, img.rgba));
    return img;
}

std::unique_ptr<Simulation> renderedSimulation(const std::string& text) {
    auto sim = test::makeSimulation(text);
    RenderOutput& out = sim->world().setResource<RenderOutput>();
    out.enabled = true;
    out.openContext = openHeadlessContext;
    out.directory = test::tempPath("render");
    out.lastFrame = 0; // no PNG
    return sim;
}

TEST(RenderSystem, AMassIsDrawnBetweenTheLastTwoStepsAtAlpha) {
    // one free mass crossing the view at 60 m/s: 1 m per step of 1/60 s, from x = -1.5 to x = -0.5
    auto sim = renderedSimulation(std::string(kCamera) + R"(
[[entity]]
name = "mass"
[entity.springs]
integrator = "symplectic_euler"
thickness = 0.3
masses = [ { x = [-1.5, 0.0, 0.0], m = 1.0, v = [60.0, 0.0, 0.0] } ]
)");
    sim->runFrame();
    const SpringNetwork& net = test::component<SpringNetwork>(*sim, "mass");
    ASSERT_NEAR(net.x[0].x, -0.5, 1e-9);
    for (double alpha : {0.0, 0.25, 0.5, 1.0}) {
        const double x = -1.5 + alpha * 1.0;
        EXPECT_NEAR(centroidX(redrawAt(*sim, alpha)), projectedX(x), 1.5) << "alpha " << alpha;
    }
}

TEST(RenderSystem, ARigidBodyIsDrawnBetweenTheLastTwoStepsAtAlpha) {
    auto sim = renderedSimulation(std::string(kCamera) + R"(
[[entity]]
name = "ball"
[entity.transform]
position = [-1.5, 0.0, 0.0]
[entity.rigid_body]
shape = "sphere"
radius = 0.3
mass = 1.0
linear_velocity = [60.0, 0.0, 0.0]
color = [1.0, 0.0, 0.0]
)");
    sim->runFrame();
    ASSERT_NEAR(test::component<RigidBody>(*sim, "ball").position.x, -0.5, 1e-5);
    for (double alpha : {0.0, 0.5, 1.0}) {
        EXPECT_NEAR(centroidX(redrawAt(*sim, alpha)), projectedX(-1.5 + alpha), 1.5) << "alpha " << alpha;
    }
}

TEST(RenderSystem, AParticleIsDrawnBetweenTheLastTwoStepsAtAlpha) {
    auto sim = renderedSimulation(std::string(kCamera) + R"(
[[entity]]
name = "spark"
[entity.transform]
position = [-1.5, 0.0, 0.0]
[entity.emitter]
shape = "point"
burst = 1
direction = [1.0, 0.0, 0.0]
spread_deg = 0.0
speed = [60.0, 60.0]
lifetime = [100.0, 100.0]
collide = false
color = [[0.0, 0.0, 1.0, 1.0], [0.0, 0.0, 1.0, 1.0]]
size = [0.6, 0.6]
)");
    sim->runFrame();
    sim->runFrame();
    const ParticlePool& pool = test::component<ParticleEmitter>(*sim, "spark").pool;
    ASSERT_EQ(pool.count, 1u);
    for (double alpha : {0.0, 0.5, 1.0}) {
        const double x = pool.px[0] - (1.0 - alpha) * sim->scene().dt * pool.vx[0];
        EXPECT_NEAR(centroidX(redrawAt(*sim, alpha)), projectedX(x), 1.5) << "alpha " << alpha;
    }
    // and that is where it was a step ago: it moved by 1 m a step
    EXPECT_NEAR(pool.px[0], -1.5 + 2.0, 1e-4);
}

TEST(RenderSystem, PngWrittenAndReadBackIsIdentical) {
    const Image img = renderOnce(sphereAt(0.3, 0.8));
    const std::string path = test::tempPath("roundtrip.png");
    writePng(path, img.width, img.height, img.rgba);
    int w = 0, h = 0, channels = 0;
    stbi_uc* back = stbi_load(path.c_str(), &w, &h, &channels, 4);
    ASSERT_NE(back, nullptr);
    EXPECT_EQ(w, img.width);
    EXPECT_EQ(h, img.height);
    EXPECT_TRUE(std::equal(img.rgba.begin(), img.rgba.end(), back));
    stbi_image_free(back);
}

TEST(RenderSystem, RunWritesTheLastFrameAndEveryKth) {
    const std::string out = test::tempPath("frames");
    const auto r =
        test::runTumble({"run", "pendulum", "--frames", "7", "--png-every", "3", "--out", out, "--quiet"});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    for (const char* f : {"frame_00003.png", "frame_00006.png", "frame_00007.png"}) {
        EXPECT_TRUE(std::filesystem::exists(out + "/" + f)) << f;
    }
    EXPECT_FALSE(std::filesystem::exists(out + "/frame_00005.png"));
}

TEST(RenderSystem, NoEglDisplayIsAClearErrorNotACrash) {
    // glvnd finds no vendor library: no EGL at all
    const auto r = test::runTumble(
        {"run", "pendulum", "--frames", "2", "--out", test::tempPath("noegl")},
        {"__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json", "__EGL_VENDOR_LIBRARY_DIRS=/nonexistent"});
    EXPECT_EQ(r.exitCode, 1) << r.err;
    EXPECT_NE(r.err.find("--no-render"), std::string::npos) << r.err;
    const auto simulated = test::runTumble(
        {"run", "pendulum", "--frames", "2", "--no-render", "--out", test::tempPath("noegl2")},
        {"__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json", "__EGL_VENDOR_LIBRARY_DIRS=/nonexistent"});
    EXPECT_EQ(simulated.exitCode, 0) << "--no-render needs no EGL: " << simulated.err;
}

TEST(RenderSystem, AVideoOfNFramesHasNFrames) {
    for (const char* ext : {".mp4", ".gif"}) {
        const std::string video = test::tempPath(std::string("clip") + ext);
        const auto r = test::runTumble({"run", "fountain", "--frames", "24", "--video", video, "--quiet",
                                        "--out", test::tempPath("clip")});
        ASSERT_EQ(r.exitCode, 0) << r.err;
        // ffprobe decodes the whole file and counts its frames
        const std::string count = test::tempPath("frames.txt");
        const std::string probe = "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                                  "stream=nb_read_frames -of csv=p=0 '" +
                                  video + "' > '" + count + "'";
        ASSERT_EQ(std::system(probe.c_str()), 0) << probe;
        EXPECT_EQ(std::stoi(test::readFile(count)), 24) << ext;
    }
}

TEST(RenderSystem, VideoWithoutFfmpegIsAClearError) {
    const auto r = test::runTumble({"run", "pendulum", "--frames", "2", "--video", test::tempPath("x.mp4"),
                                    "--out", test::tempPath("noffmpeg")},
                                   {"PATH=/nonexistent"});
    EXPECT_EQ(r.exitCode, 1) << r.err;
    EXPECT_NE(r.err.find("ffmpeg"), std::string::npos) << r.err;
    const auto bad =
        test::runTumble({"run", "pendulum", "--frames", "2", "--video", test::tempPath("x.avi")});
    EXPECT_EQ(bad.exitCode, 2) << "a bad file name is bad input";
    EXPECT_NE(bad.err.find(".mp4 or .gif"), std::string::npos) << bad.err;
}

} // namespace
} // namespace tumble
