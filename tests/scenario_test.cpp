// The scenario loader on valid input: defaults, overrides typed by the schema, repeat and scatter, events.

#include "components/spring_network.h"
#include "engine/name.h"
#include "engine/transform.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <map>

namespace tumble {
namespace {

using test::makeSimulation;

const std::string kPendulum = R"(
[scene]
name = "p"
dt = 0.01
[[entity]]
name = "bob"
[entity.transform]
position = [1.0, 2.0, 3.0]
[entity.springs]
stiffness = 10.0
masses = [ { x = [0, 0, 0], pinned = true }, { x = [1, 0, 0], m = 2.0 } ]
links = [ { a = 0, b = 1 } ]
)";

std::map<std::string, Entity> byName(World& w) {
    std::map<std::string, Entity> out;
    w.view<const Name>().each([&](Entity e, const Name& n) { out[n.value] = e; });
    return out;
}

TEST(Scenario, DefaultsFillWhatTheFileLeavesOut) {
    auto sim = makeSimulation("[scene]\nname = \"minimal\"\n");
    const SceneDef& s = sim->scene();
    EXPECT_EQ(s.name, "minimal");
    EXPECT_DOUBLE_EQ(s.dt, 1.0 / 60.0);
    EXPECT_EQ(s.substeps, 1);
    EXPECT_EQ(s.frames, 600);
    EXPECT_EQ(s.gravity[1], -9.81);
    EXPECT_EQ(s.seed, 1u);
    EXPECT_EQ(s.renderWidth, 1280);
    EXPECT_EQ(sim->world().size(), 0u);
}

TEST(Scenario, SpringsAreBuiltAtTheEntityTransform) {
    auto sim = makeSimulation(kPendulum);
    World& w = sim->world();
    const Entity bob = byName(w).at("bob");
    const auto& net = w.get<SpringNetwork>(bob);
    ASSERT_EQ(net.x.size(), 2u);
    EXPECT_EQ(net.x[1], (Vec3{2.0, 2.0, 3.0}));
    EXPECT_EQ(net.invMass[1], 0.5);
    EXPECT_EQ(net.pinned[0], 1);
    ASSERT_EQ(net.links.size(), 1u);
    EXPECT_DOUBLE_EQ(net.links[0].rest, 1.0) << "rest defaults to the initial distance";
    EXPECT_EQ(net.links[0].k, 10.0) << "k defaults to the entity's stiffness";
}

TEST(Scenario, OverridesAreTypedAndCheckedByTheSchema) {
    auto sim = makeSimulation(kPendulum, {"scene.dt=0.005", "scene.substeps=3", "bob.springs.stiffness=50",
                                          "bob.transform.position=[0, 0, 0]", "budget.physics_ms=2.5",
                                          "bob.springs.integrator=symplectic_euler"});
    EXPECT_EQ(sim->scene().dt, 0.005);
    EXPECT_EQ(sim->scene().substeps, 3);
    EXPECT_EQ(sim->scene().physicsBudgetMs, 2.5);
    World& w = sim->world();
    const auto& net = w.get<SpringNetwork>(byName(w).at("bob"));
    EXPECT_EQ(net.links[0].k, 50.0);
    EXPECT_EQ(net.x[1], (Vec3{1.0, 0.0, 0.0}));
}

TEST(Scenario, OverrideErrorsNameTheOverride) {
    try {
        makeSimulation(kPendulum, {"scene.substeps=many"});
        FAIL() << "expected a ScenarioError";
    } catch (const ScenarioError& e) {
        EXPECT_NE(
            std::string(e.what()).find("--set scene.substeps=many: 'substeps' in [scene] must be an integer"),
            std::string::npos)
            << e.what();
        EXPECT_EQ(e.file(), "test.toml");
    }
}

// A key of the file that fails because an override changed another key of its table (an air grid's size
// against the cells a --set gave it) is reported at its line and names the override. Seen to fail before:
// the message blamed the file's `size` line alone, which the user had not changed.
TEST(Scenario, AKeyFailingWithAnOverriddenOneNamesTheOverride) {
    const std::string text = "[scene]\nname = \"a\"\n[[entity]]\nname = \"room\"\n[entity.air]\n"
                             "cells = [8, 8, 8]\nsize = [1.0, 1.0, 1.0]\n";
    try {
        makeSimulation(text, {"room.air.cells=[8, 4, 8]"});
        FAIL() << "expected a ScenarioError";
    } catch (const ScenarioError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("the cells must be cubes"), std::string::npos) << what;
        EXPECT_NE(what.find("(with --set room.air.cells=[8, 4, 8])"), std::string::npos) << what;
        EXPECT_EQ(e.line(), 7) << "at the size it checked";
    }
    try {
        makeSimulation(text, {"room.air.vorticity=-1"});
        FAIL() << "expected a ScenarioError";
    } catch (const ScenarioError& e) {
        EXPECT_EQ(std::string(e.what()).find("(with"), std::string::npos)
            << "the override's own error names it once: " << e.what();
    }
    try {
        makeSimulation(text, {"room.air.vorticity=0.5", "room.air.advection=sideways"});
        FAIL() << "expected a ScenarioError";
    } catch (const ScenarioError& e) {
        EXPECT_EQ(std::string(e.what()).find("vorticity"), std::string::npos)
            << "an unrelated override is not named: " << e.what();
    }
}

TEST(Scenario, RepeatMakesNumberedCopiesAtOffsets) {
    auto sim = makeSimulation(R"(
[scene]
name = "r"
[[entity]]
name = "bead"
repeat = { count = 4, offset = [0.5, 0, 0] }
[entity.transform]
position = [1, 1, 0]
[entity.springs]
masses = [ { x = [0, 0, 0] } ]
)");
    auto names = byName(sim->world());
    ASSERT_EQ(names.size(), 4u);
    for (int i = 0; i < 4; ++i) {
        const Entity e = names.at("bead_" + std::to_string(i));
        EXPECT_DOUBLE_EQ(sim->world().get<Transform>(e).position.x, 1.0 + 0.5 * i);
        EXPECT_DOUBLE_EQ(sim->world().get<SpringNetwork>(e).x[0].x, 1.0 + 0.5 * i);
    }
}

TEST(Scenario, ScatterIsInsideItsBoxAndFollowsTheSeed) {
    const std::string text = R"(
[scene]
name = "s"
seed = 5
[[entity]]
name = "rock"
scatter = { count = 50, min = [-1, 0, -2], max = [1, 0.5, 2] }
[entity.springs]
masses = [ { x = [0, 0, 0] } ]
)";
    auto positions = [](const std::string& t, const std::vector<std::string>& o) {
        auto sim = makeSimulation(t, o);
        std::vector<Vec3> out;
        for (const auto& [n, e] : byName(sim->world())) {
            out.push_back(sim->world().get<Transform>(e).position);
        }
        return out;
    };
    const auto a = positions(text, {});
    ASSERT_EQ(a.size(), 50u);
    for (const Vec3& p : a) {
        EXPECT_GE(p.x, -1.0);
        EXPECT_LE(p.x, 1.0);
        EXPECT_GE(p.y, 0.0);
        EXPECT_LE(p.y, 0.5);
        EXPECT_GE(p.z, -2.0);
        EXPECT_LE(p.z, 2.0);
    }
    EXPECT_EQ(a, positions(text, {})) << "the same seed places the same rocks";
    EXPECT_NE(a, positions(text, {"scene.seed=6"})) << "another seed places them elsewhere";
}

TEST(Scenario, EventsAreStepsSortedByTime) {
    auto sim = makeSimulation(kPendulum + R"(
[[event]]
at = 0.5
entity = "bob"
action = "impulse"
value = [0, 0, 1]
[[event]]
frame = 7
entity = "bob"
action = "set_velocity"
value = [0, 0, 0]
)");
    const auto& ev = sim->scenario().events;
    ASSERT_EQ(ev.size(), 2u);
    EXPECT_EQ(ev[0].step, 7u) << "frame 7 with one substep";
    EXPECT_EQ(ev[1].step, 50u) << "0.5 s at dt 0.01";
    EXPECT_EQ(ev[1].action, "impulse");
}

TEST(Scenario, EventTimesBetweenStepsApplyAtTheNextStep) {
    auto at = [&](const std::string& t, const std::string& dt) {
        return makeSimulation(kPendulum + "[[event]]\nat = " + t +
                                  "\nentity = \"bob\"\naction = \"impulse\"\n"
                                  "value = [0, 0, 1]\n",
                              {"scene.dt=" + dt})
            ->scenario()
            .events.at(0)
            .step;
    };
    EXPECT_EQ(at("0.015", "0.01"), 2u) << "the first step whose time reaches 0.015 s starts at 0.02 s";
    EXPECT_EQ(at("0.02", "0.01"), 2u);
    EXPECT_EQ(at("0.0", "0.01"), 0u);
    EXPECT_EQ(at("2.0", "0.004166666"), 480u) << "a dt written with few digits still lands on 2 s";
    EXPECT_EQ(at("2.0", "0.0166666667"), 120u);
}

} // namespace
} // namespace tumble
