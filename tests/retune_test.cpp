// The `set` event (engine/retune.h): at its step it changes what its key names and nothing else, in every
// kind of component and in the scene; what a run has changed since the start stays; and it is recorded:
// a replay of a run with set events (from the scenario or from --input) verifies.

#include "components/air.h"
#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "components/water.h"
#include "systems/air_solver.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>

namespace tumble {
namespace {

using test::component;
using test::makeSimulation;

void run(Simulation& sim, int frames) {
    for (int i = 0; i < frames; ++i) {
        sim.runFrame();
    }
}

TEST(SetEvent, GravityTurnsAtItsStep) {
    // a free mass falls for 30 steps under -10, then rises under +10: symplectic Euler's velocity is
    // -10 dt times the steps before the set plus 10 dt times the steps after, to rounding
    auto sim = makeSimulation(R"(
[scene]
name = "flip"
dt = 0.01
gravity = [0, -10, 0]
[[entity]]
name = "ball"
[entity.springs]
masses = [ { x = [0, 0, 0] } ]
[[event]]
frame = 30
action = "set"
key = "scene.gravity"
value = [0, 10, 0]
)");
    run(*sim, 30);
    EXPECT_NEAR(component<SpringNetwork>(*sim, "ball").v[0].y, -3.0, 1e-12);
    run(*sim, 50);
    EXPECT_NEAR(component<SpringNetwork>(*sim, "ball").v[0].y, 2.0, 1e-12);
    EXPECT_EQ(sim->world().resource<SceneDef>().gravity[1], 10.0);
}

const char* kCurtain = R"(
[scene]
name = "c"
[[entity]]
name = "sheet"
[entity.transform]
position = [0, 2, 0]
[entity.cloth]
rows = 6
cols = 6
stretch = 5000.0
shear = 500.0
bend = 50.0
pin = "top-row"
)";

TEST(SetEvent, AClothsStretchReachesItsStructuralSpringsAloneAndKeepsARunsUnpin) {
    auto sim = makeSimulation(std::string(kCurtain) + R"(
[[event]]
frame = 2
entity = "sheet"
action = "unpin"
value = [0]
[[event]]
frame = 4
action = "set"
key = "sheet.cloth.stretch"
value = 9000.0
)");
    run(*sim, 4);
    const SpringNetwork before = component<SpringNetwork>(*sim, "sheet");
    ASSERT_FALSE(before.pinned[0]) << "unpinned at frame 2";
    run(*sim, 1);
    const SpringNetwork& after = component<SpringNetwork>(*sim, "sheet");
    int changed = 0;
    for (std::size_t k = 0; k < after.links.size(); ++k) {
        if (before.links[k].k == 5000.0) {
            EXPECT_EQ(after.links[k].k, 9000.0) << "link " << k;
            ++changed;
        } else {
            EXPECT_EQ(after.links[k].k, before.links[k].k) << "shear and bend keep theirs";
        }
        EXPECT_EQ(after.links[k].rest, before.links[k].rest);
    }
    EXPECT_EQ(changed, 2 * 6 * 5) << "the structural springs of a 6 x 6 grid";
    EXPECT_FALSE(after.pinned[0]) << "the set of stretch does not pin back what the run unpinned";
    EXPECT_TRUE(after.pinned[1]);
}

TEST(SetEvent, MovingATransformMovesTheClothAndTheWaterKeepsItsGridButTakesItsSpeed) {
    auto sim = makeSimulation(std::string(kCurtain) + R"(
[[entity]]
name = "pond"
[entity.water]
cells = [16, 16]
wave_speed = 2.0
[[event]]
frame = 3
action = "set"
key = "sheet.transform.position"
value = [1, 2, 0]
[[event]]
frame = 3
action = "set"
key = "pond.water.wave_speed"
value = 3.0
)");
    run(*sim, 3);
    const std::vector<Vec3> x = component<SpringNetwork>(*sim, "sheet").x;
    sim->runFrame();
    const SpringNetwork& net = component<SpringNetwork>(*sim, "sheet");
    EXPECT_NEAR(net.x[0].x, x[0].x + 1.0, 1e-12) << "a pinned mass moves with the transform";
    EXPECT_EQ(component<Water>(*sim, "pond").waveSpeed, 3.0);
}

TEST(SetEvent, ABodysMassAndAnEmittersRateChangeLive) {
    auto sim = makeSimulation(R"(
[scene]
name = "m"
dt = 0.01
gravity = [0, 0, 0]
[[entity]]
name = "crate"
[entity.rigid_body]
shape = "box"
mass = 1.0
[[entity]]
name = "spout"
[entity.emitter]
rate = 100.0
lifetime = [100.0, 100.0]
collide = false
[[event]]
frame = 10
action = "set"
key = "crate.rigid_body.mass"
value = 4.0
[[event]]
frame = 10
entity = "spout"
action = "set"
key = "emitter.rate"
value = 300.0
[[event]]
frame = 12
entity = "crate"
action = "impulse"
value = [2.0, 0, 0]
)");
    run(*sim, 10);
    EXPECT_EQ(component<ParticleEmitter>(*sim, "spout").born, 10u);
    run(*sim, 10);
    // 3 a step from step 10 on; an impulse of 2 N s on 4 kg
    EXPECT_EQ(component<ParticleEmitter>(*sim, "spout").born, 40u);
    EXPECT_NEAR(component<RigidBody>(*sim, "crate").linearVelocity.x, 0.5, 1e-6);
}

TEST(SetEvent, ASceneWithAHullTakesASetEvent) {
    // each of the two loads a set event compares reads its own copy of the hull's file: the same file is
    // the same shape (a wave maker's period set in the harbour was refused as "a body's shape" changing)
    auto sim = makeSimulation(R"(
[scene]
name = "hull"
dt = 0.01
[[entity]]
name = "rock"
[entity.rigid_body]
shape = "convex"
mesh = "assets/meshes/rock_0.obj"
mass = 2.0
[[event]]
frame = 5
action = "set"
key = "rock.rigid_body.friction"
value = 0.9
)");
    run(*sim, 6);
    EXPECT_EQ(component<RigidBody>(*sim, "rock").friction, 0.9);
}

TEST(SetEvent, ASetToTheFilesOwnValueStillTakesHold) {
    // the crate is given 2 m/s by an event, then set back to the file's own [0, 0, 0]: it stops (compared
    // with the file alone, the set changed nothing and was lost); a long array comes through whole
    auto sim = makeSimulation(R"(
[scene]
name = "stop"
dt = 0.01
gravity = [0, 0, 0]
[[entity]]
name = "crate"
[entity.rigid_body]
shape = "box"
mass = 1.0
sleep = false
linear_velocity = [0, 0, 0]
[[event]]
frame = 2
entity = "crate"
action = "set_velocity"
value = [2.0, 0, 0]
[[event]]
frame = 10
action = "set"
key = "crate.rigid_body.linear_velocity"
value = [0, 0, 0]
[[entity]]
name = "sheet"
[entity.transform]
position = [50, 0, 0]
[entity.cloth]
rows = 4
cols = 40
pin = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39]
[[event]]
frame = 3
action = "set"
key = "sheet.cloth.pin"
value = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38]
)");
    run(*sim, 9);
    EXPECT_NEAR(component<RigidBody>(*sim, "crate").linearVelocity.x, 2.0, 1e-6);
    run(*sim, 2);
    EXPECT_EQ(component<RigidBody>(*sim, "crate").linearVelocity.x, 0.0) << "stopped by the set";
    const SpringNetwork& sheet = component<SpringNetwork>(*sim, "sheet");
    EXPECT_TRUE(sheet.pinned[38]);
    EXPECT_FALSE(sheet.pinned[39]) << "the 40-element array came through";
}

TEST(SetEvent, FrictionSetToZeroReachesContactsAlreadyMadeInBothEngines) {
    // a sideways pull of 2 m/s^2 held by friction; at frame 5 the friction of the (static) grounds goes to
    // 0, so the mix with the bodies' (the geometric mean) is 0, and from then on each body slides as a
    // frictionless one would: x = a t^2 / 2 (a static ground's material was never given to its engine, and
    // Box2D's contacts made before the set kept their old friction: nothing slid); both bodies are asleep
    // by then (a second at rest), and the set wakes them
    auto sim = makeSimulation(R"(
[scene]
name = "slip"
gravity = [2.0, -9.81, 0.0]
[[entity]]
name = "floor"
[entity.transform]
position = [0, -0.5, 0]
[entity.rigid_body]
shape = "box"
half_extents = [20, 0.5, 20]
[[entity]]
name = "crate"
[entity.transform]
position = [0.0, 0.5, 0.0]
[entity.rigid_body]
shape = "box"
half_extents = [0.5, 0.5, 0.5]
mass = 10.0
[[entity]]
name = "ground2d"
[entity.rigid_body_2d]
shape = "edge"
from = [-20.0, 0.0]
to = [20.0, 0.0]
[[entity]]
name = "box2d"
[entity.transform]
position = [3.0, 0.5, 5.0]
[entity.rigid_body_2d]
shape = "box"
half_extents = [0.5, 0.5]
mass = 10.0
[[event]]
frame = 60
action = "set"
key = "floor.rigid_body.friction"
value = 0.0
[[event]]
frame = 60
action = "set"
key = "ground2d.rigid_body_2d.friction"
value = 0.0
)");
    run(*sim, 60);
    const double crate0 = component<RigidBody>(*sim, "crate").position.x;
    const double box0 = component<RigidBody2D>(*sim, "box2d").position[0];
    EXPECT_LT(std::abs(crate0), 1e-3) << "held by friction before the set";
    run(*sim, 60);
    const double expected = 0.5 * 2.0 * 1.0 * 1.0; // a t^2 / 2 over the 60 frames (1 s) since the set
    EXPECT_NEAR(component<RigidBody>(*sim, "crate").position.x - crate0, expected, 0.05 * expected);
    EXPECT_NEAR(component<RigidBody2D>(*sim, "box2d").position[0] - box0, expected, 0.05 * expected);
}

TEST(SetEvent, ASetOfAShapeKeyToItsOwnValueChangesNothing) {
    // rows = 6 for a 6-row cloth is allowed (nothing changes), and whatever the run changed stays: the mass
    // it unpinned stays free (compared with a load at rows = 7, the other layout's values would be read into
    // this one; copying the file's pins over would pin it back)
    auto sim = makeSimulation(std::string(kCurtain) + R"(
[[event]]
frame = 1
entity = "sheet"
action = "unpin"
value = [2]
[[event]]
frame = 2
action = "set"
key = "sheet.cloth.rows"
value = 6
)");
    run(*sim, 2);
    ASSERT_FALSE(component<SpringNetwork>(*sim, "sheet").pinned[2]) << "unpinned by the run";
    const SpringNetwork before = component<SpringNetwork>(*sim, "sheet");
    run(*sim, 1);
    const SpringNetwork& after = component<SpringNetwork>(*sim, "sheet");
    EXPECT_EQ(after.pinned, before.pinned);
    EXPECT_EQ(after.invMass, before.invMass);
    for (std::size_t k = 0; k < after.links.size(); ++k) {
        EXPECT_EQ(after.links[k].rest, before.links[k].rest) << "link " << k;
    }
}

TEST(SetEvent, AStaticBodySetElsewhereTakesItsEngineAndWakesWhatRestedOnIt) {
    // a 3D floor and a 2D ground moved 5 m down at 1 s, when the crates on them have gone to sleep: both
    // crates fall (the bridges skipped static bodies, and the crates rested on floors no longer drawn)
    auto sim = makeSimulation(R"(
[scene]
name = "drop"
[[entity]]
name = "floor"
[entity.transform]
position = [0, -0.5, 0]
[entity.rigid_body]
shape = "box"
half_extents = [5, 0.5, 5]
[[entity]]
name = "crate"
[entity.transform]
position = [0, 0.5, 0]
[entity.rigid_body]
shape = "box"
mass = 1.0
[[entity]]
name = "ground2d"
[entity.transform]
position = [0, 0, 5]
[entity.rigid_body_2d]
shape = "box"
half_extents = [5, 0.25]
[[entity]]
name = "box2d"
[entity.transform]
position = [0, 0.75, 5]
[entity.rigid_body_2d]
shape = "box"
mass = 1.0
[[event]]
frame = 60
action = "set"
key = "floor.transform.position"
value = [0, -5.5, 0]
[[event]]
frame = 60
action = "set"
key = "ground2d.transform.position"
value = [0, -5, 5]
)");
    run(*sim, 60);
    EXPECT_TRUE(component<RigidBody>(*sim, "crate").sleeping) << "asleep before the set";
    run(*sim, 30);
    EXPECT_LT(component<RigidBody>(*sim, "crate").position.y, -0.5) << "falling";
    EXPECT_LT(component<RigidBody2D>(*sim, "box2d").position[1], -0.5) << "falling";
}

TEST(SetEvent, AKeyThatBringsItsTableAlongTakesTheTableToo) {
    // water without a wave maker, given one by setting one of its keys: the maker's other keys come with
    // their defaults and it makes waves (compared only with the key at another value, the table's coming
    // was the same on both sides and the maker never started)
    auto sim = makeSimulation(R"(
[scene]
name = "maker"
dt = 0.01
[[entity]]
name = "pond"
[entity.water]
cells = [41, 11]
size = [8.0, 2.0]
[[event]]
frame = 5
action = "set"
key = "pond.water.wave_maker.amplitude"
value = 0.05
)");
    run(*sim, 5);
    EXPECT_EQ(component<Water>(*sim, "pond").maker.edge, -1);
    run(*sim, 100);
    const Water& w = component<Water>(*sim, "pond");
    EXPECT_EQ(w.maker.edge, 0) << "the default edge, -x";
    EXPECT_EQ(w.maker.amplitude, 0.05);
    EXPECT_GT(std::abs(w.h[std::size_t(w.nz / 2) * w.nx + 5]), 1e-3) << "waves near the maker";
}

TEST(SetEvent, ARunWithSetEventsReplaysBitForBit) {
    // from the scenario and from --input: both are recorded, and the replay verifies
    const std::string scenario = test::writeTemp("set_replay.toml", std::string(kCurtain) + R"(
[[event]]
frame = 5
action = "set"
key = "sheet.cloth.bend"
value = 400.0
)");
    const std::string input =
        test::writeTemp("set_replay.jsonl", "{\"frame\": 8, \"action\": \"set\", \"key\": \"scene.gravity\", "
                                            "\"value\": [1.0, -9.81, 0.0]}\n");
    const std::string replay = test::tempPath("set_replay.tumble");
    auto r = test::runTumble({"run", scenario, "--frames", "20", "--no-render", "--quiet", "--input", input,
                              "--record", replay, "--out", test::tempPath("set_out")});
    ASSERT_EQ(r.exitCode, 0) << r.err;
    r = test::runTumble(
        {"replay", replay, "--verify", "--no-render", "--quiet", "--out", test::tempPath("set_v")});
    EXPECT_EQ(r.exitCode, 0) << r.err;
    // a bad set from --input is refused like the scenario's
    const std::string bad =
        test::writeTemp("set_bad.jsonl",
                        "{\"frame\": 8, \"action\": \"set\", \"key\": \"sheet.cloth.rows\", \"value\": 9}\n");
    r = test::runTumble({"run", scenario, "--frames", "20", "--no-render", "--quiet", "--input", bad, "--out",
                         test::tempPath("set_bad")});
    EXPECT_EQ(r.exitCode, 2) << r.err;
    EXPECT_NE(r.err.find("masses and springs cannot change during a run"), std::string::npos) << r.err;
}

// An air grid's physics and drawing keys and a source's keys take a set event at its frame (the next step
// runs with them: MacCormack's vectors made when it is switched on); its grid does not, and says so. Seen
// to fail with the source's retune left out (the set refused as an unknown kind).
TEST(SetEvent, AnAirGridsPhysicsAndASourceChangeLiveButNotTheGrid) {
    const std::string scene = R"(
[scene]
name = "a"
dt = 0.01
[[entity]]
name = "room"
[entity.air]
cells = [8, 4, 4]
size = [1.0, 0.5, 0.5]
[[entity]]
name = "puff"
[entity.air_source]
air = "room"
radius = 0.2
[[event]]
frame = 3
action = "set"
key = "room.air.vorticity"
value = 0.5
[[event]]
frame = 3
action = "set"
key = "room.air.advection"
value = "maccormack"
[[event]]
frame = 3
action = "set"
key = "puff.air_source.velocity"
value = [0.0, 1.0, 0.0]
[[event]]
frame = 3
action = "set"
key = "puff.air_source.smoke"
value = 4.0
)";
    auto sim = makeSimulation(scene);
    run(*sim, 3);
    EXPECT_EQ(component<Air>(*sim, "room").vorticity, 0.0);
    EXPECT_FALSE(component<AirSource>(*sim, "puff").drives);
    run(*sim, 2);
    const Air& air = component<Air>(*sim, "room");
    EXPECT_EQ(air.vorticity, 0.5);
    ASSERT_TRUE(air.maccormack);
    EXPECT_EQ(air.scratch.back.size(), std::max({air.u.size(), air.v.size(), air.w.size()}))
        << "the largest face lattice's (v's and w's here)";
    EXPECT_EQ(air.scratch.back2.size(), air.heat.size());
    const AirSource& source = component<AirSource>(*sim, "puff");
    EXPECT_EQ(source.smoke, 4.0);
    EXPECT_TRUE(source.drives);
    EXPECT_EQ(source.velocity.y, 1.0);
    EXPECT_GT(airVelocityAt(air, {0.0, 0.0, 0.0}).y, 0.5) << "the source drives the air";

    const std::string grid = test::writeTemp("set_air.toml", scene + R"(
[[event]]
frame = 4
action = "set"
key = "room.air.cells"
value = [16, 8, 8]
)");
    const auto r = test::runTumble(
        {"run", grid, "--frames", "6", "--no-render", "--quiet", "--out", test::tempPath("set_air")});
    EXPECT_EQ(r.exitCode, 2) << r.err;
    EXPECT_NE(r.err.find("an air grid's cells, size, border and place cannot change during a run"),
              std::string::npos)
        << r.err;
}

} // namespace
} // namespace tumble
