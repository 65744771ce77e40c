// Rendering a scenario in this process on the real EGL context, for the tests on pixels.
#pragma once

#include "app/gl_context.h"
#include "engine/render_output.h"
#include "engine/simulation.h"
#include "systems/render_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace tumble::test {

/// An image read back: RGBA, top row first.
struct Image {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
    const std::uint8_t* at(int x, int y) const {
        return &rgba[(std::size_t(y) * std::size_t(width) + std::size_t(x)) * 4];
    }
};

/// A simulation of a scenario that renders headlessly in this process (no PNG written).
inline std::unique_ptr<Simulation> renderedSimulation(const std::string& text) {
    auto sim = makeSimulation(text);
    RenderOutput& out = sim->world().setResource<RenderOutput>();
    out.enabled = true;
    out.openContext = openHeadlessContext;
    out.directory = tempPath("render");
    out.lastFrame = 0; // no PNG
    return sim;
}

/// The last image a simulation drew.
inline Image lastImageOf(Simulation& sim) {
    Image img;
    EXPECT_TRUE(lastImage(sim.world(), img.width, img.height, img.rgba));
    return img;
}

/// Renders one frame of a scenario in this process and returns the image.
inline Image renderOnce(const std::string& text) {
    auto sim = renderedSimulation(text);
    sim->runFrame();
    return lastImageOf(*sim);
}

/// A scenario's static box entity: TOML arrays for its centre, half extents and colour.
inline std::string boxEntity(const std::string& name, const std::string& position,
                             const std::string& halfExtents, const std::string& colour) {
    return "\n[[entity]]\nname = \"" + name + "\"\n[entity.transform]\nposition = " + position +
           "\n[entity.rigid_body]\nshape = \"box\"\nhalf_extents = " + halfExtents + "\ncolor = " + colour +
           "\n";
}

/// A scenario's static ground plane entity: TOML arrays for a point on it, its normal and its colour.
inline std::string planeEntity(const std::string& position, const std::string& normal,
                               const std::string& colour) {
    return "\n[[entity]]\nname = \"plane\"\n[entity.transform]\nposition = " + position +
           "\n[entity.rigid_body]\nshape = \"plane\"\nnormal = " + normal + "\ncolor = " + colour + "\n";
}

} // namespace tumble::test
