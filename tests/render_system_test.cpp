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
#include "tests/render_support.h"
#include "tests/test_support.h"

#include <GLES3/gl3.h>
#include <gtest/gtest.h>
#include <stb/stb_image.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>

namespace tumble {
namespace {

using test::Image;
using test::renderedSimulation;
using test::renderOnce;

/// The plain look: a flat sky of the background's colour, grey ambient light from above, colours lit and
/// written as given; the shades the tests below work out are of this look.
const std::string kPlainLook = "sky_gradient = false\nhemisphere_ambient = false\ngamma = false\n";

const std::string kCamera = R"(
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
)" + kPlainLook;

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
                // shaded red: green and blue stay zero however dark the side turned from the light is, but
                // for the edge's pixels, which multisampling blends with the white behind (equal parts)
                red += p[1] == p[2] && p[0] >= p[1];
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

/// A scene's head: a camera `height` m above the origin looking straight down (fov 45 degrees), a white sky,
/// the key light shining straight down, no gravity.
std::string lookingDown(double height, int width, int heightPx, int msaa, bool shadows) {
    return "[scene]\nname = \"down\"\ngravity = [0, 0, 0]\n[camera]\neye = [0.0, " + std::to_string(height) +
           ", 0.0001]\ntarget = [0.0, 0.0, 0.0]\nfov_deg = 45.0\n[render]\nwidth = " + std::to_string(width) +
           "\nheight = " + std::to_string(heightPx) +
           "\nbackground = [1.0, 1.0, 1.0]\nlight_direction = [0.0, -1.0, 0.0]\nmsaa = " +
           std::to_string(msaa) + "\nshadows = " + (shadows ? "true" : "false") + "\n" + kPlainLook;
}

/// A grey floor, its top at y = 0, 10 m square.
const char* kGreyFloor = R"(
[[entity]]
name = "floor"
[entity.transform]
position = [0.0, -0.1, 0.0]
[entity.rigid_body]
shape = "box"
half_extents = [5.0, 0.1, 5.0]
color = [0.8, 0.8, 0.8]
)";

/// A dark strip 2 cm wide (about two pixels) lying on a light floor, turned 10 degrees from the image's
/// columns, seen from straight above, at `msaa` samples a pixel (no shadows: their soft edge would blend
/// too).
std::string stripScene(int msaa) {
    return lookingDown(3.0, 320, 240, msaa, false) + R"(
[[entity]]
name = "floor"
[entity.transform]
position = [0.0, 0.2, 0.0]
[entity.rigid_body]
shape = "box"
half_extents = [3.0, 0.1, 3.0]
color = [0.9, 0.9, 0.9]
[[entity]]
name = "strip"
[entity.transform]
position = [0.0, 0.31, 0.0]
[entity.rigid_body]
shape = "box"
half_extents = [0.01, 0.01, 1.0]
orientation = [0.0, 0.0871557, 0.0, 0.9961947]
color = [0.05, 0.05, 0.05]
)";
}

TEST(RenderSystem, MultisamplingBlendsAThinLinesEdgesAndKeepsItsInk) {
    // each row of the middle of the image crosses the strip: without multisampling every pixel is floor
    // (about 252) or strip (about 14), nothing between; with 4 samples the pixels its edges cut are in
    // between, and the strip's total darkness (its area) stays what it was
    const auto measure = [](const Image& img, std::size_t& between, double& ink) {
        between = 0;
        ink = 0.0;
        for (int y = img.height / 4; y < 3 * img.height / 4; ++y) {
            for (int x = 0; x < img.width; ++x) {
                const int l = img.at(x, y)[0];
                between += l >= 60 && l <= 200;
                ink += std::max(0, 252 - l);
            }
        }
    };
    std::size_t plainBetween = 0, smoothBetween = 0;
    double plainInk = 0.0, smoothInk = 0.0;
    measure(renderOnce(stripScene(1)), plainBetween, plainInk);
    measure(renderOnce(stripScene(4)), smoothBetween, smoothInk);
    const std::size_t rows = 240 / 2;
    EXPECT_EQ(plainBetween, 0u) << "one sample a pixel: no pixel is partly strip";
    EXPECT_GE(smoothBetween, rows) << "four samples: at least one blended pixel a row";
    EXPECT_GT(plainInk, 0.0);
    EXPECT_NEAR(smoothInk, plainInk, 0.1 * plainInk) << "blending moves the strip's ink, it does not lose it";
}

/// A 0.5 m square slab 3 m above a grey floor, lit from straight above, seen from 2 m above the floor
/// looking straight down (the slab, above the camera, out of the picture).
std::string slabScene(bool shadows, int msaa) {
    return lookingDown(2.0, 640, 480, msaa, shadows) + kGreyFloor + R"(
[[entity]]
name = "slab"
[entity.transform]
position = [0.0, 3.0, 0.0]
[entity.rigid_body]
shape = "box"
half_extents = [0.25, 0.1, 0.25]
color = [0.9, 0.2, 0.2]
)";
}

TEST(RenderSystem, AShadowFromStraightAboveCoversTheFootprint) {
    // the floor lit is 0.8 (0.35 + 0.75) 0.75 = 0.66 (168), in shadow 0.8 x 0.35 x 0.75 = 0.21 (54): a pixel
    // under the midpoint is shadow. The slab's footprint, 0.5 m square 2 m from the camera, covers
    // (0.5 f / 2)^2 pixels, f = H / (2 tan(fov / 2))
    const double f = 480.0 / (2.0 * std::tan(45.0 * std::numbers::pi / 360.0));
    const double footprint = std::pow(0.5 * f / 2.0, 2.0);
    const auto shadowed = [](const Image& img) {
        std::size_t n = 0;
        for (int y = 0; y < img.height; ++y) {
            for (int x = 0; x < img.width; ++x) {
                n += img.at(x, y)[0] < 111;
            }
        }
        return n;
    };
    for (const int msaa : {1, 4}) {
        const Image lit = renderOnce(slabScene(true, msaa));
        EXPECT_NEAR(double(shadowed(lit)), footprint, 0.05 * footprint) << msaa << " samples";
        // and where it falls: centred under the slab
        EXPECT_LT(lit.at(320, 240)[0], 70) << "the middle of the shadow";
        EXPECT_GT(lit.at(20, 20)[0], 150) << "a corner of the floor, lit";
        EXPECT_EQ(shadowed(renderOnce(slabScene(false, msaa))), 0u) << "shadows = false: none";
    }
}

TEST(RenderSystem, ARopesMassesCastShadows) {
    // a single pinned mass drawn as a ball of radius 0.25 m, 3 m up, above the camera; straight below it its
    // shadow, a disc (the ball is a 12-sided sphere: 95% of the circle's area) of radius 0.25 f / 2 pixels.
    // Caught the balls drawn into the shadow map with whatever model matrix the last draw left (none here)
    const std::string scene = lookingDown(2.0, 640, 480, 1, true) + kGreyFloor + R"(
[[entity]]
name = "bob"
[entity.springs]
thickness = 0.25
masses = [ { x = [0.0, 3.0, 0.0], m = 1.0, pinned = true }, { x = [0.001, 3.0, 0.0], m = 1.0, pinned = true } ]
links = [ { a = 0, b = 1 } ]
)";
    const Image img = renderOnce(scene);
    std::size_t shadowed = 0;
    for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
            shadowed += img.at(x, y)[0] < 111;
        }
    }
    const double f = 480.0 / (2.0 * std::tan(45.0 * std::numbers::pi / 360.0));
    const double disc = std::numbers::pi * std::pow(0.25 * f / 2.0, 2.0);
    EXPECT_NEAR(double(shadowed), disc, 0.1 * disc);
}

/// A grey ground plane (a grid line every metre) seen from 6 m straight above (0.5, 0, 0.5), a cell's middle,
/// lit along `light`, drawn with `msaa` samples and `more` [render] keys.
std::string groundFromAbove(const std::string& light, int msaa = 1, const std::string& more = "") {
    return "[scene]\nname = \"ground\"\ngravity = [0, 0, 0]\n[camera]\neye = [0.5, 6.0, 0.5001]\ntarget = "
           "[0.5, 0.0, "
           "0.5]\nfov_deg = 45.0\n[render]\nwidth = 640\nheight = 480\nmsaa = " +
           std::to_string(msaa) + "\nlight_direction = " + light + "\n" + more + kPlainLook +
           test::planeEntity("[0.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.8, 0.8, 0.8]");
}

/// A ball of radius 0.5 m, its centre 2 m above (0.5, 0, 0.5).
const std::string kBallTwoMetresUp = R"(
[[entity]]
name = "ball"
[entity.transform]
position = [0.5, 2.0, 0.5]
[entity.rigid_body]
shape = "sphere"
radius = 0.5
)";

TEST(RenderSystem, AnObliqueShadowFallsBesideItsCasterAndTheGroundOffTheMapIsLit) {
    // a ball of radius 0.5 m 2 m above the ground, the light 45 degrees from straight down along +x: its
    // shadow is centred 2 m along x from below it. The ground lit is 0.8 (0.35 + 0.75 cos 45) = 0.70 (180),
    // in shadow 0.8 x 0.35 = 0.28 (71). The shadow map spans the ball alone: the ground away from it is
    // read off the map, and is lit. Pixels at cells' middles (the grid lines are on whole metres)
    const std::string light = "[0.7071, -0.7071, 0.0]";
    const Image img = renderOnce(groundFromAbove(light) + kBallTwoMetresUp);
    const double metre = 480.0 / (2.0 * std::tan(45.0 * std::numbers::pi / 360.0)) / 6.0; // pixels
    const int shadowX = int(320 + 2.0 * metre), mirrorX = int(320 - 2.0 * metre);
    EXPECT_LT(img.at(shadowX, 240)[0], 111) << "the shadow, 2 m along the light from below the ball";
    EXPECT_GT(img.at(mirrorX, 240)[0], 150) << "2 m the other way: lit";
    for (const auto& [x, y] : {std::pair{int(320 - 3 * metre), int(240 - 2 * metre)},
                               std::pair{int(320 + 3 * metre), int(240 + 2 * metre)}}) {
        EXPECT_GT(img.at(x, y)[0], 150) << "the ground far off the shadow map, at " << x << ", " << y;
    }
    // and with nothing that casts, the shadow map is empty: the ground lit everywhere
    const Image bare = renderOnce(groundFromAbove(light));
    for (const int x : {shadowX, mirrorX, 320}) {
        EXPECT_GT(bare.at(x, 240)[0], 150) << "nothing casts: lit at " << x;
    }
}

/// Counts the pixels where `a` is brighter than `b` by more than a level in some channel, and those where it
/// is darker by more than `dark` levels in every channel.
std::pair<int, int> brighterAndDarker(const Image& a, const Image& b, int dark) {
    int brighter = 0, darker = 0;
    for (int y = 0; y < a.height; ++y) {
        for (int x = 0; x < a.width; ++x) {
            const std::uint8_t *p = a.at(x, y), *q = b.at(x, y);
            bool more = false, less = true;
            for (int c = 0; c < 3; ++c) {
                more = more || int(p[c]) > int(q[c]) + 1;
                less = less && int(p[c]) < int(q[c]) - dark;
            }
            brighter += more;
            darker += less;
        }
    }
    return {brighter, darker};
}

TEST(RenderSystem, TheGroundWhereTheShadowMapEndsHasNoSeam) {
    // the ground is drawn in two parts: where the shadow map reaches (with its lookups) and beyond it. The
    // ball's map ends in the middle of this view; a crack between the parts would show the background
    // (brighter than the ground), a part drawn lit where it should not be would be brighter than without
    // shadows too. With shadows a pixel may only be darker, and the ball's shadow is
    const std::string& ball = kBallTwoMetresUp;
    for (const int msaa : {1, 4}) {
        const std::string light = "[0.7071, -0.7071, 0.0]";
        const Image shadowed = renderOnce(groundFromAbove(light, msaa) + ball);
        const Image plain = renderOnce(groundFromAbove(light, msaa, "shadows = false\n") + ball);
        const auto [brighter, darker] = brighterAndDarker(shadowed, plain, 40);
        EXPECT_EQ(brighter, 0) << msaa << " samples: pixels brighter with shadows than without";
        EXPECT_GT(darker, 3000) << msaa << " samples: the ball's shadow (about 11,000 pixels)";
    }
}

TEST(RenderSystem, TheGroundIsTheSameColourOnAndOffTheShadowMap) {
    // with the default look (gamma, the hemisphere's ambient), the ground off the shadow map is written from
    // a quadratic in the grid's cover, on the map through the sRGB curve. With nothing that casts the whole
    // ground is on the map (and lit); without shadows, all of it is off: every pixel the same within a
    // level, at every cover the grid's lines take from near to far. Between the lines the colour is the
    // ground's lit in linear light: 0.5 (0.75 background + cos 30 degrees), the background (0.6, 0.7, 0.9)
    const std::string scene = R"([scene]
name = "ground"
gravity = [0, 0, 0]
[camera]
eye = [0.5, 3.0, 0.5]
target = [0.5, 0.0, -6.0]
fov_deg = 45.0
[render]
width = 640
height = 480
background = [0.6, 0.7, 0.9]
light_direction = [0.5, -0.8660254, 0.0]
)";
    const std::string ground = test::planeEntity("[0.0, 0.0, 0.0]", "[0.0, 1.0, 0.0]", "[0.5, 0.5, 0.5]");
    for (const int msaa : {1, 4}) {
        const std::string samples = "msaa = " + std::to_string(msaa) + "\n";
        const Image onMap = renderOnce(scene + samples + ground);
        const Image offMap = renderOnce(scene + samples + "shadows = false\n" + ground);
        int differing = 0;
        for (std::size_t i = 0; i < onMap.rgba.size(); ++i) {
            differing += std::abs(int(onMap.rgba[i]) - int(offMap.rgba[i])) > 1;
        }
        EXPECT_EQ(differing, 0) << msaa << " samples: channels more than a level apart";
    }
    // the pixel at the middle of the view's bottom row (47 degrees down) looks at the ground 2.8 m ahead,
    // near (0.5, 0, -2.3): inside a cell (lines on whole metres)
    const Image img = renderOnce(scene + "shadows = false\n" + ground);
    auto lin = [](double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); };
    auto srgb = [](double c) { return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055; };
    const double background[3] = {0.6, 0.7, 0.9};
    for (int c = 0; c < 3; ++c) {
        const double lit = lin(0.5) * (0.75 * lin(background[c]) + std::cos(std::numbers::pi / 6.0));
        EXPECT_NEAR(double(img.at(320, 479)[c]), 255.0 * srgb(std::min(lit, 1.0)), 2.0) << "channel " << c;
    }
}

TEST(RenderSystem, AClothInWireframeCastsNoShadow) {
    // a pinned 1 m cloth lying flat 3 m up, above the camera: drawn as a surface it shadows the floor below
    // it; in wireframe (the viewer's W) only its springs are drawn, and its invisible surface casts nothing.
    // Caught the shadow pass drawing surfaces in wireframe
    const std::string scene = lookingDown(2.0, 640, 480, 1, true) + kGreyFloor + R"(
[[entity]]
name = "sheet"
[entity.transform]
position = [0.0, 3.0, 0.0]
[entity.cloth]
rows = 4
cols = 4
size = [1.0, 1.0]
plane = "xz"
pin = "corners"
)";
    for (const bool wireframe : {false, true}) {
        auto sim = renderedSimulation(scene);
        sim->world().resource<RenderOutput>().wireframe = wireframe;
        sim->runFrame();
        const Image img = test::lastImageOf(*sim);
        if (wireframe) {
            EXPECT_GT(img.at(320, 240)[0], 150) << "wireframe: the floor under the cloth is lit";
        } else {
            EXPECT_LT(img.at(320, 240)[0], 111) << "a surface: the floor under the cloth is in its shadow";
        }
    }
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

TEST(RenderSystem, EveryClosedShapeShowsTheSideThatFacesTheCamera) {
    // Closed shapes are drawn with their back faces culled. Each shape below, centred at (0, 1, 0), is seen
    // from above and from the front, with a thin green bar through it across the view, 0.1 m in from its
    // centre towards the camera: the middle of the image shows the shape's near side, red. Were any of its
    // triangles wound inward, they would be culled where they face the camera, and the middle would show
    // through them the bar (caught the meshes as they were wound before: the sphere, cylinder, capsule,
    // 2D circle and balls; and every kind wound the wrong way round. With the shadow pass culled alike, a
    // shape alone would look the same)
    const std::string cubeObj = test::writeTemp(
        "cube.obj", "v -0.3 -0.3 -0.3\nv 0.3 -0.3 -0.3\nv 0.3 0.3 -0.3\nv -0.3 0.3 -0.3\nv -0.3 -0.3 0.3\n"
                    "v 0.3 -0.3 0.3\nv 0.3 0.3 0.3\nv -0.3 0.3 0.3\nf 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\n"
                    "f 1 6 5\nf 1 2 6\nf 4 7 3\nf 4 8 7\nf 1 8 4\nf 1 5 8\nf 2 7 6\nf 2 3 7\n");
    const std::string rope =
        "[[entity]]\nname = \"bob\"\n[entity.springs]\nthickness = 0.3\nmasses = [ { x = "
        "[0.0, 1.0, 0.0], m = 1.0, pinned = true }, { x = [0.001, 1.0, 0.0], m = 1.0, "
        "pinned = true } ]\nlinks = [ { a = 0, b = 1 } ]\n";
    auto body = [](const std::string& table) {
        return "[[entity]]\nname = \"shape\"\n[entity.transform]\nposition = [0.0, 1.0, 0.0]\n" + table +
               "color = [0.9, 0.2, 0.2]\n";
    };
    const std::vector<std::pair<std::string, std::string>> shapes = {
        {"sphere", body("[entity.rigid_body]\nshape = \"sphere\"\nradius = 0.3\n")},
        {"box", body("[entity.rigid_body]\nshape = \"box\"\nhalf_extents = [0.3, 0.2, 0.3]\n")},
        {"cylinder", body("[entity.rigid_body]\nshape = \"cylinder\"\nradius = 0.3\nheight = 0.4\n")},
        {"capsule", body("[entity.rigid_body]\nshape = \"capsule\"\nradius = 0.2\nheight = 0.4\n")},
        {"convex", body("[entity.rigid_body]\nshape = \"convex\"\nmesh = \"" + cubeObj + "\"\n")},
        {"2d box", body("[entity.rigid_body_2d]\nshape = \"box\"\nhalf_extents = [0.3, 0.2]\n")},
        {"2d circle", body("[entity.rigid_body_2d]\nshape = \"circle\"\nradius = 0.3\n")},
        {"2d polygon", body("[entity.rigid_body_2d]\nshape = \"polygon\"\nvertices = [[-0.3, -0.2], [0.3, "
                            "-0.2], [0.3, 0.2], [-0.3, 0.2]]\n")},
        {"masses of a rope", rope},
    };
    for (const int msaa : {1, 4}) {
        for (const auto& [name, entity] : shapes) {
            for (const bool fromAbove : {true, false}) {
                const std::string view =
                    fromAbove ? "eye = [0.0, 3.0, 0.0001]\nlight_direction = [0.0, -1.0, 0.0]\n"
                              : "eye = [0.0, 1.0, 3.0]\nlight_direction = [0.0, 0.0, -1.0]\n";
                const std::string scene =
                    "[scene]\nname = \"closed\"\ngravity = [0, 0, 0]\n[camera]\ntarget = [0.0, 1.0, 0.0]\n" +
                    view.substr(0, view.find('\n') + 1) +
                    "[render]\nwidth = 160\nheight = 120\nmsaa = " + std::to_string(msaa) + "\n" +
                    view.substr(view.find('\n') + 1) + kPlainLook + entity +
                    test::boxEntity("bar", fromAbove ? "[0.0, 1.1, 0.0]" : "[0.0, 1.0, 0.1]",
                                    fromAbove ? "[1.0, 0.02, 0.05]" : "[1.0, 0.05, 0.02]", "[0.1, 0.9, 0.1]");
                const Image img = renderOnce(scene);
                for (const int x : {74, 80, 86}) {
                    const std::uint8_t* p = img.at(x, 60);
                    EXPECT_GT(int(p[0]), int(p[1]) + 100)
                        << name << (fromAbove ? " from above, " : " from the front, ") << msaa
                        << " samples: red at " << x << ", 60, not " << int(p[0]) << " " << int(p[1]) << " "
                        << int(p[2]);
                }
            }
        }
    }
}

TEST(RenderSystem, ClosedShapesShowTheirNearSideWhateverCullingTheContextWasLeftWith) {
    // a context shared with a host (the embedding API) may be left culling front faces, or taking clockwise
    // ones for front: a frame sets what its culling needs. A ball with a green bar through it, seen from
    // above, as in the test before, drawn again after the context was left so (caught the frame relying on
    // GL's defaults)
    auto sim = test::renderedSimulation(
        lookingDown(3.0, 160, 120, 4, true) +
        "[[entity]]\nname = \"ball\"\n[entity.transform]\nposition = [0.0, 1.0, 0.0]\n[entity.rigid_body]\n"
        "shape = \"sphere\"\nradius = 0.3\ncolor = [0.9, 0.2, 0.2]\n" +
        test::boxEntity("bar", "[0.0, 1.1, 0.0]", "[1.0, 0.02, 0.05]", "[0.1, 0.9, 0.1]"));
    sim->runFrame();
    for (const auto& [front, cull] : {std::pair{GL_CW, GL_BACK}, std::pair{GL_CCW, GL_FRONT}}) {
        glFrontFace(GLenum(front));
        glCullFace(GLenum(cull));
        sim->runFrame();
        const Image img = test::lastImageOf(*sim);
        const std::uint8_t* p = img.at(80, 60);
        EXPECT_GT(int(p[0]), int(p[1]) + 100) << "left with " << (front == GL_CW ? "GL_CW" : "GL_FRONT")
                                              << ": red, not " << int(p[0]) << " " << int(p[1]);
    }
}

TEST(RenderSystem, TwoSimulationsInOneThreadEachDrawInTheirOwnContext) {
    // each simulation opens a context of its own. A red ball's (640 x 480) and a blue box's (320 x 240),
    // drawn in turn, then the ball's once the box's simulation is gone: each image is the one its scene
    // gives alone. Caught the ball drawn in the box's context, current since it was opened (the same names
    // there are the box's objects: its smaller target), and once that was gone, in none (black); and the
    // ball's objects freed in the box's context (the box's own, of the same names: black)
    const std::string ball = sphereAt(0.0, 1.0);
    std::string box = std::string(kCamera) +
                      test::boxEntity("box", "[0.5, 0.0, 0.0]", "[0.8, 0.6, 0.4]", "[0.1, 0.2, 0.9]");
    for (const auto& [from, to] :
         {std::pair{"width = 640", "width = 320"}, std::pair{"height = 480", "height = 240"}}) {
        box.replace(box.find(from), std::string(from).size(), to);
    }
    const Image ballAlone = renderOnce(ball), boxAlone = renderOnce(box);
    const auto expectSame = [](const Image& img, const Image& alone, const std::string& what) {
        ASSERT_EQ(img.rgba.size(), alone.rgba.size()) << what;
        int differ = 0;
        for (std::size_t i = 0; i < img.rgba.size(); ++i) {
            differ += std::abs(int(img.rgba[i]) - int(alone.rgba[i])) > 1;
        }
        EXPECT_EQ(differ, 0) << what;
    };
    auto first = renderedSimulation(ball);
    auto second = renderedSimulation(box);
    for (int turn = 0; turn < 2; ++turn) {
        first->runFrame();
        expectSame(test::lastImageOf(*first), ballAlone, "the ball, turn " + std::to_string(turn));
        second->runFrame();
        expectSame(test::lastImageOf(*second), boxAlone, "the box, turn " + std::to_string(turn));
    }
    second.reset();
    first->runFrame();
    expectSame(test::lastImageOf(*first), ballAlone, "the ball, the box's simulation gone");
    // and a simulation that goes frees its objects in its own context, not in the one current then
    second = renderedSimulation(box);
    second->runFrame();
    first.reset();
    second->runFrame();
    expectSame(test::lastImageOf(*second), boxAlone, "the box, the ball's simulation gone");
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
    return test::lastImageOf(sim);
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

// ---- air: smoke as a volume, the velocity as arrows

/// Runs `frames` frames of a scenario, rendering only the last, and returns its image.
Image renderAfter(const std::string& text, int frames) {
    auto sim = renderedSimulation(text);
    RenderOutput& out = sim->world().resource<RenderOutput>();
    out.enabled = false;
    for (int f = 1; f < frames; ++f) {
        sim->runFrame();
    }
    out.enabled = true;
    sim->runFrame();
    return test::lastImageOf(*sim);
}

/// A 2 m box of air (cells of 5 cm) on a black sky, a still sphere of smoke of radius 0.5 m at its centre
/// fed 0.5 a second for 6 steps of 1/60 s (density 0.05 in every cell whose centre is inside), seen along
/// -z from `eye`.
std::string smokeScene(const std::string& eye, const std::string& target, double opacity,
                       const std::string& more = "") {
    return R"(
[scene]
name = "smoke"
dt = 0.0166666667
gravity = [0, 0, 0]
[camera]
eye = )" + eye +
           R"(
target = )" +
           target +
           R"(
fov_deg = 45.0
[render]
width = 640
height = 480
background = [0.0, 0.0, 0.0]
)" + kPlainLook +
           R"(
[[entity]]
name = "room"
[entity.air]
cells = [40, 40, 40]
size = [2.0, 2.0, 2.0]
smoke_color = [1.0, 0.5, 0.25]
smoke_opacity = )" +
           std::to_string(opacity) +
           R"(
[[entity]]
name = "puff"
[entity.air_source]
air = "room"
radius = 0.5
smoke = 0.5
)" + more;
}

/// The colour emission and absorption give a uniform slab of optical depth tau over black, per unit of
/// the smoke's colour, with the renderer's darkening of what lies deeper: the integral over the slab of
/// sigma e^(-sigma t) (0.55 + 0.45 e^(-sigma t)) dt.
double slabShade(double tau) {
    return 0.55 * (1.0 - std::exp(-tau)) + 0.225 * (1.0 - std::exp(-2.0 * tau));
}

void expectShade(const std::uint8_t* p, double shade, const char* what) {
    const double colour[3] = {1.0, 0.5, 0.25};
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(p[c], 255.0 * shade * colour[c], 4.0) << what << ", channel " << c;
    }
}

// The smoke sphere seen through its centre from outside the box: the ray crosses 1 m of density 0.05 at
// 20 /m per unit (optical depth 1), and from inside it (the eye 0.2 m behind the centre, looking through
// 0.7 m of it); the pixel is the slab's closed-form shade within 4 of 255 (the smoke's edge is a cell's
// staircase, smoothed by the texture's interpolation; its integral along the ray is unchanged by it).
// Clear air round it is left exactly as the sky. Seen to fail with the density's opacity doubled, with
// the march starting at the box's entry behind the eye (no smoke from inside), and without the depth
// darkening (an even shade).
TEST(RenderSystem, SmokeAbsorbsAndGlowsAsTheSlabsClosedFormSays) {
    const Image outside = renderAfter(smokeScene("[0.0, 0.0, 5.0]", "[0.0, 0.0, 0.0]", 20.0), 6);
    expectShade(outside.at(320, 240), slabShade(20.0 * 0.05 * 1.0), "through the centre");
    const std::uint8_t* clear = outside.at(320 + 80, 240); // 0.86 m right of the centre at z = 0
    EXPECT_EQ(clear[0] + clear[1] + clear[2], 0) << "clear air drawn";
    const Image inside = renderAfter(smokeScene("[0.0, 0.0, 0.2]", "[0.0, 0.0, -1.0]", 20.0), 6);
    expectShade(inside.at(320, 240), slabShade(20.0 * 0.05 * 0.7), "from inside");
}

// Smoke that fills its grid ends at the grid's sides: along the middle row the box's silhouette (its near
// face's edge, x = 1 m at 4 m from the eye) ends at pixel 464.9; a pixel 2 to the right of it is the
// sky, one 15 to the left is smoke. Seen to fail with the marched box grown half a cell past the grid (the
// texture's edge then repeats the last cells' density out to pixel 469.4).
TEST(RenderSystem, SmokeEndsAtItsGridsSides) {
    std::string scene = smokeScene("[0.0, 0.0, 5.0]", "[0.0, 0.0, 0.0]", 20.0);
    const std::string sphere = "radius = 0.5\n";
    scene.replace(scene.find(sphere), sphere.size(), "shape = \"box\"\nhalf_extents = [1.0, 1.0, 1.0]\n");
    const Image img = renderAfter(scene, 6);
    const std::uint8_t* outside = img.at(467, 240);
    EXPECT_EQ(outside[0] + outside[1] + outside[2], 0) << "smoke past the grid's side";
    EXPECT_GT(img.at(450, 240)[0], 40) << "smoke inside it";
}

// Opaque things and smoke: a white box in front of the smoke is drawn exactly as without smoke (the
// march stops at the scene's depth), while one behind it shows through it, dimmed and tinted. Seen to
// fail with the scene's depth ignored (smoke over the box in front).
TEST(RenderSystem, SmokeIsHiddenByWhatIsInFrontAndHidesWhatIsBehind) {
    const std::string boxes = R"(
[[entity]]
name = "front"
[entity.transform]
position = [-0.3, 0.0, 0.8]
[entity.rigid_body]
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 0.0
color = [1.0, 1.0, 1.0]
[[entity]]
name = "behind"
[entity.transform]
position = [0.3, 0.0, -0.8]
[entity.rigid_body]
shape = "box"
half_extents = [0.1, 0.1, 0.1]
mass = 0.0
color = [1.0, 1.0, 1.0]
)";
    const Image smoky = renderAfter(smokeScene("[0.0, 0.0, 5.0]", "[0.0, 0.0, 0.0]", 20.0, boxes), 6);
    const Image clear = renderAfter(smokeScene("[0.0, 0.0, 5.0]", "[0.0, 0.0, 0.0]", 0.0, boxes), 6);
    const int frontX = int(projectedX(-0.3 * 5.0 / 4.2)), behindX = int(projectedX(0.3 * 5.0 / 5.8));
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(smoky.at(frontX, 240)[c], clear.at(frontX, 240)[c]) << "the box in front, channel " << c;
    }
    EXPECT_GT(clear.at(behindX, 240)[2], 60) << "the box behind is lit";
    EXPECT_LT(smoky.at(behindX, 240)[2], clear.at(behindX, 240)[2] - 20) << "blue taken by the smoke";
    EXPECT_GT(smoky.at(behindX, 240)[0], smoky.at(behindX, 240)[2] + 20) << "tinted by the smoke";
}

// A velocity slice: a uniform flow of 1 m/s along x (a source imposing it everywhere, the sides along x
// open) drawn with velocity_slice = "z" puts arrows in the top speed's colour (red) across the box, and
// they point along +x: their pixels lie to the right of the arrows' feet, which are symmetric about the
// centre. Without the key nothing is drawn. Seen to fail with the arrows drawn backwards.
TEST(RenderSystem, AVelocitySliceDrawsArrowsAlongTheFlow) {
    auto scene = [](const char* slice) {
        return std::string(kCamera) + R"(
[[entity]]
name = "room"
[entity.air]
cells = [16, 16, 16]
size = [2.0, 2.0, 2.0]
border = { "-x" = "open", "+x" = "open" }
velocity_slice = ")" +
               slice +
               R"("
[[entity]]
name = "fan"
[entity.air_source]
air = "room"
shape = "box"
half_extents = [1.0, 1.0, 1.0]
smoke = 0.0
velocity = [1.0, 0.0, 0.0]
)";
    };
    auto redPixels = [](const Image& img, double& meanX) {
        std::size_t n = 0;
        double sum = 0.0;
        for (int y = 0; y < img.height; ++y) {
            for (int x = 0; x < img.width; ++x) {
                const std::uint8_t* p = img.at(x, y);
                if (p[0] > 200 && p[1] < 120 && p[2] < 120) {
                    ++n;
                    sum += x + 0.5;
                }
            }
        }
        meanX = n > 0 ? sum / double(n) : 0.0;
        return n;
    };
    double meanX = 0.0;
    EXPECT_EQ(redPixels(renderAfter(scene("none"), 2), meanX), 0u);
    ASSERT_GT(redPixels(renderAfter(scene("z"), 2), meanX), 500u);
    // the arrows are 0.9 of a cell (0.125 m) long: their pixels' mean is a third of that or more to the
    // right of the centre (half of it for the shafts alone; the heads sit at the tips)
    EXPECT_GT(meanX, projectedX(0.04)) << "centre " << projectedX(0.0);
}

} // namespace
} // namespace tumble
