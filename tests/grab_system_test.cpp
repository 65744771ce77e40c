// The mouse spring against physics: backward Euler of a critically damped spring on a free mass, converging
// at first order; a rigid body pulled to the target; release, set_integrator, and the events' errors.

#include "components/particles.h"
#include "components/rigid_body.h"
#include "components/rigid_body_2d.h"
#include "components/spring_network.h"
#include "engine/scenario.h"
#include "systems/grab_system.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace tumble {
namespace {

using test::makeSimulation;

void runFor(Simulation& sim, double seconds) {
    const auto frames = static_cast<int>(std::lround(seconds / sim.scene().frameSeconds()));
    for (int i = 0; i < frames; ++i) {
        sim.runFrame();
    }
}

/// One free mass of `mass` kg at the origin, no gravity, held from the first step with the target 1 m along
/// x.
std::string heldMass(double dt, double mass) {
    return "[scene]\nname = \"held\"\ngravity = [0, 0, 0]\ndt = " + std::to_string(dt) +
           "\n[[entity]]\nname = \"bob\"\n[entity.springs]\nmasses = [ { x = [0, 0, 0], m = " +
           std::to_string(mass) +
           " } ]\n[[event]]\nframe = 0\nentity = \"bob\"\naction = \"grab\"\nvalue = 0\nposition = [1, 0, "
           "0]\n";
}

TEST(GrabSystem, HeldMassFollowsTheCriticallyDampedSpringAndConvergesAtFirstOrder) {
    // k = m w^2, c = 2 m w: x(t) = 1 - (1 + w t) e^(-w t), whatever the mass
    const double w = kGrabOmega, t = 0.5; // a whole number of steps of each dt
    const double exact = 1.0 - (1.0 + w * t) * std::exp(-w * t);
    double previous = 0.0;
    for (double dt : {0.004, 0.002, 0.001}) {
        auto sim = makeSimulation(heldMass(dt, 3.0));
        runFor(*sim, t);
        const double error = std::abs(test::component<SpringNetwork>(*sim, "bob").x[0].x - exact);
        EXPECT_LT(error, 0.05) << "dt " << dt;
        if (previous > 0.0) {
            EXPECT_NEAR(previous / error, 2.0, 0.3) << "backward Euler is first order; dt " << dt;
        }
        previous = error;
    }
    // critically damped: it never passes the target
    auto sim = makeSimulation(heldMass(1.0 / 60.0, 1e-3));
    for (int i = 0; i < 240; ++i) {
        sim->runFrame();
        ASSERT_LE(test::component<SpringNetwork>(*sim, "bob").x[0].x, 1.0 + 1e-9) << "frame " << i;
    }
    EXPECT_NEAR(test::component<SpringNetwork>(*sim, "bob").x[0].x, 1.0, 1e-3);
}

TEST(GrabSystem, RigidBodiesArePulledToTheTargetAndLetGo) {
    auto sim = makeSimulation(R"([scene]
name = "held"
gravity = [0, 0, 0]
[[entity]]
name = "crate"
[entity.rigid_body]
shape = "box"
half_extents = [0.2, 0.2, 0.2]
mass = 4.0
sleep = false
[[entity]]
name = "disc"
[entity.transform]
position = [5, 0, 0]
[entity.rigid_body_2d]
shape = "circle"
radius = 0.2
mass = 2.0
[[event]]
frame = 0
entity = "crate"
action = "grab"
value = [0.0, 0.0, 0.0]
position = [1.0, 1.0, 0.0]
[[event]]
frame = 0
entity = "disc"
action = "grab"
value = [0.0, 0.0]
position = [5.0, 2.0, 0.0]
[[event]]
at = 3.0
entity = "crate"
action = "release"
)");
    runFor(*sim, 2.5);
    const RigidBody& crate = test::component<RigidBody>(*sim, "crate");
    // held by its centre, it sits at the target (a point off the centre would let it spin about the hold)
    EXPECT_LT(length(crate.position - Vec3{1.0, 1.0, 0.0}), 0.01);
    const RigidBody2D& disc = test::component<RigidBody2D>(*sim, "disc");
    EXPECT_NEAR(disc.position[0], 5.0, 0.01);
    EXPECT_NEAR(disc.position[1], 2.0, 0.01);
    // let go, nothing pulls: it drifts at the speed it had (sleep is off: resting at the target, it would
    // sleep, and its speed go to zero)
    runFor(*sim, 0.6);
    const Vec3 v = crate.linearVelocity;
    runFor(*sim, 0.5);
    EXPECT_LT(length(crate.linearVelocity - v), 1e-6);
}

/// A free rope of four segments, hung at 2 m.
constexpr const char* kRope = R"([[entity]]
name = "rope"
[entity.transform]
position = [0, 2, 0]
[entity.rope]
segments = 4
length = 1.0
)";

TEST(GrabSystem, EmittersMoveWithTheDragAndIntegratorsChangeLive) {
    const std::string events = R"([[event]]
frame = 1
entity = "spout"
action = "grab"
position = [0, 0, 0]
[[event]]
frame = 2
entity = "spout"
action = "drag"
position = [1, 2, 3]
[[event]]
frame = 2
entity = "rope"
action = "set_integrator"
value = 4
)";
    const std::string scene =
        std::string(
            "[scene]\nname = \"moved\"\n[[entity]]\nname = \"spout\"\n[entity.emitter]\nrate = 10.0\n") +
        kRope + events;
    // the same, with a drag of the rope, which nothing holds
    auto sim = makeSimulation(
        scene + "[[event]]\nframe = 3\nentity = \"rope\"\naction = \"drag\"\nposition = [9, 9, 9]\n");
    auto undragged = makeSimulation(scene);
    runFor(*sim, 5.0 / 60.0);
    runFor(*undragged, 5.0 / 60.0);
    const ParticleEmitter& spout = test::component<ParticleEmitter>(*sim, "spout");
    EXPECT_EQ(spout.origin, (Vec3{1.0, 2.0, 3.0}));
    const SpringNetwork& rope = test::component<SpringNetwork>(*sim, "rope");
    EXPECT_EQ(rope.integrator, Integrator::ImplicitEuler);
    // a drag with nothing held moves nothing: the same bits as without it
    EXPECT_EQ(rope.x, test::component<SpringNetwork>(*undragged, "rope").x);
}

TEST(GrabSystem, EventsThatCannotHoldAreClearErrors) {
    const std::string scene = R"([scene]
name = "bad"
[[entity]]
name = "ground"
[entity.rigid_body]
shape = "plane"
)" + std::string(kRope);
    auto expectError = [&](const std::string& event, const std::string& says) {
        try {
            makeSimulation(scene + "[[event]]\nframe = 0\n" + event);
            ADD_FAILURE() << "accepted: " << event;
        } catch (const ScenarioError& e) {
            EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
        }
    };
    expectError("entity = \"ground\"\naction = \"grab\"\nvalue = [0, 0, 0]\nposition = [0, 1, 0]\n",
                "static");
    expectError("entity = \"rope\"\naction = \"grab\"\nvalue = 99\nposition = [0, 1, 0]\n",
                "mass index in [0, 4]");
    expectError("entity = \"rope\"\naction = \"set_integrator\"\nvalue = 7\n", "4 implicit_euler");
    expectError("entity = \"rope\"\naction = \"release\"\nvalue = 1\n", "value");
}

TEST(GrabSystem, SwitchingABigExplicitNetworkToImplicitIsRefusedByTheMemoryTheLoadCharged) {
    const std::string cloth =
        "[scene]\nname = \"big\"\n[[entity]]\nname = \"sheet\"\n[entity.cloth]\nrows = 300\n"
        "cols = 300\nintegrator = \"symplectic_euler\"\n[[event]]\nframe = 1\nentity = "
        "\"sheet\"\naction = \"set_integrator\"\nvalue = ";
    try {
        makeSimulation(cloth + "4\n");
        ADD_FAILURE() << "a 300 x 300 cloth loaded explicit switched to implicit Euler uncharged";
    } catch (const ScenarioError& e) {
        EXPECT_NE(std::string(e.what()).find("did not charge"), std::string::npos) << e.what();
    }
    EXPECT_NO_THROW(makeSimulation(cloth + "1\n")) << "explicit to explicit costs nothing more";
}

} // namespace
} // namespace tumble
