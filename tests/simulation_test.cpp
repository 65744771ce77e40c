// The simulation loop end to end in one process: steps and substeps, determinism of the state hash, and
// the dump's contents.

#include "components/spring_network.h"
#include "engine/dump.h"
#include "engine/float_mode.h"
#include "engine/run_report.h"
#include "systems/builtin.h"
#include "tests/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstring>

namespace tumble {
namespace {

using test::makeSimulation;

const std::string kChain = R"(
[scene]
name = "chain"
dt = 0.005
substeps = 3
[[entity]]
name = "chain"
[entity.springs]
stiffness = 300.0
damping = 0.1
masses = [ { x = [0, 0, 0], pinned = true }, { x = [0.3, -0.4, 0] }, { x = [0.9, -0.5, 0.1] } ]
links = [ { a = 0, b = 1 }, { a = 1, b = 2 } ]
[[event]]
at = 0.1
entity = "chain"
action = "impulse"
value = [0, 0, 2]
)";

/// A product of two small floats that is a denormal (about 1e-40) unless denormals are flushed to zero.
float denormalProduct() {
    volatile float tiny = 1e-30f, scale = 1e-10f;
    return tiny * scale;
}

TEST(Simulation, DenormalsAreFlushedDuringAStepAndTheCallersModeIsPutBack) {
    ASSERT_GT(denormalProduct(), 0.0f); // the process's own mode keeps denormals
    {
        const FlushDenormals flush;
        EXPECT_EQ(denormalProduct(), 0.0f);
    }
    EXPECT_GT(denormalProduct(), 0.0f);
    // inside a step every system sees them flushed (the solver of a resting cloth ran ten times slower on
    // denormals); after it, the program that runs the simulation has its own mode again
    Catalog catalog;
    registerBuiltinSystems(catalog);
    std::vector<float> seen;
    catalog.addSystem(
        {"probe", Phase::Fixed, [&](World&, const StepContext&) { seen.push_back(denormalProduct()); }, {}});
    Simulation sim(catalog, "test.toml", kChain, {});
    sim.runFrame();
    ASSERT_EQ(seen.size(), 3u);
    for (float v : seen) {
        EXPECT_EQ(v, 0.0f);
    }
    EXPECT_GT(denormalProduct(), 0.0f);
}

TEST(Simulation, EachFrameRunsSubstepsFixedSteps) {
    auto sim = makeSimulation(kChain);
    for (int i = 0; i < 10; ++i) {
        sim->runFrame();
    }
    EXPECT_EQ(sim->frame(), 10u);
    EXPECT_EQ(sim->step(), 30u);
    EXPECT_DOUBLE_EQ(sim->time(), 30 * 0.005);
    for (const SlotStats& s : sim->profiler().slotStats()) {
        if (s.name == "springs" || s.name == "events") {
            EXPECT_EQ(s.calls, 30u) << s.name;
        }
        if (s.name == "phase:frame") {
            EXPECT_EQ(s.calls, 10u);
        }
    }
}

TEST(Simulation, SameScenarioGivesTheSameHashEveryFrame) {
    auto a = makeSimulation(kChain);
    auto b = makeSimulation(kChain);
    for (int i = 0; i < 50; ++i) {
        a->runFrame();
        b->runFrame();
        ASSERT_EQ(a->hash(), b->hash()) << "frame " << i;
    }
}

TEST(Simulation, AChangedScenarioGivesAnotherHash) {
    auto a = makeSimulation(kChain);
    auto b = makeSimulation(kChain, {"chain.springs.stiffness=301"});
    auto c = makeSimulation(kChain, {"scene.gravity=[0, -9.8, 0]"});
    a->runFrame();
    b->runFrame();
    c->runFrame();
    // the springs' stiffness is the scenario's, not hashed state: it shows in how the masses move
    EXPECT_NE(a->hash(), b->hash()) << "a stiffer spring moves the masses differently";
    EXPECT_NE(a->hash(), c->hash()) << "a different gravity moves the masses differently";
}

TEST(Simulation, OneFlippedBitOfStateChangesTheHash) {
    auto sim = makeSimulation(kChain);
    sim->runFrame();
    const std::uint64_t before = sim->hash();
    SpringNetwork* net = nullptr;
    sim->world().view<SpringNetwork>().each([&](Entity, SpringNetwork& n) { net = &n; });
    std::uint64_t bits;
    std::memcpy(&bits, &net->v[2].z, sizeof bits);
    bits ^= 1; // one ulp
    std::memcpy(&net->v[2].z, &bits, sizeof bits);
    EXPECT_NE(sim->hash(), before);
}

TEST(Simulation, DumpLineHasTheContractFieldsAndRoundTrips) {
    auto sim = makeSimulation(kChain);
    for (int i = 0; i < 7; ++i) {
        sim->runFrame();
    }
    std::string line;
    sim->appendDump(line);
    ASSERT_FALSE(line.empty());
    EXPECT_EQ(line.back(), '\n');
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["frame"], 7);
    EXPECT_EQ(j["t"].get<double>(), sim->time());
    EXPECT_EQ(j["hash"], hashHex(sim->hash()));
    const auto& chain = j["entities"]["chain"];
    EXPECT_EQ(chain["kind"], "springs");
    SpringNetwork* net = nullptr;
    sim->world().view<SpringNetwork>().each([&](Entity, SpringNetwork& n) { net = &n; });
    ASSERT_EQ(chain["x"].size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
        // doubles written in full: what is read back is the same double
        EXPECT_EQ(chain["x"][i][0].get<double>(), net->x[i].x);
        EXPECT_EQ(chain["x"][i][1].get<double>(), net->x[i].y);
        EXPECT_EQ(chain["v"][i][2].get<double>(), net->v[i].z);
    }
}

// An entity with two kinds of state (a falling body that is also an emitter, an air grid that emits) keeps
// both in the dump: the first kind's fields as ever, the other's in an object under its kind. The body's
// numbers are the ones the same body dumps without the emitter (which changes nothing of its motion).
TEST(Simulation, AnEntityWithTwoKindsOfStateDumpsBoth) {
    const std::string body = R"(
[scene]
name = "two_kinds"
dt = 0.01
[[entity]]
name = "ball"
[entity.transform]
position = [0.0, 1.2, 0.0]
[entity.rigid_body]
shape = "sphere"
radius = 0.1
mass = 1.0
)";
    const std::string emitter = R"(
[entity.emitter]
rate = 200.0
max_particles = 50
)";
    auto plain = makeSimulation(body);
    auto both = makeSimulation(body + emitter);
    for (int i = 0; i < 20; ++i) {
        plain->runFrame();
        both->runFrame();
    }
    std::string line, reference;
    both->appendDump(line);
    plain->appendDump(reference);
    const auto ball = nlohmann::json::parse(line)["entities"]["ball"];
    const auto alone = nlohmann::json::parse(reference)["entities"]["ball"];
    ASSERT_EQ(alone["kind"], "rigid");
    ASSERT_TRUE(ball.contains("kind") && ball.contains("x") && ball.contains("count")) << ball.dump();
    ASSERT_TRUE(ball.contains("rigid")) << "the body's state is missing: " << ball.dump();
    EXPECT_EQ(ball["kind"], "particles");
    EXPECT_GT(ball["count"].get<int>(), 0);
    for (const char* field : {"x", "q", "v", "w"}) {
        EXPECT_EQ(ball["rigid"][field], alone[field]) << field;
    }
    EXPECT_LT(ball["rigid"]["x"][0][1].get<double>(), 1.0) << "it fell";
}

TEST(Simulation, ABlowUpIsCaughtFrozenAndReported) {
    // a spring far too stiff for its step: explicit Euler diverges
    auto sim = makeSimulation(std::string("[scene]\nname = \"boom\"\ndt = 0.0166666667\n") +
                              test::kBlowingUpBob + R"(
[[entity]]
name = "calm"
[entity.springs]
masses = [ { x = [0, 5, 0] } ]
)");
    for (int i = 0; i < 200; ++i) {
        ASSERT_NO_THROW(sim->runFrame());
    }
    const auto& failures = sim->world().resource<RunReport>().failures;
    ASSERT_EQ(failures.size(), 1u) << "said once, not every frame";
    EXPECT_NE(failures[0].find("entity 'bob' blew up at frame"), std::string::npos) << failures[0];
    EXPECT_NE(failures[0].find("explicit_euler"), std::string::npos);
    EXPECT_NE(failures[0].find("implicit_euler"), std::string::npos) << "it suggests a remedy";
    std::string line;
    sim->appendDump(line);
    const auto j = nlohmann::json::parse(line);
    EXPECT_EQ(j["entities"]["bob"]["frozen"], true);
    for (const auto& p : j["entities"]["bob"]["x"]) {
        for (const auto& c : p) {
            EXPECT_TRUE(c.is_number()) << "frozen before its state turned non-finite: " << line;
        }
    }
    // the rest of the scene ran on: the free mass fell for 200 frames
    EXPECT_LT(j["entities"]["calm"]["x"][0][1].get<double>(), 5.0 - 50.0);
}

} // namespace
} // namespace tumble
