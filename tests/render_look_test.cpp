// The default look on real pixels (llvmpipe here): the sky's gradient, lighting in linear light written as
// sRGB, the hemisphere's ambient light, the floor grid far away, and water that shows what lies under it
// and reflects more at grazing angles. Every expected shade is worked out here from the sRGB standard and
// the look's stated constants (README "Rendering"), not read from the renderer.

#include "tests/render_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <string>
#include <utility>

namespace tumble {
namespace {

using test::Image;
using test::renderOnce;

using Rgb = std::array<double, 3>;

/// The sRGB transfer curve (IEC 61966-2-1) both ways.
double toLinear(double c) {
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
double toSrgb(double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}
Rgb linear(const Rgb& c) {
    return {toLinear(c[0]), toLinear(c[1]), toLinear(c[2])};
}

/// Expects the pixel to hold `expected` (in [0, 1]) within `tolerance` levels of 255 in each channel.
void expectShade(const std::uint8_t* p, const Rgb& expected, double tolerance, const std::string& what) {
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(double(p[c]), 255.0 * expected[c], tolerance) << what << ", channel " << c;
    }
}

std::string head(const std::string& eye, const std::string& target, const std::string& render,
                 int width = 640, int height = 480) {
    return "[scene]\nname = \"look\"\ngravity = [0, 0, 0]\n[camera]\neye = " + eye + "\ntarget = " + target +
           "\nfov_deg = 45.0\n[render]\nwidth = " + std::to_string(width) +
           "\nheight = " + std::to_string(height) + "\n" + render;
}

TEST(RenderLook, TheSkyPalesFromTheZenithToTheHorizonAndDarkensBelowIt) {
    // nothing in the scene: every pixel is sky. Looking level, the middle column's rows run from 22.5
    // degrees up to 22.5 down. The gradient (README): the zenith is the background's hue at 1.6 times its
    // saturation (about its luma), times 0.85; the horizon a third of the way to white (0.35); below the
    // horizon towards 0.45 times the background, reached 7 degrees down; mixed in linear light by the square
    // root of the ray's height above the horizon, and by 8 times its depth below
    const Rgb b{0.62, 0.74, 0.86};
    const double luma = 0.3 * b[0] + 0.59 * b[1] + 0.11 * b[2];
    Rgb zenith, horizon, nadir;
    for (int c = 0; c < 3; ++c) {
        zenith[c] = toLinear(std::clamp((luma + 1.6 * (b[c] - luma)) * 0.85, 0.0, 1.0));
        horizon[c] = toLinear(b[c] + 0.35 * (1.0 - b[c]));
        nadir[c] = toLinear(0.45 * b[c]);
    }
    const Image img = renderOnce(head("[0.0, 1.0, 0.0]", "[0.0, 1.0, -10.0]", ""));
    const double t = std::tan(22.5 * std::numbers::pi / 180.0);
    for (int y = 0; y < img.height; y += 7) {
        // the ray through the middle of the pixel (x = 320, y), the image's rows top first
        const double up = (239.5 - y) / 240.0 * t, across = 0.5 / 320.0 * t * 640.0 / 480.0;
        const double dy = up / std::sqrt(1.0 + up * up + across * across);
        const double s = dy >= 0.0 ? std::sqrt(dy) : std::min(-8.0 * dy, 1.0);
        const Rgb& to = dy >= 0.0 ? zenith : nadir;
        Rgb expected;
        for (int c = 0; c < 3; ++c) {
            expected[c] = toSrgb(horizon[c] + (to[c] - horizon[c]) * s);
        }
        expectShade(img.at(320, y), expected, 2.0, "row " + std::to_string(y));
    }
    // without the gradient the sky is the background, flat
    const Image flat = renderOnce(head("[0.0, 1.0, 0.0]", "[0.0, 1.0, -10.0]", "sky_gradient = false\n"));
    for (int y : {0, 120, 240, 479}) {
        expectShade(flat.at(100, y), b, 1.0, "flat sky, row " + std::to_string(y));
    }
}

TEST(RenderLook, TheSkyShowsWhereverTheGroundLeavesItSeen) {
    // the sky is drawn only in the rows a ground plane does not cover from edge to edge: over a ground,
    // looking level, the rows above the horizon (the ground below); under a ceiling, the rows below it. Each
    // row the plane leaves holds the sky of the same view without it, within a level (a row or two at the
    // horizon left out: the plane's edge 200 m away, antialiased)
    const std::string view = head("[0.0, 1.0, 0.0]", "[0.0, 1.0, -10.0]", "shadows = false\n");
    const Image sky = renderOnce(view);
    const std::string grey = "[0.3, 0.3, 0.3]";
    const Image ground = renderOnce(view + test::planeEntity("[0.0, -2.0, 0.0]", "[0.0, 1.0, 0.0]", grey));
    const Image ceiling = renderOnce(view + test::planeEntity("[0.0, 4.0, 0.0]", "[0.0, -1.0, 0.0]", grey));
    int seen = 0;
    for (int y = 0; y < sky.height; ++y) {
        const bool aboveHorizon = y<236, belowHorizon = y> 243;
        for (int x = 0; x < sky.width; x += 5) {
            for (int c = 0; c < 3; ++c) {
                if (aboveHorizon) {
                    EXPECT_NEAR(int(ground.at(x, y)[c]), int(sky.at(x, y)[c]), 1)
                        << "over the ground: " << x << ", " << y;
                } else if (belowHorizon) {
                    EXPECT_NEAR(int(ceiling.at(x, y)[c]), int(sky.at(x, y)[c]), 1)
                        << "under the ceiling: " << x << ", " << y;
                }
            }
            seen += aboveHorizon || belowHorizon;
        }
    }
    EXPECT_GT(seen, 60000);
    // and where the plane is, it is seen: the ground's grey, not the sky
    EXPECT_LT(int(ground.at(320, 470)[2]), 150);
    EXPECT_LT(int(ceiling.at(320, 10)[2]), 150);
}

TEST(RenderLook, WhatIsInFrontOfTheSkyHidesItInDepthOrder) {
    // with several samples the sky is drawn first, under the scene, and with one last, behind it: either way
    // a red ball 6 m away hides a green box 10 m away drawn after it, both hide the sky, and the sky around
    // them is the sky of the same view without them (caught the depth test left off after the sky)
    for (const int msaa : {1, 4}) {
        const std::string view = head("[0.0, 1.0, 0.0]", "[0.0, 1.0, -10.0]",
                                      "shadows = false\nmsaa = " + std::to_string(msaa) + "\n");
        const Image sky = renderOnce(view);
        const Image img =
            renderOnce(view +
                       "[[entity]]\nname = \"ball\"\n[entity.transform]\nposition = [0.0, 1.0, -6.0]\n"
                       "[entity.rigid_body]\nshape = \"sphere\"\nradius = 0.5\ncolor = [0.9, 0.1, 0.1]\n" +
                       test::boxEntity("box", "[0.0, 1.0, -10.0]", "[2.0, 2.0, 0.5]", "[0.1, 0.9, 0.1]"));
        const std::string at = std::to_string(msaa) + " samples: ";
        const std::uint8_t* middle = img.at(320, 240);
        EXPECT_GT(int(middle[0]), int(middle[1]) + 60) << at << "the ball in the middle";
        const std::uint8_t* box = img.at(320, 140);
        EXPECT_GT(int(box[1]), int(box[0]) + 60) << at << "the box above the ball";
        for (const auto& [x, y] : {std::pair{20, 20}, std::pair{620, 200}, std::pair{100, 460}}) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(int(img.at(x, y)[c]), int(sky.at(x, y)[c]), 1)
                    << at << "the sky at " << x << ", " << y;
            }
        }
    }
}

TEST(RenderLook, NothingOfTheFrameBeforeIsLeftOnceTheSkyAndTheGroundAreDrawn) {
    // with the sky gradient the colour is not cleared: the sky and the ground must cover every pixel. A
    // frame filled with a red box close up, then the camera turned to each view: over the ground looking
    // level, straight down at it, from under it, at the sky alone, askew; each image matches the same view
    // drawn by a renderer that never drew the box close up (caught the sky's rows cut 5 rows short of the
    // ground)
    const std::string things =
        test::planeEntity("[0.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.5, 0.5, 0.5]") +
        test::boxEntity("box", "[0.0, 1.0, 0.0]", "[1.0, 1.0, 1.0]", "[0.9, 0.1, 0.1]");
    using View = std::pair<std::array<double, 3>, std::array<double, 3>>;
    const View closeUp{{0.0, 1.0, 1.3}, {0.0, 1.0, 0.0}};
    const std::array<View, 5> views{
        View{{0.0, 1.0, 20.0}, {0.0, 1.0, 0.0}}, View{{0.0, 12.0, 0.01}, {0.0, 0.0, 0.0}},
        View{{3.0, -2.0, 15.0}, {0.0, 0.0, 0.0}}, View{{0.0, 0.5, 30.0}, {0.0, 40.0, 0.0}},
        View{{5.0, 3.0, 5.0}, {-20.0, 0.0, -20.0}}};
    const auto look = [](Simulation& sim, const View& view) {
        RenderOutput& out = sim.world().resource<RenderOutput>();
        out.cameraSet = true;
        out.eye = view.first;
        out.target = view.second;
        sim.runFrame();
        return test::lastImageOf(sim);
    };
    for (const int msaa : {1, 4}) {
        const std::string text = head("[0.0, 1.0, 20.0]", "[0.0, 1.0, 0.0]",
                                      "shadows = false\nmsaa = " + std::to_string(msaa) + "\n") +
                                 things;
        for (std::size_t v = 0; v < views.size(); ++v) {
            auto reused = test::renderedSimulation(text);
            const Image red = look(*reused, closeUp);
            ASSERT_GT(int(red.at(320, 240)[0]), int(red.at(320, 240)[1]) + 60) << "the box fills the view";
            const Image img = look(*reused, views[v]);
            reused.reset();
            const Image expected = look(*test::renderedSimulation(text), views[v]);
            int differ = 0;
            for (std::size_t i = 0; i < img.rgba.size(); ++i) {
                differ += std::abs(int(img.rgba[i]) - int(expected.rgba[i])) > 1;
            }
            EXPECT_EQ(differ, 0) << msaa << " samples, view " << v;
        }
    }
}

/// A 10 m square slab of colour `colour`, its top at y = 0.5, seen from 2 m above its top.
std::string slabFromAbove(const std::string& render, const std::string& colour) {
    return head("[0.0, 2.5, 0.0001]", "[0.0, 0.0, 0.0]", render + "shadows = false\n") +
           test::boxEntity("slab", "[0.0, 0.0, 0.0]", "[5.0, 0.5, 5.0]", colour);
}

TEST(RenderLook, LightIsAddedInLinearLightAndWrittenAsSrgb) {
    // the slab's top faces up; the key light (strength 1 with gamma, 0.75 without) comes in at angle theta
    // from straight down, the grey ambient from above (0.2 with gamma, 0.35 without: hemisphere off). With
    // gamma the colour is taken as sRGB, lit in linear light and written as sRGB; without, lit as given
    const Rgb albedo{0.6, 0.4, 0.2};
    for (const double theta : {0.0, 60.0, 80.0}) {
        const double c = std::cos(theta * std::numbers::pi / 180.0),
                     s = std::sin(theta * std::numbers::pi / 180.0);
        const std::string light =
            "light_direction = [" + std::to_string(-s) + ", " + std::to_string(-c) + ", 0.0]\n";
        const Image on = renderOnce(slabFromAbove(light + "hemisphere_ambient = false\n", "[0.6, 0.4, 0.2]"));
        const Image off = renderOnce(
            slabFromAbove(light + "hemisphere_ambient = false\ngamma = false\n", "[0.6, 0.4, 0.2]"));
        Rgb gammaOn, gammaOff;
        for (int k = 0; k < 3; ++k) {
            gammaOn[k] = toSrgb(toLinear(albedo[k]) * (0.2 + 1.0 * c));
            gammaOff[k] = std::min(albedo[k] * (0.35 + 0.75 * c), 1.0);
        }
        const std::string at = "light " + std::to_string(theta) + " degrees from straight down";
        expectShade(on.at(320, 240), gammaOn, 2.0, at + ", gamma");
        expectShade(off.at(320, 240), gammaOff, 2.0, at + ", no gamma");
    }
}

TEST(RenderLook, AmbientLightComesFromTheSkyAboveAndTheGroundBelow) {
    // the key light level (along x): neither face below gets any of it. A face looking up takes the ambient
    // light from the sky (0.75 times the background, linear); a face looking down, from the ground (0.5
    // times the warm grey (0.45, 0.42, 0.38))
    const std::string render =
        "background = [0.3, 0.5, 0.9]\nlight_direction = [1.0, 0.0, 0.0]\nshadows = false\n";
    const Rgb albedo{0.8, 0.8, 0.8}, sky = linear({0.3, 0.5, 0.9}), ground = linear({0.45, 0.42, 0.38});
    const std::string slab = test::boxEntity("slab", "[0.0, 3.0, 0.0]", "[5.0, 0.5, 5.0]", "[0.8, 0.8, 0.8]");
    // from 2 m below its bottom face, looking up at it; then the same slab from 2 m above its top
    const Image below = renderOnce(head("[0.0, 0.5, 0.0001]", "[0.0, 3.0, 0.0]", render) + slab);
    const Image above = renderOnce(head("[0.0, 5.5, 0.0001]", "[0.0, 3.0, 0.0]", render) + slab);
    Rgb fromGround, fromSky;
    for (int k = 0; k < 3; ++k) {
        fromGround[k] = toSrgb(toLinear(albedo[k]) * 0.5 * ground[k]);
        fromSky[k] = toSrgb(toLinear(albedo[k]) * 0.75 * sky[k]);
    }
    expectShade(below.at(320, 240), fromGround, 2.0, "the bottom face, lit by the ground");
    expectShade(above.at(320, 240), fromSky, 2.0, "the top face, lit by the sky");
    EXPECT_GT(below.at(320, 240)[0], below.at(320, 240)[2]) << "the ground's light is warm";
    EXPECT_GT(above.at(320, 240)[2], above.at(320, 240)[0] + 30) << "the sky's light is blue";
}

TEST(RenderLook, TheFloorGridFadesIntoItsAverageWithoutMoire) {
    // a ground plane seen from 3 m up, looking level: the row dy pixels below the horizon shows the ground
    // at distance d = 3 f / dy. Near (d under 13 m) the lines across the view are a pixel or two wide and
    // the rows' means dip where they are; far (30 to 150 m, a pixel spanning 0.35 to 9 m of ground; the plane
    // ends at 200 m) a line can only be an average: drawn by where each pixel's centre falls, the rows that
    // hit one are 30% darker than their neighbours (a moire of stripes), averaged they all hold the same
    // shade
    const Image img =
        renderOnce(head("[0.3, 3.0, 0.2]", "[0.3, 3.0, -10.0]", "shadows = false\n", 1280, 720) +
                   test::planeEntity("[0.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.6, 0.6, 0.6]"));
    const double f = 360.0 / std::tan(22.5 * std::numbers::pi / 180.0);
    std::vector<double> mean(img.height, 0.0);
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            mean[y] += img.at(x, y)[1];
        }
        mean[y] /= img.width;
    }
    const auto rowAt = [&](double distance) { return int(359.5 + 3.0 * f / distance); };
    double worstFar = 0.0;
    for (int y = rowAt(150.0); y <= rowAt(30.0); ++y) {
        worstFar = std::max(worstFar, std::abs(mean[y - 1] - 2.0 * mean[y] + mean[y + 1]));
    }
    EXPECT_LT(worstFar, 2.0) << "far rows: their means change smoothly (no stripes)";
    double deepestDip = 0.0;
    for (int y = rowAt(13.0); y + 3 < img.height; ++y) {
        deepestDip = std::max(deepestDip, std::min(mean[y - 3], mean[y + 3]) - mean[y]);
    }
    EXPECT_GT(deepestDip, 10.0) << "near rows: the lines across the view are seen";
}

/// Looking at a 1 m square patch of `patch` colour on a black floor (its top at y = 0.6), from `eye`, with
/// or without still water over both (its surface at y = 1.5). The key light from above, tilted so that its
/// glint on the water is out of the picture; no shadows.
std::string patchScene(const std::string& eye, bool patch, bool water) {
    std::string s = head(eye, "[0.0, 0.6, 0.0]", "light_direction = [0.5, -1.0, 0.0]\nshadows = false\n") +
                    test::boxEntity("floor", "[0.0, 0.0, 0.0]", "[6.0, 0.5, 6.0]", "[0.0, 0.0, 0.0]");
    if (patch) {
        s += test::boxEntity("patch", "[0.0, 0.55, 0.0]", "[0.5, 0.05, 0.5]", "[0.9, 0.9, 0.9]");
    }
    if (water) {
        s += R"(
[[entity]]
name = "pool"
[entity.transform]
position = [0.0, 1.5, 0.0]
[entity.water]
cells = [32, 32]
size = [12.0, 12.0]
depth = 1.0
)";
    }
    return s;
}

TEST(RenderLook, AFloorPatchUnderWaterShowsThroughItLessAtGrazingAngles) {
    // the water's colour covers 45% of what lies below when seen head on, and its reflection takes a
    // Fresnel share F = 0.02 + 0.98 (1 - cos)^5 (Schlick; cos between the view and the surface's normal):
    // (1 - F)(1 - 0.45) of the patch's contrast against the floor comes through the water. Blending is on
    // the written values, so the contrast through water is that share of the dry contrast exactly
    for (const auto& view : {std::pair{std::string("[0.0, 4.5, 0.0001]"), 1.0},
                             std::pair{std::string("[0.0, 1.9, 7.0]"), 1.3 / std::hypot(1.3, 7.0)}}) {
        const std::string& eye = view.first; // (clang 14 cannot capture a structured binding)
        const double cosine = view.second;
        const auto contrast = [&](bool water) {
            const Image with = renderOnce(patchScene(eye, true, water));
            const Image without = renderOnce(patchScene(eye, false, water));
            return double(with.at(320, 240)[1]) - double(without.at(320, 240)[1]);
        };
        const double dry = contrast(false), wet = contrast(true);
        const double fresnel = 0.02 + 0.98 * std::pow(1.0 - cosine, 5.0);
        ASSERT_GT(dry, 100.0) << "the patch stands out from the floor";
        EXPECT_NEAR(wet, (1.0 - fresnel) * 0.55 * dry, 3.0) << "seen from " << eye;
    }
    // and the water is drawn: over the black floor it shows its own colour, blue
    const Image pool = renderOnce(patchScene("[0.0, 4.5, 0.0001]", false, true));
    EXPECT_GT(pool.at(320, 240)[2], pool.at(320, 240)[0] + 20);
    EXPECT_EQ(pool.at(320, 240)[3], 255) << "blending leaves the image opaque (a PNG's alpha)";
}

} // namespace
} // namespace tumble
