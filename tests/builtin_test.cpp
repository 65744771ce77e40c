// The one table of systems: its run order is the order docs/architecture.md states, every system declares
// what it touches (that the declarations cover what each system does is checked while every demo runs: see
// PinnedHash and Demo, which run them under the world's access check), and the schedule runs the table.

#include "systems/builtin.h"

#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace tumble {
namespace {

TEST(BuiltinSystems, RunInTheStatedOrder) {
    std::vector<std::string> fixed, frame;
    for (const SystemEntry& s : builtinSystems()) {
        (s.phase == Phase::Fixed ? fixed : frame).push_back(s.name);
        EXPECT_NE(s.phase, Phase::Input) << s.name << ": the input phase is the engine's own (events)";
        EXPECT_TRUE(s.fn) << s.name;
        EXPECT_FALSE(s.access.all) << s.name << " declares no access of its own";
    }
    // force fields -> emitters -> particles -> springs/cloth -> collisions -> rigid bridges -> what Box2D's
    // step left inside its bodies -> water -> air; the renderer's history before them all, the mouse spring
    // with the forces
    EXPECT_EQ(fixed,
              (std::vector<std::string>{"render_history", "force_fields", "mouse_spring", "emitters",
                                        "particles", "springs", "collisions", "cloth_collision", "rigid_in",
                                        "bullet", "box2d", "rigid_out", "collisions_2d", "water", "air"}));
    EXPECT_EQ(frame, (std::vector<std::string>{"render"}));
    // the simulation runs exactly the table, after the engine's event input
    auto sim = test::makeSimulation("[scene]\nname = \"empty\"\n");
    EXPECT_EQ(sim->schedule().names(Phase::Fixed), fixed);
    EXPECT_EQ(sim->schedule().names(Phase::Frame), frame);
    EXPECT_EQ(sim->schedule().names(Phase::Input), (std::vector<std::string>{"events"}));
}

TEST(BuiltinSystems, WhatRunsSideBySideIsWhatTheArchitectureSays) {
    // docs/architecture.md, "Declared access": the pairs it names do not wait for each other, and the
    // systems that write RunReport or pass RigidBody on do
    auto sim = test::makeSimulation("[scene]\nname = \"empty\"\n");
    const std::vector<std::string> names = sim->schedule().names(Phase::Fixed);
    const auto waits = sim->schedule().waitsFor(Phase::Fixed);
    auto index = [&](const std::string& name) {
        return std::size_t(std::find(names.begin(), names.end(), name) - names.begin());
    };
    auto waitsFor = [&](const std::string& later, const std::string& earlier) {
        const auto& w = waits[index(later)];
        return std::find(w.begin(), w.end(), index(earlier)) != w.end();
    };
    EXPECT_TRUE(waits[index("force_fields")].empty());
    EXPECT_TRUE(waits[index("emitters")].empty());
    EXPECT_FALSE(waitsFor("particles", "mouse_spring"));
    EXPECT_FALSE(waitsFor("springs", "particles"));
    EXPECT_FALSE(waitsFor("box2d", "bullet"));
    EXPECT_TRUE(waitsFor("particles", "emitters"));
    EXPECT_TRUE(waitsFor("cloth_collision", "springs"));
    EXPECT_TRUE(waitsFor("rigid_out", "bullet"));
    EXPECT_TRUE(waitsFor("water", "rigid_out"));
    EXPECT_TRUE(waitsFor("collisions_2d", "rigid_out"));
    EXPECT_TRUE(waitsFor("air", "water"));     // the air reads the bodies the water pushed
    EXPECT_TRUE(waitsFor("air", "springs"));   // the springs feel the air the step started with
    EXPECT_TRUE(waitsFor("air", "rigid_out")); // a source moves with its entity's transform
}

TEST(BuiltinSystems, OnlyTheRendererTouchesRenderState) {
    // the renderer must never change the simulation: outside render_history and render, no system
    // declares the render resources, and the renderer writes nothing that is simulated
    for (const SystemEntry& s : builtinSystems()) {
        for (const TypeRef& t : s.access.writes) {
            if (s.name == "render") {
                EXPECT_TRUE(t.name == "RenderOutput" || t.name == "Renderer") << t.name;
            }
            if (s.name == "render_history") {
                EXPECT_TRUE(t.name == "RenderHistory" || t.name == "PoseHistory") << t.name;
            }
        }
    }
}

} // namespace
} // namespace tumble
